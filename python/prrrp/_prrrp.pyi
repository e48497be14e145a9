"""Type stubs of the native module prrrp._prrrp (import `prrrp` instead).

Array arguments accept anything numpy converts to float64. Joint-space arguments (q, qd,
qdd, tau) have shape (5,) for one sample or (N, 5) for a batch; λ (`lam`) has shape (8,) or
(N, 8). Single samples broadcast against batches. Outputs get a leading N for a batch.
"""

from collections.abc import Iterator
from typing import Any, Final, Literal, TypedDict

import numpy as np
import numpy.typing as npt

_ArrayLike = npt.ArrayLike
_F64 = npt.NDArray[np.float64]

__version__: Final[str]
NDOF: Final[int]
"""Number of joints (5)."""
NPARAM: Final[int]
"""Number of grouped base parameters λ (8)."""
STANDARD_GRAVITY: Final[float]
"""Default gravitational acceleration, 9.81 m/s² along -z."""

class PrrrpError(Exception):
    """Base class of every error raised by prrrp."""

class InvalidInputError(PrrrpError, ValueError):
    """The input is at fault (shape, value, too few samples, ...)."""

class InvalidParameterError(InvalidInputError):
    field: str
    value: float
    reason: str

class NonFiniteError(InvalidInputError):
    what: str
    row: int | None

class ShapeMismatchError(InvalidInputError):
    what: str
    expected: str
    got: str

class TooFewSamplesError(InvalidInputError):
    needed: int
    got: int

class NonIncreasingTimeError(InvalidInputError):
    row: int

class RankDeficientError(InvalidInputError):
    rank: int
    params: int
    cond: float
    directions: list[list[float]]

class NotPositiveDefiniteError(InvalidInputError):
    what: str

class InfeasibleError(InvalidInputError):
    what: str

class DivergedError(PrrrpError, ArithmeticError):
    what: str
    at: int
    hint: str

class _DhRow(TypedDict):
    kind: Literal["prismatic", "revolute"]
    theta: float
    d: float
    a: float
    alpha: float

class InverseDerivatives:
    """∂τ/∂q and ∂τ/∂q̇ at fixed q̈ and λ; unpacks as (dtau_dq, dtau_dqd)."""

    @property
    def dtau_dq(self) -> _F64: ...
    @property
    def dtau_dqd(self) -> _F64: ...
    def __iter__(self) -> Iterator[_F64]: ...
    def __len__(self) -> int: ...

class ForwardDerivatives:
    """q̈ and ∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂λ at fixed τ; unpacks as
    (qdd, dqdd_dq, dqdd_dqd, dqdd_dlambda)."""

    @property
    def qdd(self) -> _F64: ...
    @property
    def dqdd_dq(self) -> _F64: ...
    @property
    def dqdd_dqd(self) -> _F64: ...
    @property
    def dqdd_dlambda(self) -> _F64: ...
    def __iter__(self) -> Iterator[_F64]: ...
    def __len__(self) -> int: ...

