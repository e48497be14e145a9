"""Type stubs of the native module prrrp._prrrp (import `prrrp` instead).

Array arguments accept anything numpy converts to float64. Joint-space arguments (q, qd,
qdd, tau) have shape (5,) for one sample or (N, 5) for a batch; λ (`lam`) has shape (8,) or
(N, 8). Single samples broadcast against batches. Outputs get a leading N for a batch.
"""

import builtins
import os
from collections.abc import Callable, Iterator, Mapping
from typing import Any, Final, Literal, Self, TypedDict, Unpack, final, overload

import numpy as np
import numpy.typing as npt

# Where a default in the Rust signature is not a Python literal (`UInt(20)`, a Rust
# constant), pyo3 shows it as `...` at runtime. The stub writes `...` too, so that stubtest
# checks the signature, with the value in a comment; where the Rust default is the exported
# `STANDARD_GRAVITY`, the stub names that constant. Keyword options that several functions
# share are one `TypedDict` (`**options: Unpack[...]`, defaults in its docstrings): stubtest
# (mypy >= 2.0) checks their names and kinds against each runtime signature.

_ArrayLike = npt.ArrayLike
_F64 = npt.NDArray[np.float64]

# The module's `__all__` lists every name `register` adds (pyo3 keeps it); stubtest checks
# it against this one, which each section below extends by its own names.
__all__ = [
    "MAX_FACTOR",
    "MAX_HARMONICS",
    "MAX_MAGNITUDE",
    "MIN_FACTOR",
    "NDOF",
    "NPARAM",
    "SETTLING_PERIODS",
    "STANDARD_GRAVITY",
    "__version__",
    "is_factor",
]

__version__: Final[str]
NDOF: Final[int]
"""Number of joints (5)."""
NPARAM: Final[int]
"""Number of grouped base parameters λ (8)."""
STANDARD_GRAVITY: Final[float]
"""Default gravitational acceleration, 9.81 m/s² along -z."""
MAX_MAGNITUDE: Final[float]
"""Magnitude from which a logged value is refused (1e100; s, rad, m, N·m, N, A, per s): far
beyond any arm or clock, far below where the squares least squares forms overflow a
double. The CSV and bag readers and `OnlineIdentifier.update` refuse it, naming it."""
MIN_FACTOR: Final[float]
"""Smallest width or noise factor squared into a covariance (1e-6): `OnlineIdentifier`'s
`prior_width`, `ekf_noise`, `payload_mass_std` (kg) and `payload_size` (m), the EKF's
`least_squares_prior_width`."""
MAX_FACTOR: Final[float]
"""Largest such factor (1e6), also the largest factor on simulated noise."""
MAX_HARMONICS: Final[int]
"""Most harmonics per joint of an excitation design (100)."""
SETTLING_PERIODS: Final[float]
"""Cut-off periods after which a low-pass's start or edge transient counts as decayed (3,
i.e. 3/cutoff s): the batch preprocessing trims that much at each end, and the online
identifier updates no estimate before it."""

def is_factor(v: float) -> bool:
    """Whether ``v`` lies in [MIN_FACTOR, MAX_FACTOR] (False for NaN and infinities)."""

__all__ += [
    "DivergedError",
    "InfeasibleError",
    "InvalidInputError",
    "InvalidParameterError",
    "NonFiniteError",
    "NonIncreasingTimeError",
    "NotPositiveDefiniteError",
    "PrrrpError",
    "RankDeficientError",
    "RobotFileError",
    "ShapeMismatchError",
    "TooFewSamplesError",
]

class PrrrpError(Exception):
    """Base class of every error raised by prrrp."""

class InvalidInputError(PrrrpError, ValueError):
    """The input is at fault (shape, value, too few samples, ...)."""

class InvalidParameterError(InvalidInputError):
    field: str
    value: float | str
    """The offending number, or the text given for a non-numeric setting."""
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

class RobotFileError(InvalidInputError):
    """A robot file (URDF, TOML) cannot be read or describes no usable chain."""

    file: str
    element: str
    message: str

class DivergedError(PrrrpError, ArithmeticError):
    what: str
    at: int
    hint: str

__all__ += [
    "ForwardDerivatives",
    "InverseDerivatives",
    "Robot",
    "condition_number",
    "observation_matrix",
    "regressor",
    "singular_values",
]

class _DhRow(TypedDict):
    kind: Literal["prismatic", "revolute"]
    theta: float
    d: float
    a: float
    alpha: float

class _Derivatives:
    """The derivative results: they unpack as a tuple of their arrays."""

    def __iter__(self) -> Iterator[_F64]: ...
    def __len__(self) -> int: ...

@final
class InverseDerivatives(_Derivatives):
    """∂τ/∂q and ∂τ/∂q̇ at fixed q̈ and λ; unpacks as (dtau_dq, dtau_dqd)."""

    @property
    def dtau_dq(self) -> _F64: ...
    @property
    def dtau_dqd(self) -> _F64: ...

@final
class ForwardDerivatives(_Derivatives):
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

@final
class Robot:
    """The PRRRP arm (paper Table 2 quantities, SI units) and its dynamic model.

    Keyword arguments default to the paper's values: mass m1..m5 (kg, > 0), length l1..l5
    (m, > 0), com lc2..lc4 (m, >= 0, from joints 2-4 along the link), inertia_zz I2zz..I4zz
    (kg·m², >= 0, about the centre of mass), gravity (m/s², >= 0, along -z).
    Raises InvalidParameterError naming a non-physical value.
    """

    def __new__(
        cls,
        *,
        mass: _ArrayLike | None = None,
        length: _ArrayLike | None = None,
        com: _ArrayLike | None = None,
        inertia_zz: _ArrayLike | None = None,
        gravity: float = STANDARD_GRAVITY,
    ) -> Self: ...
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
        self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, *, lam: _ArrayLike | None = None
    ) -> _F64:
        """τ = M·q̈ + C·q̇ + G (N, N·m), shape (5,) or (N, 5)."""
    def forward_dynamics(
        self, q: _ArrayLike, qd: _ArrayLike, tau: _ArrayLike, *, lam: _ArrayLike | None = None
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
        self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, *, lam: _ArrayLike | None = None
    ) -> InverseDerivatives: ...
    def forward_derivatives(
        self, q: _ArrayLike, qd: _ArrayLike, tau: _ArrayLike, *, lam: _ArrayLike | None = None
    ) -> ForwardDerivatives: ...
    def __eq__(self, other: object, /) -> bool: ...
    def __getnewargs_ex__(self) -> tuple[tuple[()], dict[str, Any]]:
        """Pickle and copy support: the keyword arguments that rebuild this robot."""

def regressor(
    q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, *, gravity: float = STANDARD_GRAVITY
) -> _F64:
    """Φ(q, q̇, q̈) with τ = Φ·λ, shape (5, 8) or (N, 5, 8).

    The paper's arm in closed form only (its study); for any robot:
    `SerialChain.regressor` / `base_regressor`."""

def observation_matrix(
    q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, *, gravity: float = STANDARD_GRAVITY
) -> _F64:
    """Stacked regressors W (eq. 35), shape (5·N, 8).

    The paper's arm in closed form only (its study); for any robot:
    `SerialChain.base_regressor` stacked."""

def singular_values(w: _ArrayLike) -> _F64:
    """Singular values of W, decreasing."""

def condition_number(w: _ArrayLike) -> float:
    """σmax/σmin of W (eq. 38); inf if rank deficient."""

# --- trajectories -------------------------------------------------------------------------

__all__ += ["Excitation", "SinusoidReference", "joint_limits", "optimise_excitation"]

_Triple = tuple[_F64, _F64, _F64]

class _JointLimits(TypedDict):
    q_min: _F64
    q_max: _F64
    qd_max: _F64
    qdd_max: _F64

class _LimitUsage(TypedDict):
    q: _F64
    qd: _F64
    qdd: _F64

def joint_limits() -> _JointLimits:
    """Default joint limits of the excitation search: (5,) arrays (m, rad, /s, /s²)."""

@final
class Excitation:
    """An optimised excitation trajectory (paper §4.1) and the figures of its search."""

    @property
    def cond_initial(self) -> float: ...
    @property
    def cond_final(self) -> float: ...
    @property
    def evaluations(self) -> int: ...
    @property
    def limits_satisfied(self) -> bool: ...
    @property
    def samples(self) -> int: ...
    @property
    def duration(self) -> float: ...
    @property
    def dt(self) -> float: ...
    @property
    def limit_usage(self) -> _LimitUsage: ...
    def eval(self, t: _ArrayLike) -> _Triple:
        """(q, qd, qdd): (5,) each for a scalar t (s), (N, 5) each for t of shape (N,)."""
    def sample(self, t: _ArrayLike) -> _Triple:
        """Same as `eval`."""
    def reflected(self) -> Excitation:
        """The same excitation played forward and backward in turn, defined for every
        t ≥ 0 (period 2·duration; C² at every turn since it starts and ends at rest): the
        reference of a recording longer than one excitation. `duration` stays one pass."""
    @property
    def is_reflected(self) -> bool: ...

@final
class SinusoidReference:
    """q_i(t) = offset_i + amplitude_i·sin(omega_i·t + phase_i); each argument (5,)."""

    def __new__(
        cls,
        *,
        offset: _ArrayLike,
        amplitude: _ArrayLike,
        omega: _ArrayLike,
        phase: _ArrayLike | None = None,
    ) -> Self: ...
    def eval(self, t: _ArrayLike) -> _Triple: ...
    def sample(self, t: _ArrayLike) -> _Triple: ...

