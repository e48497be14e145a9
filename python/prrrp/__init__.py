"""prrrp: dynamic models and parameter identification of serial robot manipulators.

A robot is loaded by name or from a file — :func:`load_robot` with ``"paper"`` (the 5-DOF
PRRRP arm of Urrea & Pascal, "Parameter identification methods for real redundant
manipulators", J. Appl. Res. Technol. 15 (2017) 320-331), a ``.urdf`` or a ``.toml`` robot
file — and every robot runs through the same functions: :func:`excite`, :func:`simulate`,
:func:`identify_measurements` (an :class:`IdentifiedModel` that predicts torques and saves to
JSON), :class:`OnlineIdentifier`, :func:`benchmark`, and the ``prrrp`` command. The paper's
closed-form model in its 8 grouped parameters λ (:class:`Robot`, :func:`regressor`, …) is
the fast path of its study (``prrrp reproduce``); its functions are for that arm only, each
beside the general one: :func:`regressor` (``SerialChain.regressor``), :func:`least_squares`
(:func:`identify`), :func:`preprocess` (:func:`preprocess_log`), :func:`optimise_excitation`
(:func:`excite`), :func:`simulate_closed_loop` (:func:`simulate`), :func:`validate`
(:func:`validate_model`). A model of ``"paper"`` also reads in λ: :func:`paper_lambda`.

Conventions: SI units (m and rad, N and N·m, kg, kg·m, kg·m²); world z up, gravity along -z
(9.81 m/s² by default). Functions take numpy arrays (anything convertible to float64) for
one sample, shape (n,), or a batch with a leading axis N, shape (N, n), and return float64
arrays of the matching shape; batches are computed in Rust with the GIL released. For the
paper's arm q = [d1, θ2, θ3, θ4, d5] (m, rad, rad, rad, m) and τ = [F1, τ2, τ3, τ4, F5]
(N, N·m, N·m, N·m, N).

>>> import numpy as np, prrrp
>>> robot = prrrp.load_robot("paper")          # or "arm.urdf" (with tip=...), "arm.toml"
>>> q, qd, qdd = np.zeros(5), np.ones(5), np.ones(5)
>>> tau = robot.inverse_dynamics(q, qd, qdd)
>>> closed_form = prrrp.Robot.paper()
>>> bool(np.allclose(closed_form.inverse_dynamics(q, qd, qdd), tau))
True
>>> bool(np.allclose(prrrp.regressor(q, qd, qdd) @ closed_form.base_parameters(), tau))
True

Layers, and where a new robot, estimator or file format goes: docs/architecture.md.
"""

import json
from collections.abc import Callable
from typing import Any

from prrrp import payload
from prrrp._prrrp import (
    MAX_FACTOR,
    MAX_HARMONICS,
    MAX_MAGNITUDE,
    MIN_FACTOR,
    NDOF,
    NPARAM,
    SETTLING_PERIODS,
    STANDARD_GRAVITY,
    Adaline,
    BaseParameters,
    ChainSimulation,
    ChainTrajectory,
    Dataset,
    DivergedError,
    Ekf,
    Excitation,
    FitCache,
    ForwardDerivatives,
    Hopfield,
    IdentifiedModel,
    InfeasibleError,
    InvalidInputError,
    InvalidParameterError,
    InverseDerivatives,
    LeastSquaresResult,
    NonFiniteError,
    NonIncreasingTimeError,
    NotPositiveDefiniteError,
    OnlineIdentifier,
    PrrrpError,
    RankDeficientError,
    Rls,
    Robot,
    RobotFileError,
    SerialChain,
    ShapeMismatchError,
    SinusoidReference,
    TooFewSamplesError,
    __version__,
    agreement_index,
    clear_stop,
    condition_number,
    design_excitation,
    error_indices,
    identified_model_from_parts,
    identify,
    identify_drive_gains,
    is_factor,
    joint_limits,
    least_squares,
    observation_matrix,
    optimise_excitation,
    preprocess,
    preprocess_log,
    regressor,
    relative_errors_percent,
    request_stop,
    rms,
    rsd,
    run_study_json,
    sensitivity,
    simulate_chain,
    simulate_chain_open_loop,
    simulate_closed_loop,
    simulate_open_loop,
    singular_values,
    stop_requested,
    torque_prediction,
    validate,
    validate_model,
)
from prrrp.lambda_view import paper_lambda
from prrrp.measurements import measurements_to_dataset, read_measurements
from prrrp.montecarlo import benchmark
from prrrp.workflow import (
    Identification,
    TrackingError,
    excite,
    identify_measurements,
    load_robot,
    simulate,
)

__all__ = [
    "MAX_FACTOR",
    "MAX_HARMONICS",
    "MAX_MAGNITUDE",
    "MIN_FACTOR",
    "NDOF",
    "NPARAM",
    "SETTLING_PERIODS",
    "STANDARD_GRAVITY",
    "Adaline",
    "BaseParameters",
    "ChainSimulation",
    "ChainTrajectory",
    "Dataset",
    "DivergedError",
    "Ekf",
    "Excitation",
    "FitCache",
    "ForwardDerivatives",
    "Hopfield",
    "Identification",
    "IdentifiedModel",
    "InfeasibleError",
    "InvalidInputError",
    "InvalidParameterError",
    "InverseDerivatives",
    "LeastSquaresResult",
    "NonFiniteError",
    "NonIncreasingTimeError",
    "NotPositiveDefiniteError",
    "OnlineIdentifier",
    "PrrrpError",
    "RankDeficientError",
    "Rls",
    "Robot",
    "RobotFileError",
    "SerialChain",
    "ShapeMismatchError",
    "SinusoidReference",
    "TooFewSamplesError",
    "TrackingError",
    "__version__",
    "agreement_index",
    "benchmark",
    "clear_stop",
    "condition_number",
    "design_excitation",
    "error_indices",
    "excite",
    "identified_model_from_parts",
    "identify",
    "identify_drive_gains",
    "identify_measurements",
    "is_factor",
    "joint_limits",
    "least_squares",
    "load_robot",
    "measurements_to_dataset",
    "observation_matrix",
    "optimise_excitation",
    "paper_lambda",
    "payload",
    "preprocess",
    "preprocess_log",
    "read_measurements",
    "regressor",
    "relative_errors_percent",
    "request_stop",
    "rms",
    "rsd",
    "run_study",
    "sensitivity",
    "simulate",
    "simulate_chain",
    "simulate_chain_open_loop",
    "simulate_closed_loop",
    "simulate_open_loop",
    "singular_values",
    "stop_requested",
    "torque_prediction",
    "validate",
    "validate_model",
]


def run_study(
    seed: int = 0, progress: Callable[[str, int, int], object] | None = None
) -> dict[str, Any]:
    """Runs the paper's whole study (excitation, simulation, the four estimators,
    validation, sensitivity) on the paper robot and returns the parsed JSON result
    (schema_version 1). `progress(stage, done, total)` is called on the calling thread
    while the study runs; an exception it raises stops the study and is raised."""
    return json.loads(run_study_json(seed, progress))