class Robot:
    """The PRRRP arm (paper Table 2 quantities, SI units) and its dynamic model.

    Keyword arguments default to the paper's values: mass m1..m5 (kg, > 0), length l1..l5
    (m, > 0), com lc2..lc4 (m, >= 0, from joints 2-4 along the link), inertia_zz I2zz..I4zz
    (kg·m², >= 0, about the centre of mass), gravity (m/s², >= 0, along -z).
    Raises InvalidParameterError naming a non-physical value.
    """

    def __init__(
        self,
        *,
        mass: _ArrayLike | None = None,
        length: _ArrayLike | None = None,
        com: _ArrayLike | None = None,
        inertia_zz: _ArrayLike | None = None,
        gravity: float = 9.81,
    ) -> None: ...
    @staticmethod
    def paper() -> Robot:
        """The robot of Urrea & Pascal 2017, Table 2, with g = 9.81 m/s²."""
    @property
    def mass(self) -> _F64:
        """Link masses m1..m5, kg, shape (5,)."""
    @property
    def length(self) -> _F64:
        """Link lengths l1..l5, m, shape (5,)."""
    @property
    def com(self) -> _F64:
        """Centre-of-mass distances lc2..lc4, m, shape (3,)."""
    @property
    def inertia_zz(self) -> _F64:
        """I2zz..I4zz about the centres of mass, kg·m², shape (3,)."""
    @property
    def g(self) -> float:
        """Gravitational acceleration, m/s², along -z."""
    def base_parameters(self) -> _F64:
        """The 8 grouped base parameters λ (paper Table 3, corrected), shape (8,)."""
    def dh_table(self) -> list[_DhRow]:
        """Standard DH table at q = 0 (paper Table 1)."""
    def mass_matrix(self, q: _ArrayLike, *, lam: _ArrayLike | None = None) -> _F64:
        """M(q, λ), shape (5, 5) or (N, 5, 5)."""
    def coriolis(self, q: _ArrayLike, qd: _ArrayLike, *, lam: _ArrayLike | None = None) -> _F64:
        """C(q, q̇, λ)·q̇ (N, N·m), shape (5,) or (N, 5)."""
    def gravity(self, q: _ArrayLike, *, lam: _ArrayLike | None = None) -> _F64:
        """G(λ) (N, N·m), shape (5,) or (N, 5); q only sets the shape."""
    def nonlinear_effects(
        self, q: _ArrayLike, qd: _ArrayLike, *, lam: _ArrayLike | None = None
    ) -> _F64:
        """C(q, q̇, λ)·q̇ + G(λ) (N, N·m), shape (5,) or (N, 5)."""
    def inverse_dynamics(
        self,
        q: _ArrayLike,
        qd: _ArrayLike,
        qdd: _ArrayLike,
        *,
        lam: _ArrayLike | None = None,
    ) -> _F64:
        """τ = M·q̈ + C·q̇ + G (N, N·m), shape (5,) or (N, 5)."""
    def forward_dynamics(
        self,
        q: _ArrayLike,
        qd: _ArrayLike,
        tau: _ArrayLike,
        *,
        lam: _ArrayLike | None = None,
    ) -> _F64:
        """q̈ = M⁻¹(τ - C·q̇ - G), shape (5,) or (N, 5). Raises NotPositiveDefiniteError
        for a non-physical λ."""
    def regressor(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike) -> _F64:
        """Φ(q, q̇, q̈) at this robot's gravity, shape (5, 8) or (N, 5, 8)."""
    def kinetic_energy(
        self, q: _ArrayLike, qd: _ArrayLike, *, lam: _ArrayLike | None = None
    ) -> Any:
        """½·q̇ᵀ·M·q̇ (J): float, or shape (N,)."""
    def potential_energy(self, q: _ArrayLike, *, lam: _ArrayLike | None = None) -> Any:
        """g·(λ1·d1 + λ8·(d1 - d5)) (J): float, or shape (N,)."""
    def inverse_derivatives(
        self,
        q: _ArrayLike,
        qd: _ArrayLike,
        qdd: _ArrayLike,
        *,
        lam: _ArrayLike | None = None,
    ) -> InverseDerivatives: ...
    def forward_derivatives(
        self,
        q: _ArrayLike,
        qd: _ArrayLike,
        tau: _ArrayLike,
        *,
        lam: _ArrayLike | None = None,
    ) -> ForwardDerivatives: ...
    def __eq__(self, other: object) -> bool: ...

def regressor(q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, *, gravity: float = 9.81) -> _F64:
    """Φ(q, q̇, q̈) with τ = Φ·λ, shape (5, 8) or (N, 5, 8)."""

def observation_matrix(
    q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, *, gravity: float = 9.81
) -> _F64:
    """Stacked regressors W (eq. 35), shape (5·N, 8)."""

def singular_values(w: _ArrayLike) -> _F64:
    """Singular values of W, decreasing."""

def condition_number(w: _ArrayLike) -> float:
    """σmax/σmin of W (eq. 38); inf if rank deficient."""