def optimise_excitation(
    *,
    seed: int = ...,  # 0
    duration: float = 10.0,
    dt: float = 0.02,
    max_evaluations: int = ...,  # 6000
    restarts: int = ...,  # 6
    margin: float = 0.01,
    limits: Mapping[str, _ArrayLike] | None = None,
    progress: Callable[[int, int, float], object] | None = None,
    progress_every: int = ...,  # 100
) -> Excitation:
    """Minimises cond(W) within the joint limits. `progress(evaluations, max_evaluations,
    best_cond)`; an exception it raises is re-raised when the search returns.

    The paper's arm in closed form only (its study); for any robot:
    `design_excitation` / `prrrp.excite`."""

# --- simulation ---------------------------------------------------------------------------

__all__ += ["simulate_closed_loop", "simulate_open_loop"]

class _Record(TypedDict, total=False):
    t: _F64
    q_ref: _F64
    qd_ref: _F64
    qdd_ref: _F64
    q: _F64
    qd: _F64
    qdd: _F64
    tau: _F64
    q_measured: _F64
    tau_measured: _F64

class _ClosedLoop(TypedDict, total=False):
    """The computed-torque loop of `simulate_closed_loop` and `validate` (all optional)."""

    controller_lam: _ArrayLike | None
    """λ (8,) of the controller's model (default: the simulated robot's)."""
    dt: float
    """Sample period, s (default 0.02)."""
    substeps: int
    """RK4 steps per sample (default 20)."""
    kp: _ArrayLike | None
    """Proportional gains (5,), 1/s² (default 400)."""
    kd: _ArrayLike | None
    """Derivative gains (5,), 1/s (default 40)."""
    q_noise: _ArrayLike | None
    """Position noise std per joint (5,), m or rad (default: the core's `SensorNoise`;
    zeros for none)."""
    tau_noise: _ArrayLike | None
    """Torque noise std per joint (5,), N or N·m (default: the core's `SensorNoise`)."""

def simulate_closed_loop(
    reference: Excitation | SinusoidReference,
    duration: float,
    *,
    lam: _ArrayLike | None = None,
    seed: int = ...,  # 0
    **options: Unpack[_ClosedLoop],
) -> _Record:
    """Computed-torque tracking of `reference`; arrays t (N,) and (N, 5) columns.

    The paper's arm in closed form only (its study); for any robot:
    `simulate_chain` / `prrrp.simulate`."""

def simulate_open_loop(
    q0: _ArrayLike,
    qd0: _ArrayLike,
    tau: _ArrayLike,
    *,
    lam: _ArrayLike | None = None,
    dt: float = 0.02,
    substeps: int = ...,  # 20
    q_noise: _ArrayLike | None = None,
    tau_noise: _ArrayLike | None = None,
    seed: int = ...,  # 0
) -> _Record:
    """The robot under the torques tau (N, 5), zero-order hold; no *_ref keys.

    The paper's arm in closed form only (its study); for any robot:
    `simulate_chain_open_loop`."""

# --- preprocessing ------------------------------------------------------------------------

__all__ += ["preprocess"]

class _Dataset(TypedDict):
    t: _F64
    q: _F64
    qd: _F64
    qdd: _F64
    tau: _F64

def preprocess(
    t: _ArrayLike,
    q: _ArrayLike,
    tau: _ArrayLike,
    *,
    cutoff_hz: float = 5.0,
    order: int = 4,
    filter_torque: bool = True,
    trim: int | None = None,
    decimate: int = ...,  # 1
) -> _Dataset:
    """Zero-phase low-pass, central differences, trimming, decimation.

    The paper's arm in closed form only (its study); for any robot:
    `preprocess_log`."""

# --- estimators ---------------------------------------------------------------------------

__all__ += ["Adaline", "Ekf", "Hopfield", "LeastSquaresResult", "Rls", "least_squares"]

@final
class LeastSquaresResult:
    lam: _F64
    std: _F64
    rsd_percent: _F64
    cond: float
    sigma2: float
    singular_values: _F64
    joint_variances: _F64
    samples: int

def least_squares(
    q: _ArrayLike,
    qd: _ArrayLike,
    qdd: _ArrayLike,
    tau: _ArrayLike,
    *,
    weighted: bool = False,
    noise_variances: _ArrayLike | None = None,
    rank_tolerance: float = 1e-10,
) -> LeastSquaresResult:
    """Least-squares λ (eq. 36) from (N, 5) columns.

    The paper's arm in closed form only (its study); for any robot:
    `identify(robot, data, "ls")`."""

class _OnlineEstimator:
    """The online estimators. Adaline, Hopfield and Rls are built for the paper's arm
    (`lam0` (8,), default Table 3), or for any chain: pass a `SerialChain` first; then
    `beta0` (b,) (default zeros), the analysis `base` (default `chain.base_parameters()`)
    and a positive column `scale` (b,) (default ones): the estimator trains on
    γ = β/scale and reports β. Ekf: see its constructor."""

    @property
    def estimate(self) -> _F64: ...
    def step(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, tau: _ArrayLike) -> _F64:
        """One sample ((5,) each; (n,) for a chain) → the updated λ̂ (8,) (β̂ (b,) for a
        chain)."""
    @overload
    def run(
        self,
        q: _ArrayLike,
        qd: _ArrayLike,
        qdd: _ArrayLike,
        tau: _ArrayLike,
        *,
        history_every: None = None,
    ) -> _F64: ...
    @overload
    def run(
        self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, tau: _ArrayLike, *, history_every: int
    ) -> tuple[_F64, _F64]: ...
    def reset(self) -> None: ...

class _TrainedEstimator(_OnlineEstimator):
    def train(
        self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, tau: _ArrayLike, epochs: int
    ) -> _F64:
        """RMS equation error per epoch, (epochs,)."""

@final
class Adaline(_TrainedEstimator):
    def __new__(
        cls,
        lam0: _ArrayLike | None = None,
        *,
        rule: Literal["normalised", "normalized", "delta"] = "normalised",
        learning_rate: float = 5e-3,
        step_size: float = 1.0,
        epsilon: float = 1e-9,
        divergence_ratio: float = 1e6,
        beta0: _ArrayLike | None = None,
        base: BaseParameters | None = None,
        scale: _ArrayLike | None = None,
    ) -> Self: ...

@final
class Hopfield(_TrainedEstimator):
    def __new__(
        cls,
        lam0: _ArrayLike | None = None,
        *,
        bound: float = 10.0,
        beta: float = 100.0,
        dt: float = 0.02,
        stability_limit: float = 1.0,
        max_substeps: int = 64,
        beta0: _ArrayLike | None = None,
        base: BaseParameters | None = None,
        scale: _ArrayLike | None = None,
    ) -> Self: ...

@final
class Rls(_OnlineEstimator):
    def __new__(
        cls,
        lam0: _ArrayLike | None = None,
        *,
        forgetting: float = 1.0,
        initial_covariance: float = 1e6,
        beta0: _ArrayLike | None = None,
        base: BaseParameters | None = None,
        scale: _ArrayLike | None = None,
    ) -> Self: ...

@final
class Ekf(_OnlineEstimator):
    def __new__(
        cls,
        lam0: _ArrayLike | None = None,
        *,
        measurement: Literal["positions", "positions_velocities"] = "positions",
        discretisation: Literal["euler", "second_order"] = "euler",
        dt: float = 0.02,
        position_noise: float = 1e-3,
        velocity_noise: float = 1e-2,
        process_position_noise: float = 1e-6,
        process_velocity_noise: float = 1e-3,
        process_parameter_noise: float = 1e-5,
        initial_position_std: float = 1e-3,
        initial_velocity_std: float = 1.0,
        initial_parameter_rel_std: float = 0.5,
        initial_parameter_min_std: float = 1e-3,
        init_from_first_measurement: bool = True,
        beta0: _ArrayLike | None = None,
        base: BaseParameters | None = None,
    ) -> Self:
        """The paper's arm (`lam0` (8,), default Table 3), or any chain: pass a
        `SerialChain` first; then `beta0` (b,) (default the chain's own base parameters,
        since the filter needs a positive definite M(q, β0)) and the analysis `base`.
        States S = 2n + b; `state`, `covariance`, `parameter_std` and the setters take
        the chain's sizes."""
    @property
    def parameter_std(self) -> _F64: ...
    @property
    def skipped_updates(self) -> int: ...
    @property
    def damped_updates(self) -> int: ...
    @property
    def state(self) -> _F64:
        """x = [q, qd, lam] predicted for the next sample, (18,)."""
    @property
    def covariance(self) -> _F64:
        """State covariance P, (18, 18)."""
    def set_initial_covariance(self, p0: _ArrayLike) -> None:
        """P0, (18, 18), symmetric positive definite."""
    def set_process_noise(self, variances: _ArrayLike) -> None:
        """Q = diag(variances), (18,), per step, each >= 0."""
    def set_measurement_noise(self, positions: _ArrayLike, velocities: _ArrayLike) -> None:
        """R = diag(positions (5,), velocities (5,)), variances, each > 0."""

# --- metrics ------------------------------------------------------------------------------

__all__ += ["agreement_index", "error_indices", "relative_errors_percent", "rms", "rsd"]

class _Indices(TypedDict):
    rms: Any
    rsd: Any
    ai: Any

def rms(observed: _ArrayLike, predicted: _ArrayLike) -> Any:
    """float for (N,) inputs, (C,) array for (N, C)."""

def rsd(observed: _ArrayLike, predicted: _ArrayLike) -> Any: ...
def agreement_index(observed: _ArrayLike, predicted: _ArrayLike) -> Any: ...
def error_indices(observed: _ArrayLike, predicted: _ArrayLike) -> _Indices: ...
def relative_errors_percent(estimate: _ArrayLike, truth: _ArrayLike) -> _F64: ...

# --- study --------------------------------------------------------------------------------

__all__ += ["paper_lambda_map", "run_study_json"]

def run_study_json(
    seed: int = ...,  # 0
    progress: Callable[[str, int, int], object] | None = None,
) -> str:
    """The whole study as JSON (schema_version 1); use `prrrp.run_study` for a dict."""

