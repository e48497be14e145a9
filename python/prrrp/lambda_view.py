"""The paper's λ view of a model identified on the built-in ``paper`` robot.

Urrea & Pascal group the PRRRP arm's dynamics into 8 parameters λ1..λ8 (units:
:data:`prrrp.paper.PARAMETER_UNITS`). The general pipeline identifies the chain's base
parameters β instead; on the paper's arm both describe the same torques, so λ = T·β for a
fixed T (:func:`lambda_map`), and σ_λ follows from β's covariance. This is a view of one
robot's model, not a second API: any :class:`prrrp.IdentifiedModel` of ``--robot paper``
has it, every other robot has none.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

import prrrp
from prrrp import _prrrp

#: :attr:`SerialChain.name` of the built-in ``paper`` robot.
PAPER_ROBOT_NAME = "paper-prrrp"


@functools.cache
def _rigid_base_names() -> tuple[str, ...]:
    return tuple(prrrp.SerialChain.paper().base_parameters().independent_names)


@functools.cache
def lambda_map() -> np.ndarray:
    """T, (8, 9): the paper's λ = T @ β for the base parameters β of
    ``prrrp.identify(prrrp.load_robot("paper"), ...)``: the library's map
    (``PaperLambdaView``, the same one the study reports its λ through).

    The chain's 9 base parameters span the paper's λ1..λ5, λ8, m4·lc4 + m5·l4 (λ6 and λ7
    are l2 and l3 times it) and the first moments across links 3 and 4, which the paper's
    model sets to 0. So Y_b(x)·β = Φ(x)·λ + Y_μ(x)·μ at every state x (Y_μ the closed
    form's first-moment columns), and T is the λ rows of the exact solution of
    [Φ | Y_μ]·[T; L] = Y_b over states (checked to round-off: an identity, not a fit)."""
    return np.asarray(_prrrp.paper_lambda_map(), dtype=float)


def paper_lambda(model: prrrp.IdentifiedModel) -> dict[str, Any] | None:
    """The paper's λ1..λ8 of ``model`` with σ (None where the method gives no
    covariance), or None when the model is not of the built-in ``paper`` robot (its
    base parameters then have no λ). Friction columns of the model are not part of λ
    (the paper's model has no friction); they are left out of the map.

    Returns ``{"names": ["lambda1", …], "units": […], "lambda": […], "sigma": […] | None}``.
    """
    if model.robot.name != PAPER_ROBOT_NAME:
        return None
    names = list(model.base_names)
    rigid = _rigid_base_names()
    if not all(n in names for n in rigid):
        return None
    idx = [names.index(n) for n in rigid]
    t = lambda_map()
    beta = np.asarray(model.beta)[idx]
    lam = t @ beta
    sigma = None
    cov = model.covariance
    if cov is not None:
        c = np.asarray(cov)[np.ix_(idx, idx)]
        sigma = np.sqrt(np.clip(np.diag(t @ c @ t.T), 0.0, None)).tolist()
    from prrrp import paper

    return {
        "names": [f"lambda{k + 1}" for k in range(prrrp.NPARAM)],
        "units": list(paper.PARAMETER_UNITS),
        "lambda": lam.tolist(),
        "sigma": sigma,
    }