def paper_lambda_map() -> list[list[float]]:
    """T (8 rows of 9): the paper's λ = T·β for the base parameters β of the built-in paper
    robot; use `prrrp.lambda_view.lambda_map` for an array."""

# --- generic serial chains ------------------------------------------------------------

__all__ += [
    "BaseParameters",
    "FitCache",
    "IdentifiedModel",
    "OnlineIdentifier",
    "SerialChain",
    "identified_model_from_parts",
    "identify",
    "identify_drive_gains",
]

class _RobotFileOptions(TypedDict, total=False):
    """The options of `SerialChain.from_urdf` and `from_file` (all optional)."""

    base: str | None
    """First link of the chain (default: the root link, or the TOML file's `base`)."""
    tip: str | None
    """Last link of the chain (default: the end of the movable joints, or the file's)."""
    gravity: _ArrayLike | None
    """(3,) m/s² in the base link's frame (default (0, 0, −9.81))."""
    friction: str | list[str] | None
    """Friction terms, as in the constructor (default: the file's, else none)."""
    coulomb_smoothing: float
    """Speed scale v_s of fc·tanh(q̇/v_s), rad/s; 0 = exact sign (default 0)."""

@final
class SerialChain:
    """A serial arm of revolute and prismatic joints, with the 10 standard inertial parameters
    per link and optional joint friction. n joints; joint-space arrays have shape (n,) or
    (N, n). Built from a Denavit–Hartenberg table (this constructor), a URDF (`from_urdf`) or a
    robot file (`from_file`: .urdf or .toml).

    Arguments (SI units):
    - dh: (n, 4) rows [a, alpha, d, theta] (m, rad, m, rad); theta and d are the constant
      offsets to which a revolute/prismatic joint coordinate is added. With
      convention='modified' (Craig), a and alpha of row i are a_{i-1} and alpha_{i-1}, as
      Craig's tables list them.
    - joint_types: 'RRP...' or a list of 'R'/'P' (or 'revolute'/'prismatic'), one per row;
      anything else raises InvalidParameterError.
    - convention: 'standard' (distal: joint i moves about z_{i-1}, frame i at the far end of
      link i) or 'modified' (proximal: joint i moves about z_i, frame i at joint i).
    - inertial: (n, 10), per link [m, m·x, m·y, m·z, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]
      (Pinocchio's order; kg, kg·m, kg·m²) with the centre of mass (x, y, z) in frame i and
      the inertia tensor about the ORIGIN of frame i, in frame i's axes (I_O = I_C +
      m·(|c|²·1 − c·cᵀ)). In standard DH frame i is at the distal end of link i, so a centre of
      mass at lc from joint i along a link of length a lies at x = lc − a. Default zeros.
    - gravity: (3,) in world (frame 0) coordinates, m/s²; default (0, 0, −9.81).
    - friction: None, or terms among 'viscous', 'coulomb', 'offset' (list, or 'viscous+coulomb');
      friction_params: (n, 3) per joint [fv, fc, fo] (N·s/m or N·m·s/rad; N or N·m); joint j
      adds fv·q̇ + fc·sgn(q̇) + fo (enabled terms only), with sgn ≈ tanh(q̇/coulomb_smoothing)
      when coulomb_smoothing > 0.

    The standard parameter vector is [inertial of links 1..n, enabled friction terms of
    joints 1..n] (`parameters`, `parameter_names`), P = `num_params` entries.
    """

    def __new__(
        cls,
        dh: _ArrayLike,
        joint_types: str | list[str],
        *,
        convention: Literal["standard", "modified"] = "standard",
        inertial: _ArrayLike | None = None,
        gravity: _ArrayLike | None = None,
        friction: str | list[str] | None = None,
        friction_params: _ArrayLike | None = None,
        coulomb_smoothing: float = 0.0,
    ) -> Self: ...
    @staticmethod
    def from_urdf(
        source: str | os.PathLike[str], **options: Unpack[_RobotFileOptions]
    ) -> SerialChain:
        """A chain from a URDF: `source` is its path or its XML text (a string with '<').

        The chain is the path of movable joints (revolute, continuous, prismatic) from the link
        `base` (default: the root link) to the link `tip` (default: the end of the movable
        joints when they form a single path; otherwise RobotFileError lists the candidate
        tips). Bodies on fixed joints are merged into the chain link they hang from; movable
        joints off the path (a gripper's fingers) are held at zero and merged the same way
        (`locked_joints`), so the dynamics equal Pinocchio's reduced model with those joints
        locked at zero. Link frames are the URDF joint frames; each link's `<inertial>`
        becomes its 10 standard parameters about the joint-frame origin. `<limit>` and
        `<dynamics>` are kept (`limits`). `gravity` (3,) m/s² in the base link's frame,
        default (0, 0, −9.81); `friction`/`coulomb_smoothing` as in the constructor.
        Non-physical inertials load (see `non_physical_links`). Malformed files, missing
        links, zero or non-unit axes, floating/planar/mimic joints on the path:
        RobotFileError or InvalidParameterError naming the file and element."""
    @staticmethod
    def from_file(
        path: str | os.PathLike[str], **options: Unpack[_RobotFileOptions]
    ) -> SerialChain:
        """A chain from a `.urdf` (see `from_urdf`) or a `.toml` robot file:

        ```toml
        name = "panda"
        convention = "modified"            # or "standard"
        gravity = [0.0, 0.0, -9.80665]     # optional, default [0, 0, -9.81]
        [[joint]]                          # one per joint, base to tip
        type = "revolute"                  # or "prismatic"
        a = 0.0
        alpha = 0.0
        d = 0.333
        theta = 0.0
        # optional: name, lower, upper, velocity, acceleration, effort (SI);
        # inertial = [m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]; friction = [fv, fc, fo]
        ```

        Unknown keys are an error naming them; a `friction` row enables viscous, Coulomb and
        offset terms (overridden by the `friction` argument).

        A TOML file may instead take its links from a URDF and declare its drives:

        ```toml
        name = "tx40"
        urdf = "tx40.urdf"      # relative to the TOML file; exclusive with [[joint]]
        base = "base_link"      # optional; `base`/`tip` arguments override them
        tip = "tool0"
        [actuators]             # also allowed in a [[joint]] file
        armature = true         # one rotor inertia Ia per actuator, identified
        coupling = [[1,0,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],
                    [0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,1,1]]   # q̇ₘ = C·q̇
        armature_values = [...] # optional, kg·m² joint side (needs armature = true)
        gear_ratios = [...]     # optional, motor angle per joint angle (motor-side logs)
        friction = [[fv, fc, fo], ...]   # optional, per actuator
        coulomb_smoothing = 0.02         # optional, rad/s
        ```

        URDF `<transmission>` elements (Simple, Differential, FourBarLinkage; Drake's
        rotor inertia) are read into the same actuators; see `with_actuators`."""
    def to_urdf(self, parameters: _ArrayLike | None = None) -> str:
        """A URDF of this chain with the standard parameters `parameters` (P,) (default:
        `parameters`): kinematics as loaded, each link's inertial about its centre of mass.
        Loading it back gives the same dynamics (to round-off). Chains whose link frames sit
        off the joint axes (standard DH) are written in joint frames, inertials moved
        accordingly."""
    def with_friction(
        self,
        friction: str | list[str] | None,
        friction_params: _ArrayLike | None = None,
        *,
        coulomb_smoothing: float = 0.0,
    ) -> SerialChain:
        """The same chain with another friction model (terms as in the constructor),
        per-joint [fv, fc, fo] (n, 3) (default zeros) and the smooth-sign scale (rad/s).
        With coupled actuators the rows are per actuator (friction on C·q̇)."""
    def with_actuators(
        self,
        *,
        coupling: _ArrayLike | None = None,
        armature: bool | None = None,
        armature_values: _ArrayLike | None = None,
        gear_ratios: _ArrayLike | None = None,
    ) -> SerialChain:
        """The same chain with other actuators (arguments left None keep the chain's).

        n actuators drive the n joints with joint-side velocities q̇ₘ = C·q̇ (`coupling`, an
        invertible (n, n) matrix; the identity is one geared motor per joint, a row
        [0, 0, 0, 0, 1, 1] a sixth motor turning with q̇5 + q̇6). Each actuator has friction
        (the chain's friction model, acting on q̇ₘ) and, with `armature`, a reflected rotor
        inertia Iaₘ (kg·m², joint side; `armature_values` (n,) its values, default 0),
        identified as one more parameter per actuator (`Ia1..Ian`). Their torques reach
        the joints through Cᵀ: τ = M·q̈ + C(q,q̇)·q̇ + G + Cᵀ·(diag(Ia)·C·q̈ + f(C·q̇)).
        `gear_ratios` (n,) (motor angle per joint-side angle) only map motor-side logs
        (`joint_positions_from_motor`). A singular, non-square or non-finite coupling
        raises InvalidParameterError / ShapeMismatchError."""
    @property
    def actuators(self) -> dict[str, Any]:
        """'coupling' ((n, n) or None = identity), 'armature' (bool), 'armature_values'
        ((n,) kg·m² or None), 'gear_ratios' ((n,) or None)."""
    def joint_torques_from_currents(self, current: _ArrayLike, gains: _ArrayLike) -> _F64:
        """Joint torques τ = Cᵀ·(K∘i) (N·m, N) from motor currents `current` (A), (n,) or
        (N, n), with joint-side drive gains `gains` (n,) N·m/A (torque constant × gear
        ratio)."""
    def joint_positions_from_motor(self, theta: _ArrayLike) -> _F64:
        """Joint positions q = C⁻¹·(θ/r) from motor angles θ (rad, motor side), (n,) or
        (N, n); needs `gear_ratios`. Also maps motor velocities/accelerations."""
    def joint_torques_from_motor(self, tau_motor: _ArrayLike) -> _F64:
        """Joint torques τ = Cᵀ·(r∘τ_motor) (N·m, N) from motor-side torques (N·m), (n,)
        or (N, n); needs `gear_ratios`."""
    def to_toml(self, urdf: str, parameters: _ArrayLike | None = None) -> str:
        """A TOML robot file of this chain whose links are in the URDF `urdf` (a path
        relative to the TOML file, e.g. `to_urdf`'s output next to it), with the drives
        URDF cannot hold ([actuators]: coupling, armature values, gear ratios, per-actuator
        friction); `parameters` (P,) default to the chain's own."""
    @property
    def name(self) -> str:
        """The robot's name from its file ('robot' otherwise)."""
    @property
    def joint_names(self) -> list[str]:
        """Joint names, base to tip ('joint1', ... for DH tables)."""
    @property
    def link_names(self) -> list[str]:
        """The base link, then the link each joint moves (n + 1 names)."""
    @property
    def locked_joints(self) -> list[str]:
        """Movable joints of the source file held at zero and merged into the links."""
    @property
    def limits(self) -> dict[str, _F64]:
        """'lower', 'upper' (rad or m), 'velocity', 'acceleration', 'effort' (SI), each (n,);
        NaN where the file gives none."""
    @property
    def non_physical_links(self) -> list[str]:
        """Links whose inertials no rigid body has (pseudo-inertia not positive semidefinite:
        a negative mass, an inertia breaking the triangle inequality)."""
    def is_physically_consistent(self) -> bool:
        """True when `non_physical_links` is empty."""
    @property
    def is_closed_form(self) -> bool:
        """Whether the chain is evaluated in closed form (the paper's arm; read-only)."""
    @staticmethod
    def paper() -> SerialChain:
        """The paper's PRRRP arm (Tables 1–2, g = 9.81 m/s²) as a chain: same dynamics as
        `Robot.paper()`, 50 standard parameters, 9 base parameters; its joints carry the
        limits of the paper's excitation (`joint_limits()`), and `load_robot("paper")` /
        `--robot paper` give it."""
    @staticmethod
    def puma560() -> SerialChain:
        """The PUMA 560 (6R, standard DH), links only, from Corke & Armstrong-Hélouvry (ICRA
        1994) as in Corke's `mdl_puma560`; gravity (0, 0, −9.81) m/s². 36 base parameters."""
    @property
    def dof(self) -> int: ...
    @property
    def num_params(self) -> int:
        """P = 10·n + (enabled friction terms)·n."""
    @property
    def parameter_names(self) -> list[str]:
        """['m1', 'mx1', 'my1', 'mz1', 'Ixx1', ..., 'Izz<n>', 'fv1', 'fc1', ...]."""
    @property
    def parameters(self) -> _F64:
        """The standard parameter vector π, (P,)."""
    @property
    def dh(self) -> _F64 | None:
        """(n, 4) rows [a, alpha, d, theta]; None for a chain not built from a DH table."""
    @property
    def joint_types(self) -> str:
        """E.g. 'RRRRRR'."""
    @property
    def convention(self) -> Literal["standard", "modified"] | None:
        """The DH convention; None for a chain not built from a DH table."""
    @property
    def inertial(self) -> _F64:
        """(n, 10), see the class docs for the frame."""
    @property
    def gravity(self) -> _F64:
        """(3,) m/s², world frame."""
    @property
    def friction(self) -> tuple[str, ...]:
        """Enabled friction terms, e.g. ('viscous', 'coulomb')."""
    @property
    def friction_params(self) -> _F64:
        """(n, 3) [fv, fc, fo] per joint."""
    @property
    def coulomb_smoothing(self) -> float: ...
    def inverse_dynamics(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike) -> _F64:
        """τ = M·q̈ + C·q̇ + G + τ_friction (N, N·m), (n,) or (N, n)."""
    def nonlinear_effects(self, q: _ArrayLike, qd: _ArrayLike) -> _F64:
        """C·q̇ + G + τ_friction (the torque at q̈ = 0), (n,) or (N, n)."""
    def gravity_torques(self, q: _ArrayLike) -> _F64:
        """G(q) (no friction), (n,) or (N, n)."""
    def mass_matrix(self, q: _ArrayLike) -> _F64:
        """M(q), (n, n) or (N, n, n)."""
    def forward_dynamics(self, q: _ArrayLike, qd: _ArrayLike, tau: _ArrayLike) -> _F64:
        """q̈ = M⁻¹(τ − C·q̇ − G − τ_friction), (n,) or (N, n). NotPositiveDefiniteError (with
        `.sample` for a batch) where M(q) is singular."""
    def regressor(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike) -> _F64:
        """Full regressor Y with τ = Y @ parameters, (n, P) or (N, n, P); column 10·i + k is
        parameter k of link i+1 (link-frame parameters), then the friction columns."""
    def observation_matrix(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike) -> _F64:
        """The regressors stacked, (N·n, P); rows n·k..n·k+n hold sample k."""
    def feasibility(self, parameters: _ArrayLike | None = None) -> dict[str, Any]:
        """Physical feasibility of standard parameters (P,) (default `parameters`): per link
        ("links": link, mass, min_eigenvalue and pseudo_inertia_eigenvalues of the 4×4
        pseudo-inertia, com, principal_moments about it, triangle_margins, consistent), per
        joint ("friction": joint, viscous, coulomb, consistent: both ≥ 0), and overall
        "consistent" and "non_physical_links"."""
    def base_feasibility(
        self, beta: _ArrayLike, *, prior: _ArrayLike | None = None
    ) -> dict[str, Any]:
        """Whether physically consistent standard parameters with base values `beta` (in
        `base_parameters()`) exist, e.g. for a least-squares estimate: the nearest rigid
        bodies found ("parameters", their feasibility report as in `feasibility`),
        "max_relative_mismatch" of their base values, "feasible" (relative mismatch
        ≤ 1e-6, each entry against max(|β_r|, 1e-3·max|β|)), "converged", "iterations".
        The unseen directions come from `prior`."""
    def coulomb_scale(
        self,
        data: Dataset,
        *,
        candidates: _ArrayLike | None = None,
        folds: int = ...,  # 4
        refine: bool = True,
        max_widenings: int = ...,  # 2
    ) -> dict[str, Any]:
        """Chooses the speed scale v_s (rad/s, m/s) of this chain's smooth Coulomb friction
        fc·tanh(q̇/v_s) from `data` (the chain must have a Coulomb term): for each candidate
        (default 0 = the exact sign, and 16 log-spaced values over 1e-3..0.3) least squares
        on the base parameters is scored by `folds`-fold cross-validation over contiguous
        blocks of samples; an optimum on the edge of the candidates widens the range by a
        decade on that side (at most `max_widenings` times), and the best grid point is
        refined by a parabola in log v_s. Returns {"chosen", "candidates", "cv_rms" (N·m,
        N; None where singular), "reversals" (speed sign changes per joint), "identifiable"
        (False for data without a speed reversal or with a cross-validation curve flat to
        0.1 %, where the chain's own scale is kept, and for an optimum still on an edge
        after the widenings, where the best candidate is chosen), "note" (why not
        identifiable; None otherwise), "widenings", "range" (smallest and largest positive
        candidate scored)}. Apply it with
        `with_friction(..., coulomb_smoothing=report["chosen"])`."""
    def base_parameters(
        self,
        *,
        samples: int = ...,  # 0
        seed: int = ...,  # 0x5EED_BA5E
        rank_tolerance: float = ...,  # 1e-8
    ) -> BaseParameters:
        """Numerical base parameters: QR with column pivoting of the regressor stacked over
        `samples` random states (0 = automatic, ≥ 4·P rows and ≥ 20 states) drawn with
        `seed`, columns scaled to unit norm, rank tolerance `rank_tolerance` in (0, 1).
        Depends on the geometry, gravity direction and friction terms, not on the inertial
        values. The default analysis is cached. TooFewSamplesError if samples·n < P."""
    def base_regressor(
        self,
        q: _ArrayLike,
        qd: _ArrayLike,
        qdd: _ArrayLike,
        *,
        base: BaseParameters | None = None,
    ) -> _F64:
        """Y_b = Y[..., base.independent] with τ = Y_b @ base.base_values(parameters),
        (n, b) or (N, n, b); `base` defaults to `base_parameters()`."""
    def to_json(self) -> str:
        """The complete description as JSON (schema version 1; `from_json` rebuilds it
        exactly). Pickling uses it, so chains from files pickle too."""
    @staticmethod
    def from_json(text: str) -> SerialChain:
        """A chain from the JSON of `to_json`."""
    def __reduce__(self) -> tuple[Any, ...]: ...

class _OnlineUpdate(TypedDict):
    prediction: _F64
    estimate: _F64
    sigma: _F64 | None
    change: bool
    updated: bool

@final
class OnlineIdentifier:
    """Identification while the arm runs: one raw sample at a time, causal (no sample
    after the current one is used), any clock (irregular time stamps, repeated rows).

    Built from a robot (a `SerialChain`, starting from no knowledge) or from a `prior`
    model (`IdentifiedModel`: its robot, β̂ and covariance), not both. `method`: "rls" (joint-
    weighted recursive least squares), "ekf" (the paper's filter on [q, q̇, β], started
    inside the physical region: from the prior, or after `ekf_warmup` s of RLS), "adaline"
    or "hopfield". `payload=True` (needs `prior`) tracks only the 10 inertial parameters
    of a payload at the tip link (m ≥ 0, pseudo-inertia PSD after every update).
    `forgetting`: memory in s (data older weigh < 1/e), directional for RLS unless
    `directional=False`; `change_detection`: an innovation test that opens the covariance
    when the dynamics jump (`change_threshold`: alarm level of the normalised squared
    one-step-ahead error). `cutoff_hz`: bandwidth of the causal filtering (default: 10 Hz,
    lowered once after 1 s of filtered rows to where the positions' sensor noise leaves the
    accelerations within a tenth of their RMS, `settings["cutoff_choice"]`, the one-step-ahead
    predictions' tracker with it; the whole-arm "ekf", whose filter measures q and q̇,
    lowers only the tracker),
    `prior_width`: P₀ = width²·Σ_prior, `ekf_noise`: factor on the EKF's measurement noise
    (1e-3 rad, 1e-2 rad/s), `payload_mass_std` (kg) and `payload_size` (m): the payload
    prior, `initial_covariance` (without a prior; at most 1e9): the RLS's δ on the
    equilibrated parameters, `seed`: of the random states they are equilibrated on.
    `coulomb_scale="auto"` (from no knowledge, a robot with a Coulomb term): the
    speed scale v_s of fc·tanh(q̇/v_s) is chosen online among 0, 0.001, 0.002, 0.004, …,
    0.256 rad/s (an octave apart) and the robot's own, by the one-step-ahead torque errors
    of an RLS of each scale (whatever the method) from 5 s to 10 s after the first row
    (all candidates run until then;
    the estimates before the choice are the robot's own scale's,
    `settings["coulomb_search"]` records it).
    Settings out of range (an unstable step size, a non-positive memory) raise
    InvalidParameterError.

    >>> import numpy as np, prrrp
    >>> robot = prrrp.SerialChain.puma560()
    >>> online = prrrp.OnlineIdentifier(robot, method="rls")
    >>> for k in range(300):
    ...     t = k * 1e-3
    ...     q = np.sin(t * np.arange(1, 7))
    ...     qd = np.arange(1, 7) * np.cos(t * np.arange(1, 7))
    ...     qdd = -np.arange(1, 7) ** 2 * q
    ...     out = online.update(t, q, robot.inverse_dynamics(q, qd, qdd))
    >>> sorted(out)
    ['change', 'estimate', 'prediction', 'sigma', 'updated']
    >>> model = online.estimate()  # an IdentifiedModel, as identify returns
    """

    def __new__(
        cls,
        robot: SerialChain | None = None,
        *,
        prior: IdentifiedModel | None = None,
        method: str = "rls",
        payload: bool = False,
        forgetting: float | None = None,
        directional: bool = True,
        change_detection: bool = True,
        change_threshold: float = 9.0,
        cutoff_hz: float | None = None,
        prior_width: float = 3.0,
        initial_covariance: float = 1e6,
        payload_mass_std: float = 10.0,
        payload_size: float = 0.2,
        ekf_noise: float = 1.0,
        ekf_warmup: float = 2.0,
        step_size: float = 0.5,
        seed: int = ...,  # 0
        coulomb_scale: Literal["auto"] | None = None,
    ) -> Self: ...
    def update(
        self, t: float, q: _ArrayLike, tau: _ArrayLike, qd: _ArrayLike | None = None
    ) -> _OnlineUpdate:
        """One raw sample: time t (s, not decreasing), positions q (rad, m), joint forces
        tau (N·m, N), optionally measured velocities qd (rad/s, m/s; at every sample or
        never). Returns the one-step-ahead `prediction` of this row's forces from the
        estimate before it, the `estimate` after it with its `sigma` (None for Adaline and
        Hopfield), whether a `change` was detected, and whether the row `updated` the
        estimate. NaN, wrong lengths and time running backwards raise and leave the state
        as it was."""
    def estimate(self) -> IdentifiedModel:
        """The current estimate as a model (in payload mode: the prior's arm carrying the
        payload). InvalidParameterError from no knowledge before any row has updated it
        (its zeros are not a model)."""
    def payload(self) -> dict[str, Any] | None:
        """Payload mode: mass (kg), com (m, tip frame), inertia about the com (kg·m²),
        each with σ; None otherwise."""
    @property
    def parameter_names(self) -> list[str]: ...
    @property
    def parameters(self) -> _F64: ...
    @property
    def sigma(self) -> _F64 | None: ...
    @property
    def dof(self) -> int: ...
    @property
    def counts(self) -> tuple[int, int, int, int]:
        """Rows consumed, rows that updated the estimate, repeated rows, changes."""
    @property
    def dropped_alarms(self) -> int:
        """Alarms whose look dropped the opening (a spike, not a change)."""
    @property
    def noise_rms(self) -> list[float]:
        """Running noise level of each joint's torque (N·m or N)."""
    @property
    def ekf_running(self) -> bool: ...
    @property
    def settings(self) -> dict[str, Any]: ...

@final
class IdentifiedModel:
    """An identification result for any robot (schema: docs/model-schema.md): the robot
    description, the base-parameter analysis, β̂ with σ and %σ where the method gives them
    (the EKF gives its covariance), cond(W_b), the RMS torque residual per joint, the
    method, its settings and the preprocessing used. It predicts joint torques on its own
    and saves to / loads from JSON, so a saved model needs neither the robot file nor the
    data."""

    MAX_FILE_BYTES: Final[int]
    """Largest model file `load` reads (256 MiB)."""
    @staticmethod
    def from_json(text: str) -> IdentifiedModel: ...
    @staticmethod
    def load(path: str | os.PathLike[str]) -> IdentifiedModel:
        """A model from a file written by `save`. The path must be a regular file of at
        most MAX_FILE_BYTES, checked before it is opened (a FIFO or /dev/zero is refused,
        never read); a missing, unreadable, oversized or malformed file is an
        InvalidParameterError with `.file`, `.what` (path, size, content) and `.message`, whose
        message names the file and, for bad JSON, the line, column and what is wrong."""
    def to_json(self) -> str: ...
    def save(self, path: str | os.PathLike[str]) -> None:
        """Writes the model as JSON, atomically (a temporary file moved into place)."""
    def to_urdf(self) -> str:
        """A URDF of the robot with the identified inertials, for models of method
        "physical" (they carry physically consistent standard parameters); others raise
        InvalidParameterError (base parameters do not determine each link)."""
    @property
    def standard_parameters(self) -> _F64 | None:
        """Physically consistent standard parameters π (P,) with base values β̂ (method
        "physical"); None otherwise."""
    def report(
        self,
        dir: str | os.PathLike[str],
        data: Dataset,
        *,
        validation: Dataset | None = None,
    ) -> list[Any]:
        """Writes `report.md` and figures (torque prediction per joint on `validation` or
        `data`, residual histograms, friction curves over the data's residual-corrected
        points) about this model into the folder `dir`, built aside and swapped in whole.
        Returns the written paths."""
    def predict(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike) -> _F64:
        """Joint torques τ = Y_b(q, q̇, q̈)·β̂ (N·m or N), (n,) or (N, n)."""
    @property
    def robot(self) -> SerialChain:
        """The robot, with the inertials it was loaded with (a prior)."""
    @property
    def method(self) -> str: ...
    @property
    def beta(self) -> _F64:
        """β̂, (b,), SI units of each combination."""
    @property
    def sigma(self) -> _F64 | None: ...
    @property
    def rsd_percent(self) -> _F64 | None:
        """100·σ/|β̂| (%), NaN where β̂ = 0."""
    @property
    def covariance(self) -> _F64 | None:
        """(b, b), where the method gives it (LS, RLS, EKF)."""
    @property
    def cond(self) -> float | None: ...
    @property
    def converged(self) -> bool:
        """Adaline/Hopfield: the stopping rule held before `max_epochs` (False: β̂ is not
        at the method's optimum). Other methods: True when they finished normally."""
    @property
    def epochs(self) -> int | None:
        """Epochs trained by Adaline/Hopfield; None for the other methods."""
    @property
    def residual_rms(self) -> _F64:
        """(n,), N·m or N, on the identification data."""
    @property
    def base_names(self) -> list[str]: ...
    @property
    def combinations(self) -> list[str]: ...
    @property
    def settings(self) -> dict[str, Any]: ...
    @property
    def preprocessing(self) -> dict[str, Any]: ...
    @property
    def actuators(self) -> list[dict[str, Any]]:
        """Per actuator: 'actuator' (1-based), 'joints' it moves, and 'terms' (fv, fc, fo,
        Ia as the robot has them), each a dict with 'name' (e.g. 'Ia6'), 'base_index' (the
        base parameter it is identified in, None if unidentifiable), 'combination', 'alone'
        (the base parameter is this term alone), 'value' (its β̂), 'sigma', 'standard'
        (physically consistent value, method "physical"). Empty without actuator terms."""
    @property
    def payload(self) -> dict[str, Any] | None:
        """The payload the model carries, or None: 'link', 'link_index' (0-based),
        'parameters' (10: m, m·c, inertia about the link origin; kg, kg·m, kg·m²),
        'covariance' (100, row-major), 'mass' (kg), 'com' (m, link frame), 'inertia'
        ([Ixx, Ixy, Iyy, Ixz, Iyz, Izz] about the COM, kg·m²), their σ ('mass_sigma',
        'com_sigma', 'inertia_sigma'), 'identifiable' ({'mass', 'com', 'inertia'} flags),
        'mass_given' and 'identification' (how). Predictions add its torques."""
    @property
    def drive_gains(self) -> dict[str, Any] | None:
        """Identified drive gains, or None: 'values' and 'sigma' (N·m/A per actuator),
        'identifiable' (bools), 'identification' (method, the naive least-squares gains)."""
    def payload_json(self) -> str | None:
        """The payload as the JSON text of payload.json, or None."""
    def identify_payload(
        self,
        data: Dataset,
        mass: float | None = None,
        *,
        tip: str | int | None = None,
        refit_friction: bool = True,
        max_relative_sigma: float = 0.1,
        com_tolerance: float = 0.01,
    ) -> IdentifiedModel:
        """The arm + payload model from `data`, a run with a payload (torques in this
        model's units): the payload's 10 inertial parameters at the link `tip` (name or
        0-based index; default the last) fitted to the torque this model does not explain,
        by joint-weighted least squares with the friction terms re-fitted
        (`refit_friction`), projected onto the rigid bodies (m > 0, pseudo-inertia ⪰ 0)
        when the fit is not physical. `mass` (kg) fixes a known mass. Each quantity is
        'identifiable' when σ ≤ `max_relative_sigma` × the mass (mass) or × ½·tr(I_C)
        (inertia), or σ ≤ `com_tolerance` m (COM). Raises RankDeficientError when the run
        does not determine the mass, InvalidParameterError when it shows no payload."""
    def without_payload(self) -> IdentifiedModel:
        """This model without its payload (the bare arm)."""
    def __reduce__(self) -> tuple[Any, ...]: ...

def identify_drive_gains(
    model: IdentifiedModel,
    unloaded: Dataset,
    loaded: Dataset,
    mass: float,
    *,
    tip: str | int | None = None,
    iterations: int = 3,
    refit_friction: bool = True,
    max_relative_sigma: float = 0.05,
) -> tuple[IdentifiedModel, dict[str, Any], list[float]]:
    """Drive gains by Gautier & Briot's protocol: `unloaded` and `loaded` hold motor currents
    (A) in their torque columns, of runs without and with a payload of `mass` kg at `tip`;
    `model` gives the robot and base analysis (e.g. the unloaded run identified in current
    units). Instrumental variables (`iterations` ≥ 1; 0 = naive least squares with the
    currents in the regressor, biased by their noise). Returns the arm in torque units with
    'drive_gains' (σ; a gain with σ > `max_relative_sigma` of it is flagged not
    identifiable), the payload dict and the naive least-squares gains."""

def identified_model_from_parts(
    robot: SerialChain,
    beta: _ArrayLike,
    *,
    sigma: _ArrayLike | None = None,
    covariance: _ArrayLike | None = None,
    cond: float | None = None,
    residual_rms: _ArrayLike | None = None,
    method: str = "manual",
    settings: dict[str, Any] | None = None,
    preprocessing: dict[str, Any] | None = None,
    base: BaseParameters | None = None,
) -> IdentifiedModel:
    """An IdentifiedModel from its parts (β̂ in `base`, default `robot.base_parameters()`)."""

def identify(
    robot: SerialChain | Robot,
    data: Dataset,
    method: Literal["ls", "wls", "rls", "adaline", "hopfield", "ekf", "physical"] = "ls",
    *,
    base: BaseParameters | None = None,
    preprocessing: dict[str, Any] | None = None,
    cache: FitCache | None = None,
    **settings: Any,
) -> IdentifiedModel:
    """Identifies the base parameters of `robot` (default analysis `robot.base_parameters()`,
    friction columns included; a `Robot` is the paper's arm, identified through its chain
    form with 9 base parameters) from `data` (a Dataset with the robot's joint count).

    Methods: "ls" / "wls" (ordinary / weighted least squares, σ from the residual); "rls"
    (one pass on the column-equilibrated model, σ from σ̂²·P when `forgetting` = 1);
    "adaline" / "hopfield" (epochs over the data from β = 0, step from the data, each
    epoch starting from the Anderson mixing of the previous epochs' outputs; at each
    step's fixed point (the change still to come, extrapolated geometrically, below
    `parameter_tolerance` (1e-5; changes below 1 % of least squares' σ count as none) and
    the relative change of the epoch's equation error below `error_tolerance` (1e-6)) the
    step is cut by powers of 2 (at most `halvings`, 24, in all) until the step's bias,
    from the move between consecutive steps' fixed points, is below `parameter_tolerance`,
    within `max_epochs` (3000); `converged` and `epochs`
    say how it ended; Adaline's default rule is the delta rule, whose fixed point is least
    squares; no σ); "ekf" (starts from the least-squares β̂, dt from the time stamps,
    positions and velocities measured; process noise from the least-squares residual
    variances through M⁻¹ at each sample and the current estimate;
    covariance from the filter times the residuals' correlation time κ, since low-pass
    filtered data are not white); LS σ and covariance also carry κ;
    "physical" (least squares over the standard parameters with every link's pseudo-inertia
    positive semidefinite and fv, fc ≥ 0, a barrier interior-point method; the model keeps
    the standard parameters, `standard_parameters`, and writes a URDF, `to_urdf()`; no σ).

    Settings (keywords; an unknown one is a TypeError naming the valid ones): all methods
    `rank_tolerance`; rls `forgetting`, `initial_covariance` (at most 1e9 with
    `scale_columns`, the default), `scale_columns`; adaline
    `rule`, `step_size` (0, 2), `learning_rate` (delta rule; unstable → error),
    `max_epochs`, `halvings`, `parameter_tolerance`, `error_tolerance`, `scale_columns`,
    `whiten` (default True: the network runs on parameters whose regressor columns are
    orthogonal, so that it converges in tens of epochs whatever cond(W)); hopfield
    `step_size`, `bound`, `max_epochs`, `halvings`, `parameter_tolerance`,
    `error_tolerance`, `scale_columns`, `whiten`; ekf `initial` ("ls", "prior" or β0), `dt`,
    `measurement`, `discretisation`, the noise settings of `Ekf` (a given `position_noise`
    or `velocity_noise` replaces the one from the data), `noise_from_data` (R from the data's
    third differences, default False), `process_noise_at_estimate` (default True),
    `correlation_correction` (default True: a sandwich covariance with each joint's
    residual variance and correlation time), `parameter_jacobian` ("predicted" or
    "data_acceleration", the default: the Jacobian linearised at the data's q̈, free of the
    input-noise bias), `least_squares_prior_width` (default 3: P0 of β is 3² times the
    weighted least-squares covariance; 0 for the diagonal prior), `stiff_handling` (default
    True: the time update is linearly implicit at samples where the dynamics are too stiff
    for the explicit step, h·‖∂q̈/∂q̇‖∞ + h²·‖∂q̈/∂q‖∞ > 0.5; the trapezoidal rule,
    second order and A-stable); `discretisation` of
    ekf also takes "midpoint" (its default); physical `prior`
    (standard parameters π0; default the robot's own, `robot.parameters`: a URDF's
    inertials), `divergence_weight` (γ ≥ 0, default 10: the log-det divergence of each
    link's pseudo-inertia from the prior's, in units of the data's χ², holds at the prior
    what the data do not determine without biasing what they do), `prior_weight` (≥ 0,
    default 0: an extra ridge towards π0), `weighted` (default True: each joint weighted
    by 1/σ_j² as wls estimates it; False: unit weights). The
    model records the settings used, including the values chosen from the data.
    Errors: ShapeMismatchError (joint count), TooFewSamplesError, RankDeficientError (data
    that do not excite every base parameter), InvalidParameterError (unknown method, a
    setting out of range, an unstable step), DivergedError, NonFiniteError.

    `cache`: a :class:`FitCache` shared by several calls on the same robot, base analysis
    and data, so that they stack the least-squares regressor W_b once per weighting
    instead of once each (the models are the same bit for bit); a cache used with other
    inputs is an InvalidParameterError."""

@final
class FitCache:
    """The least-squares work several :func:`identify` calls on one data set share: the
    stacked base regressor W_b and its solve, once unweighted (ls, rls, adaline, hopfield,
    physical with ``weighted=False``) and once weighted (wls, ekf, physical) per rank
    tolerance, built by the first call that needs it (a second thread waits for it).
    Belongs to one robot, base analysis and data set (the first call records a
    fingerprint; others are refused). Holds up to two copies of W_b (8 bytes × samples ×
    joints × base parameters each) until dropped: make one per data set."""

    def __init__(self) -> None: ...
    @property
    def stacks(self) -> int:
        """Least-squares stacks held (at most one per weighting and rank tolerance)."""

@final
class BaseParameters:
    """Result of `SerialChain.base_parameters()`: base parameters β = map @ π (b of them)."""

    @property
    def count(self) -> int:
        """b."""
    @property
    def num_params(self) -> int:
        """P (standard parameters)."""
    @property
    def names(self) -> list[str]:
        """Names of the P standard parameters."""
    @property
    def independent(self) -> npt.NDArray[np.int64]:
        """Indices of the standard parameters kept as base parameters, (b,), increasing."""
    @property
    def independent_names(self) -> list[str]: ...
    @property
    def dependent(self) -> npt.NDArray[np.int64]:
        """Indices regrouped into the independent ones or unidentifiable, (P − b,)."""
    @property
    def unidentifiable(self) -> npt.NDArray[np.int64]:
        """Indices that affect no joint force (a subset of `dependent`)."""
    @property
    def map(self) -> _F64:
        """K, (b, P): β = K @ π, identity on the independent columns."""
    @property
    def combinations(self) -> list[str]:
        """Each β_r as a readable combination, e.g. '0.4318*m2 + mx2 + ...'."""
    @property
    def pivots(self) -> _F64:
        """|R_kk| of the scaled pivoted QR (the rank gap)."""
    @property
    def rank_tolerance(self) -> float: ...
    def base_values(self, parameters: _ArrayLike) -> _F64:
        """β = K @ π for π of shape (P,) or (N, P): (b,) or (N, b)."""
    def __len__(self) -> int: ...

# --- data sets, validation, sensitivity --------------------------------------------------

__all__ += [
    "Dataset",
    "clear_stop",
    "preprocess_log",
    "read_numeric_csv",
    "request_stop",
    "sensitivity",
    "stop_requested",
    "torque_prediction",
    "validate",
]

@final
class Dataset:
    """An identification data set of any robot, checked on creation: t (N,) s strictly
    increasing; q, qd, qdd, tau (N, n) (m, rad; m/s, rad/s; m/s², rad/s²; N, N·m), n joints
    from q's shape; N ≥ 8; every value finite. Errors: ShapeMismatchError, NonFiniteError
    (with .row), NonIncreasingTimeError (.row), TooFewSamplesError. Functions of the paper's
    arm (`torque_prediction`, ...) take 5-joint data sets."""

    MIN_SAMPLES: Final[int]
    def __new__(
        cls, t: _ArrayLike, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, tau: _ArrayLike
    ) -> Self: ...
    @staticmethod
    def from_dict(d: Mapping[str, _ArrayLike]) -> Dataset:
        """From a mapping with keys t, q, qd, qdd, tau (e.g. `preprocess(...)`'s result)."""
    @property
    def t(self) -> _F64: ...
    @property
    def q(self) -> _F64: ...
    @property
    def qd(self) -> _F64: ...
    @property
    def qdd(self) -> _F64: ...
    @property
    def tau(self) -> _F64: ...
    @property
    def dof(self) -> int:
        """Number of joints n."""
    @property
    def duration(self) -> float:
        """t[-1] − t[0], s."""
    def slice(self, start: int, stop: int) -> Dataset:
        """Samples start..stop as a new data set (TooFewSamplesError below 8)."""
    def __getitem__(self, key: builtins.slice, /) -> Dataset:
        """Contiguous slices only (step 1)."""
    def __len__(self) -> int: ...
    def to_dict(self) -> _Dataset: ...

class _LogReport(TypedDict):
    rows_in: int
    repeated_rows: int
    """Rows whose time stamp repeats the previous one (dropped; the first is kept)."""
    conflicting_repeats: int
    """Of those, rows whose values differ from the kept one."""
    median_rate_hz: float
    rate_hz: float
    """Rate of the uniform grid the log was resampled onto."""
    resampled: bool
    largest_gap_s: float
    largest_gap_row: int
    cutoff_hz: float
    order: int
    trim_samples: int
    trim_s: float
    decimation: int
    output_rate_hz: float
    measured_velocity: bool
    rows_out: int

def request_stop() -> None:
    """Asks every running prrrp computation of this process, in any thread, to stop: each
    raises ``KeyboardInterrupt`` at its next check (no partial result) and new ones stop
    at once, until :func:`clear_stop`. For a host that runs computations in several
    threads and must stop them all (a Ctrl-C reaches only the main thread's call)."""

def clear_stop() -> None:
    """Lowers the flag of :func:`request_stop`, so that new computations run."""

def stop_requested() -> bool:
    """Whether the flag of :func:`request_stop` is raised."""

def read_numeric_csv(data: bytes) -> tuple[str, int, int, int, bytes] | None:
    """(header line, its 1-based line number, rows, cells per row, the values as native
    float64 bytes, row after row) of a plain numeric CSV text, or None for anything else
    (for ``prrrp.csvio``'s general reader)."""

def preprocess_log(
    t: _ArrayLike,
    q: _ArrayLike,
    tau: _ArrayLike,
    *,
    qd: _ArrayLike | None = None,
    rate_hz: float | None = None,
    cutoff_hz: float | None = None,
    order: int = ...,  # 4
    filter_torque: bool = True,
    trim_s: float | None = None,
    decimate_to_hz: float | None = None,
    max_gap_s: float | None = None,
) -> tuple[Dataset, _LogReport]:
    """A Dataset of n joints from a real log: t (N,) s, q and tau (N, n), optional measured
    velocities qd (N, n). Rows repeating the previous time stamp are dropped (counted); time
    running backwards is NonIncreasingTimeError naming the row; the log is resampled
    linearly onto a uniform grid at `rate_hz` (default: its median rate; a whole multiple of
    `decimate_to_hz` when that is set); zero-phase Butterworth low-pass of order `order` at
    `cutoff_hz` (default min(10 Hz, output rate/10)) on q, measured qd and (if
    `filter_torque`) tau; q̇ differentiated from q unless measured, q̈ from q̇; `trim_s`
    seconds dropped at each end (default 3 cut-off periods); then decimation to
    `decimate_to_hz`. A gap longer than `max_gap_s` (default half a cut-off period;
    `math.inf` accepts any) is an InvalidParameterError naming its row. Returns the data set
    and a report of what was done."""

class _TorquePrediction(TypedDict):
    rms: _F64
    """RMS of tau − predicted per joint, (5,) N, N·m."""
    relative_percent: _F64
    """100·‖tau − predicted‖/‖tau‖ per joint, (5,) %."""
    predicted: _F64
    """Φ(q, q̇, q̈)·λ̂, (N, 5)."""

def torque_prediction(
    data: Dataset | Mapping[str, _ArrayLike], lam: _ArrayLike, *, gravity: float = STANDARD_GRAVITY
) -> _TorquePrediction:
    """Predicts data's torques with Φ(q, q̇, q̈)·lam (8,) and compares them with data.tau.

    The paper's arm in closed form only (its study); for any robot:
    `IdentifiedModel.predict`."""

class _ValidationIndices(TypedDict):
    rms: _F64
    rsd: _F64
    ai: _F64

class _MethodValidation(TypedDict):
    method: str
    lam: _F64
    q: _F64
    """Positions of the robot simulated with λ̂, (N, 5)."""
    indices: _ValidationIndices
    """RMS, RSD, AI of q against the true run's, each (5,) (paper Table 5)."""
    torque: _TorquePrediction
    """Φ·λ̂ on the true run's noise-free states against its measured torques."""
    relative_error_percent: _F64 | None
    """100·|λ̂ − λ|/|λ|, (8,); None with relative_errors=False."""

class _Validation(TypedDict):
    truth: _Record
    methods: list[_MethodValidation]

def validate(
    estimates: Mapping[str, _ArrayLike] | list[tuple[str, _ArrayLike]],
    *,
    true_lam: _ArrayLike | None = None,
    relative_errors: bool = True,
    reference: SinusoidReference | None = None,
    duration: float = 10.0,
    seed: int = ...,  # 1
    **options: Unpack[_ClosedLoop],
) -> _Validation:
    """Validation of estimates λ̂ (paper §5.1): the true robot (true_lam, default Table 3)
    and each λ̂ follow `reference` (default: one sinusoid per joint, periods 5, 4, 3.5, 3,
    2.5 s) under the same computed-torque controller (controller_lam, default true_lam);
    trajectories are compared by RMS/RSD/AI and torques predicted on the true run. The true
    run has sensor noise (seed `seed`), the estimate runs none. Errors of the simulator
    (NotPositiveDefiniteError for a non-physical λ̂, DivergedError).

    The paper's arm in closed form only (its study); for any robot:
    `validate_model`."""

class _Sensitivity(TypedDict):
    factors: _F64
    """Scale factors applied to each λ_i, (K,), e.g. 0.5, 0.6, ..., 1.5."""
    ranges: _F64
    """(8, 2): [min, max] of each λ_i over the sweep (Table 6)."""
    rms: _F64
    """(8, K, 5): trajectory RMS of each joint against the nominal run when λ_i is scaled by
    factors[k]; NaN where the varied λ is not physical."""
    physical: npt.NDArray[np.bool_]
    """(8, K): False where the varied λ is not physical — M(q, λ) not positive definite
    somewhere along the motion, so no robot has it (core returns None there)."""

def sensitivity(
    *,
    nominal: _ArrayLike | None = None,
    range: float = 0.5,
    points: int = ...,  # 11
    threads: int = ...,  # 0
    reference: SinusoidReference | None = None,
    duration: float = 10.0,
    dt: float = 0.02,
    substeps: int = ...,  # 20
    kp: _ArrayLike | None = None,
    kd: _ArrayLike | None = None,
    progress: Callable[[int, int], object] | None = None,
) -> _Sensitivity:
    """Sensitivity of the simulated robot to each λ_i (paper Table 6, Fig. 8): λ_i scaled by
    `points` factors in [1 − range, 1 + range] (0 < range < 1), the others nominal (default
    Table 3), each run tracking `reference` under the nominal controller without noise.
    threads = 0 uses every core. Runs in Rust with the GIL released; `progress(done,
    total)` is called on the calling thread while it runs, and an exception it raises stops
    the sweep and is raised."""

# --- simulation and validation of any chain -----------------------------------------------

__all__ += [
    "Canvas",
    "ChainSimulation",
    "ChainTrajectory",
    "design_excitation",
    "simulate_chain",
    "simulate_chain_open_loop",
    "validate_model",
]

@final
class ChainTrajectory:
    """A reference trajectory of n joints (any robot): per-joint Fourier series, one
    sinusoid per joint, or a recorded trajectory. Units: m, rad; m/s, rad/s; m/s², rad/s²."""

    @staticmethod
    def fourier(omega: float, offsets: _ArrayLike, a: _ArrayLike, b: _ArrayLike) -> ChainTrajectory:
        """Finite Fourier series (Swevers 1997) with base angular frequency `omega` (rad/s,
        > 0), offsets q0 (n,) and sine/cosine coefficients a, b (n, H) in velocity units:
        q_j = q0_j + Σ_l [a_jl/(ω·l)·sin(ω·l·t) − b_jl/(ω·l)·cos(ω·l·t)]. Periodic, so
        defined for every t (end_time None). Starts at rest when Σ_l a_jl = 0 and
        Σ_l l·b_jl = 0."""
    @staticmethod
    def sinusoids(
        offset: _ArrayLike,
        amplitude: _ArrayLike,
        omega: _ArrayLike,
        phase: _ArrayLike | None = None,
    ) -> ChainTrajectory:
        """q_j = offset_j + amplitude_j·sin(omega_j·t + phase_j); offset (n,) sets n, the
        others are scalars or (n,); phase defaults to 0 (rad)."""
    @staticmethod
    def sampled(t: _ArrayLike, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike) -> ChainTrajectory:
        """A recorded trajectory: t (N,) s strictly increasing (taken relative to t[0]),
        q, qd, qdd (N, n); interpolated by the quintic matching (q, q̇, q̈) at both ends of
        each interval; ends at the last sample."""
    @property
    def dof(self) -> int:
        """Number of joints n."""
    @property
    def end_time(self) -> float | None:
        """Last time at which the trajectory is defined (s), or None."""
    def eval(self, t: _ArrayLike) -> tuple[_F64, _F64, _F64]:
        """(q, qd, qdd) at a scalar t (each (n,)) or at t of shape (N,) (each (N, n))."""

@final
class ChainSimulation:
    """What `simulate_chain` / `simulate_chain_open_loop` recorded at t_k = k/rate. The true
    signals are consistent: tau[k] = inverse dynamics of the chain at (q, qd, qdd)[k]."""

    @property
    def dof(self) -> int:
        """Number of joints n."""
    def __len__(self) -> int: ...
    @property
    def t(self) -> _F64:
        """Time stamps (N,), s."""
    @property
    def q(self) -> _F64:
        """True positions (N, n), m or rad."""
    @property
    def qd(self) -> _F64:
        """True velocities (N, n)."""
    @property
    def qdd(self) -> _F64:
        """True accelerations (N, n) at the sample instant, under the torque applied from it."""
    @property
    def tau(self) -> _F64:
        """Applied torques (N, n), N or N·m, held from the sample instant."""
    @property
    def q_ref(self) -> _F64 | None:
        """Reference positions (N, n); None for open-loop runs."""
    @property
    def qd_ref(self) -> _F64 | None:
        """Reference velocities (N, n); None for open-loop runs."""
    @property
    def qdd_ref(self) -> _F64 | None:
        """Reference accelerations (N, n); None for open-loop runs."""
    @property
    def q_measured(self) -> _F64:
        """q plus Gaussian noise (N, n)."""
    @property
    def qd_measured(self) -> _F64 | None:
        """qd plus Gaussian noise (N, n); None unless qd_noise was given."""
    @property
    def tau_measured(self) -> _F64:
        """tau plus Gaussian noise (N, n)."""
    def true_dataset(self) -> Dataset:
        """The noise-free (t, q, qd, qdd, tau) as a Dataset (at least 14 samples)."""
    def measured_dataset(self, **kwargs: Any) -> tuple[Dataset, dict[str, Any]]:
        """`preprocess_log(t, q_measured, tau_measured, qd=qd_measured, **kwargs)`: the
        Dataset an estimator would see on the real robot, and the preprocessing report."""

def simulate_chain(
    chain: SerialChain,
    reference: ChainTrajectory | Dataset | Mapping[str, _ArrayLike] | tuple[Any, ...],
    duration: float,
    *,
    rate: float = 100.0,
    substeps: int = ...,  # 10
    controller: SerialChain | None = None,
    kp: _ArrayLike | None = None,
    kd: _ArrayLike | None = None,
    q_noise: _ArrayLike | None = None,
    qd_noise: _ArrayLike | None = None,
    tau_noise: _ArrayLike | None = None,
    seed: int = ...,  # 0
) -> ChainSimulation:
    """Simulates `chain` (its inertials and friction) tracking `reference` (a
    ChainTrajectory, a Dataset, a dict with t, q, qd, qdd, or a tuple (t, q, qd, qdd)) from
    t = 0 to `duration` s, starting on it, under computed-torque control
    τ = ID_ctrl(q, q̇, q̈_r + kd·(q̇_r − q̇) + kp·(q_r − q)) with the model `controller`
    (default: the chain itself). RK4 with `substeps` steps per sample of `rate` Hz; the
    controller updates at every step. kp (1/s², default 400), kd (1/s, default 40) and the
    Gaussian noise stds q_noise (m, rad), qd_noise (m/s, rad/s; velocities are measured
    only when given), tau_noise (N, N·m) are scalars or (n,); noise defaults to none.
    Seeded (ChaCha8). Runs in Rust with the GIL released; Ctrl-C interrupts. Raises
    ShapeMismatchError for joint-count mismatches, InvalidParameterError for bad rates,
    gains, noise or durations, DivergedError (attributes at, time, joint, signal) if the
    state becomes NaN/∞."""

def simulate_chain_open_loop(
    chain: SerialChain,
    q0: _ArrayLike,
    qd0: _ArrayLike,
    tau: _ArrayLike,
    *,
    rate: float = 100.0,
    substeps: int = ...,  # 10
    q_noise: _ArrayLike | None = None,
    qd_noise: _ArrayLike | None = None,
    tau_noise: _ArrayLike | None = None,
    seed: int = ...,  # 0
) -> ChainSimulation:
    """Simulates `chain` from (q0, qd0) (n,) under the torques tau (N, n), row k held over
    [k/rate, (k+1)/rate) (zero-order hold). No reference (q_ref etc. are None)."""

class _TorqueValidation(TypedDict):
    rms: _F64
    """(n,) RMS of measured minus predicted torque per joint, N or N·m."""
    rsd: _F64
    """(n,) ‖τ − τ̂‖/‖τ‖ per joint (dimensionless; 0 is perfect)."""
    ai: _F64
    """(n,) Willmott's agreement index per joint, in [0, 1] (1 is perfect)."""
    predicted: _F64
    """(N, n) predicted torques."""

def validate_model(
    model: IdentifiedModel | SerialChain,
    data: Dataset,
    *,
    beta: _ArrayLike | None = None,
    base: BaseParameters | None = None,
) -> _TorqueValidation:
    """Torque-prediction validation on a Dataset the model was not fitted on: predicts
    data's torques from its (q, qd, qdd) and compares them with data.tau per joint (paper
    eqs. 45–47). `model` is an IdentifiedModel (τ̂ = Y_b·β̂), or a SerialChain with its
    own parameters, or a SerialChain with base parameters `beta` in the analysis `base`
    (default the chain's `base_parameters()`). Raises ShapeMismatchError if data's joint
    count is not the model's. The reference is data.tau as given: for a Dataset made by
    `preprocess_log` that is the low-passed torque, not the measurement; score a log with
    `prrrp.prediction.prepare(raw, settings)` instead (against the measured torque at the
    log's rows)."""

def design_excitation(
    robot: SerialChain,
    *,
    harmonics: int = ...,  # 5
    base_frequency: float = 0.1,
    sample_rate: float = 10.0,
    margin: float = 0.05,
    seed: int = ...,  # 0
    restarts: int = ...,  # 16
    max_evaluations: int = ...,  # 2000
    limits: dict[str, _ArrayLike] | None = None,
    progress: Callable[[int, int], object] | None = None,
) -> dict[str, Any]:
    """An exciting trajectory for any robot: per joint a finite Fourier series of
    `harmonics` harmonics of `base_frequency` (Hz; one period = 1/base_frequency s),
    starting and ending at rest, each joint scaled to use (1 − margin) of its tightest
    position / speed / acceleration limit, with coefficients that minimise cond(W_b) of the
    robot's base regressor (friction columns included) sampled at `sample_rate` Hz;
    Nelder–Mead from the best of `restarts` seeded random shapes, `max_evaluations` in all.
    Limits are the robot file's; `limits` overrides them ({"lower", "upper", "velocity",
    "acceleration"}: (n,) arrays, NaN = none). A joint whose limits do not bound its motion
    (no speed limit, or neither position nor acceleration limit) is an InfeasibleError
    naming it and what is missing. `progress(evaluations, max_evaluations)` is called
    every few evaluations. Returns {"trajectory": ChainTrajectory, "omega" (rad/s),
    "offsets" (n,), "a", "b" (n, H), "period" (s), "cond_initial", "cond_final",
    "evaluations", "limit_usage" (n, 3): fraction of each limit used, NaN where none}."""

_Rgba = tuple[int, int, int, int]

@final
class Canvas:
    """A white RGBA image of width × height pixels (1..16384 each) to draw on, in pixel
    coordinates (x right, y down from the top-left corner); colours (r, g, b, a) of
    0..255. The native part of :mod:`prrrp.canvas` (the report figures without
    matplotlib). Errors: InvalidInputError."""

    def __new__(cls, width: int, height: int) -> Self: ...
    @property
    def size(self) -> tuple[int, int]:
        """(width, height), pixels."""
    def set_clip(self, rect: tuple[float, float, float, float] | None) -> None:
        """Shapes drawn next stay inside the rectangle (x0, y0, x1, y1); None lifts it."""
    def polyline(
        self, xs: _ArrayLike, ys: _ArrayLike, color: _Rgba, width: float, dash: list[float] = ...
    ) -> None:
        """A line through (xs[i], ys[i]), ``width`` pixels wide; ``dash``: on/off lengths
        (pixels; empty: solid). NaN breaks the line."""
    def fill_rect(self, x0: float, y0: float, x1: float, y1: float, color: _Rgba) -> None:
        """A filled rectangle between the corners (x0, y0) and (x1, y1)."""
    def stroke_rect(
        self, x0: float, y0: float, x1: float, y1: float, color: _Rgba, width: float
    ) -> None:
        """A rectangle's outline, ``width`` pixels wide."""
    def fill_polygon(self, xs: _ArrayLike, ys: _ArrayLike, color: _Rgba) -> None:
        """The closed polygon through (xs[i], ys[i]), filled."""
    def markers(self, xs: _ArrayLike, ys: _ArrayLike, radius: float, color: _Rgba) -> None:
        """A filled disc of ``radius`` pixels at each (xs[i], ys[i])."""
    def text(
        self,
        text: str,
        x: float,
        y: float,
        size: float,
        ha: str = "left",
        va: str = "baseline",
        rotation: float = 0.0,
        color: _Rgba = ...,
    ) -> None:
        """``text`` at ``size`` pixels per em anchored (ha: left/center/right, va:
        top/center/baseline/bottom) at (x, y), rotated ``rotation`` degrees
        counter-clockwise, in ``color`` (default black)."""
    def text_extent(self, text: str, size: float) -> tuple[float, float, float]:
        """(width, ascent, descent) of ``text`` at ``size`` pixels per em, pixels."""
    def png(self) -> bytes:
        """The image as PNG bytes."""
