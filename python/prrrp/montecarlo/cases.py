"""The grid of a Monte-Carlo benchmark and the runner of one case.

One case is one seed × sensor-noise scale × sampling rate. It designs an exciting
trajectory, runs the simulated robot along it in closed loop, adds sensor noise,
preprocesses the record like a real log, identifies the base parameters with each method,
and predicts the torques of a second, noise-free trajectory the methods never saw.

Determinism: every random stream of a case is derived from its seed alone (excitation
from ``seed``, sensor noise and the validation trajectory from ``SeedSequence([seed, k])``),
so a case gives the same numbers in any process, on any worker and in any order. The noise
realisation of a seed is the same at every noise scale (only scaled), and its excitation
the same at every rate, so the grid's comparisons are paired.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import time
from typing import Any

import numpy as np

from prrrp._prrrp import MAX_FACTOR

#: Methods a benchmark can run (``prrrp.identify``'s), in report order.
METHODS = ("ls", "wls", "rls", "adaline", "hopfield", "ekf", "physical")
#: The issue's default selection: least squares and the four on-line methods.
DEFAULT_METHODS = ("ls", "rls", "adaline", "hopfield", "ekf")

#: The error columns of a row (%): base parameters against the truth
#: (:func:`parameter_errors`) and torques on the validation data.
ERROR_COLUMNS = (
    "max_param_error_percent",
    "median_param_error_percent",
    "param_error_norm_percent",
    "torque_rms_relative_percent",
)
#: Columns of ``results.csv``, in order (one row per case × method).
COLUMNS = (
    "seed",
    "noise",
    "rate",
    "excitation_evaluations",
    "method",
    "status",
    *ERROR_COLUMNS,
    "converged",
    "epochs",
    "seconds",
    "samples",
    "excitation_cond",
    "attempts",
    "error",
)

#: Largest number of samples one case may simulate (rate × duration).
MAX_CASE_SAMPLES = 1_000_000
#: Largest grid (cases) a benchmark accepts.
MAX_CASES = 10_000_000

# Paper's arm: the core's default sensor noise (prrrp_core::SensorNoise::default), standard
# deviations of positions (m, rad) and generalised forces (N, N·m) per joint.
_PAPER_Q_NOISE = np.array([1e-5, 1e-4, 1e-4, 1e-4, 1e-5])
_PAPER_TAU_NOISE = np.array([0.5, 0.03, 0.015, 0.007, 0.05])


@dataclasses.dataclass(frozen=True)
class Case:
    """One case of the grid, everything a worker needs (picklable, small).

    ``robot_json``: the simulated robot (``SerialChain.to_json``), None for the paper's arm
    (``prrrp.Robot.paper()``, identified through its chain form). ``noise`` scales the
    default sensor noise (0: none); ``rate`` is the sampling rate (Hz); ``duration`` the
    excitation's length (s); ``excitation_evaluations`` the optimiser's budget.
    ``attempt`` counts retries (it also makes a retried submission distinct for engines
    that cache by arguments, like Dask). ``fault`` is a test hook: ``"exit"`` makes the
    worker process die (``os._exit``) on every attempt, ``"exit-once"`` on the first
    only, ``"hang"`` sleeps for an hour.
    """

    seed: int
    noise: float
    rate: float
    methods: tuple[str, ...]
    robot_json: str | None = None
    duration: float = 10.0
    excitation_evaluations: int = 300
    attempt: int = 0
    fault: str | None = None

    @property
    def key(self) -> tuple[int, float, float, int]:
        """(seed, noise, rate, excitation evaluations): what identifies the case in the
        results."""
        return (self.seed, self.noise, self.rate, self.excitation_evaluations)


def _invalid(message: str) -> Exception:
    from prrrp import InvalidInputError

    return InvalidInputError(message)


def _unique(values: Any, what: str, convert: Any) -> tuple[Any, ...]:
    if isinstance(values, int | float | np.integer | np.floating):
        values = [values]
    try:
        items = [convert(v) for v in values]
    except (TypeError, ValueError) as e:
        raise _invalid(f"{what}: {e}") from None
    if not items:
        raise _invalid(f"empty grid: no {what} given")
    return tuple(dict.fromkeys(items))


def grid(
    methods: Any = DEFAULT_METHODS,
    noise: Any = (1.0,),
    rates: Any = (50.0,),
    seeds: Any = 10,
    *,
    robot_json: str | None = None,
    duration: float = 10.0,
    excitation_evaluations: Any = 300,
) -> list[Case]:
    """The cases of a benchmark, seed-major: every seed × noise scale × rate × excitation
    budget. ``seeds`` is a count N (seeds 0..N−1) or a sequence of seeds (integers in
    [0, 2³²)). Methods may be a list or a comma-separated string.
    ``excitation_evaluations``: the excitation optimiser's budget per case (cost
    evaluations), one number or several (the report then shows its effect on the errors;
    a seed starts every budget's search from the same point, so the comparison is
    paired). Raises InvalidInputError for unknown methods (naming the valid ones), an
    empty axis, negative or non-finite noise, rates that are not positive, a budget below
    1, an absurd case size or grid size."""
    if isinstance(methods, str):
        methods = [m.strip() for m in methods.split(",") if m.strip()]
    method_list = _unique(methods, "methods", str)
    unknown = [m for m in method_list if m not in METHODS]
    if unknown:
        raise _invalid(f"unknown method {unknown[0]!r}; valid: {', '.join(METHODS)}")
    noise_list = _unique(noise, "noise scales", float)
    # Above MAX_FACTOR the noise alone is beyond any arm (×1e300 failed every case with
    # "`QR factor of W` has a NaN or infinite value"), as for `prrrp simulate --noise`.
    bad = [x for x in noise_list if not (math.isfinite(x) and 0 <= x <= MAX_FACTOR)]
    if bad:
        raise _invalid(
            f"noise scale {bad[0]:g} must be between 0 and {MAX_FACTOR:g} (1 = default noise)"
        )
    rate_list = _unique(rates, "rates", float)
    bad = [x for x in rate_list if not (math.isfinite(x) and x > 0)]
    if bad:
        raise _invalid(f"sampling rate {bad[0]} must be a positive number of Hz")
    if isinstance(seeds, int | np.integer) and not isinstance(seeds, bool):
        if seeds < 1:
            raise _invalid(f"empty grid: {seeds} seeds; give at least 1")
        if seeds > MAX_CASES:
            raise _invalid(f"{seeds} seeds is more than {MAX_CASES}")
        seed_list: tuple[int, ...] = tuple(range(int(seeds)))
    else:
        seed_list = _unique(seeds, "seeds", _seed)
    if not (math.isfinite(duration) and duration > 0):
        raise _invalid(f"duration must be a positive number of seconds, got {duration}")
    too_long = [r for r in rate_list if r * duration > MAX_CASE_SAMPLES]
    if too_long:
        raise _invalid(
            f"{too_long[0]:g} Hz × {duration:g} s is more than {MAX_CASE_SAMPLES} samples per case"
        )
    if too_long := [r for r in rate_list if r * duration < 50]:
        raise _invalid(
            f"{too_long[0]:g} Hz × {duration:g} s gives under 50 samples; "
            "raise the rate or the duration"
        )
    budgets = _unique(excitation_evaluations, "excitation evaluations", _budget)
    count = len(seed_list) * len(noise_list) * len(rate_list) * len(budgets)
    if count > MAX_CASES:
        raise _invalid(f"{count} cases is more than {MAX_CASES}")
    return [
        Case(
            seed=s,
            noise=n,
            rate=r,
            methods=method_list,
            robot_json=robot_json,
            duration=float(duration),
            excitation_evaluations=e,
        )
        for s in seed_list
        for n in noise_list
        for r in rate_list
        for e in budgets
    ]


def _budget(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeError(f"must be integers >= 1, got {value!r}")
    if value < 1:
        raise ValueError(f"must be >= 1, got {value}")
    return int(value)


def _seed(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer | str):
        raise TypeError(f"a seed must be an integer, got {value!r}")
    seed = int(value)
    if not 0 <= seed < 2**32:
        raise ValueError(f"seed {seed} must be in [0, 2^32)")
    return seed


def derived_seed(seed: int, stream: int) -> int:
    """An independent 64-bit seed for stream ``stream`` of case seed ``seed``."""
    return int(np.random.SeedSequence([seed, stream]).generate_state(1, np.uint64)[0])


# ----------------------------------------------------------------------------- one case


@functools.lru_cache(maxsize=8)
def _chain(robot_json: str | None) -> Any:
    import prrrp

    return (
        prrrp.SerialChain.paper() if robot_json is None else prrrp.SerialChain.from_json(robot_json)
    )


@functools.lru_cache(maxsize=8)
def _truth(robot_json: str | None) -> tuple[list[str], np.ndarray]:
    """Names and values of the simulated robot's base parameters (the analysis
    ``prrrp.identify`` uses by default)."""
    chain = _chain(robot_json)
    base = chain.base_parameters()
    return list(base.independent_names), np.asarray(base.base_values(chain.parameters))


def converged(model: Any) -> bool:
    """Whether the method reports that it converged (methods without a stopping rule, and
    builds whose IdentifiedModel does not say, count as converged)."""
    return bool(getattr(model, "converged", True))


def epochs(model: Any) -> int | None:
    """Epochs an iterative method ran (None for the others)."""
    value = getattr(model, "epochs", None)
    if value is None:
        value = (model.settings or {}).get("epochs")
    return None if value is None else int(value)


def parameter_errors(estimate: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """Relative errors of base parameters (%): the largest and the median over the
    parameters whose true value is not zero (a base parameter can be structurally zero,
    e.g. a lateral first moment; its relative error has no meaning), and the norm error
    100·‖β̂ − β‖/‖β‖ over all."""
    scale = float(np.max(np.abs(truth)))
    nonzero = np.abs(truth) > 1e-9 * scale
    rel = 100.0 * np.abs(estimate[nonzero] - truth[nonzero]) / np.abs(truth[nonzero])
    return {
        "max_param_error_percent": float(np.max(rel)),
        "median_param_error_percent": float(np.median(rel)),
        "param_error_norm_percent": float(
            100.0 * np.linalg.norm(estimate - truth) / np.linalg.norm(truth)
        ),
    }


def _paper_data(case: Case) -> tuple[Any, Any, Any, float]:
    """Identification data, validation data set of the paper's arm and cond(W) of the
    optimised excitation."""
    import prrrp

    robot = prrrp.Robot.paper()
    exc = prrrp.optimise_excitation(
        seed=case.seed,
        duration=case.duration,
        dt=0.02,
        max_evaluations=case.excitation_evaluations,
        restarts=2,
    )
    run = prrrp.simulate_closed_loop(
        exc,
        case.duration,
        dt=1.0 / case.rate,
        q_noise=case.noise * _PAPER_Q_NOISE,
        tau_noise=case.noise * _PAPER_TAU_NOISE,
        seed=derived_seed(case.seed, 1),
    )
    data = prrrp.Dataset.from_dict(
        prrrp.preprocess(run["t"], run["q_measured"], run["tau_measured"])
    )
    other = prrrp.optimise_excitation(
        seed=derived_seed(case.seed, 2), duration=case.duration, dt=0.02, max_evaluations=50
    )
    t = np.arange(round(case.duration * case.rate) + 1) / case.rate
    q, qd, qdd = other.eval(t)
    validation = prrrp.Dataset(t, q, qd, qdd, robot.inverse_dynamics(q, qd, qdd))
    return robot, data, validation, float(exc.cond_final)


def _chain_data(case: Case) -> tuple[Any, Any, Any, float]:
    """Identification data, validation data set of a robot from a file and cond(W_b) of
    the optimised excitation."""
    import prrrp
    from prrrp import workflow

    chain = _chain(case.robot_json)
    # The identification and the validation trajectories: designs of the same robot,
    # duration and rate from other seeds.
    excite = functools.partial(workflow.excite, chain, case.duration, rate=case.rate)
    design = excite(seed=case.seed, max_evaluations=case.excitation_evaluations, restarts=4)
    rec = prrrp.simulate_chain(
        chain,
        (design["t"], design["q"], design["qd"], design["qdd"]),
        case.duration,
        rate=case.rate,
        substeps=10,
        q_noise=case.noise * workflow.DEFAULT_Q_NOISE,
        tau_noise=case.noise * workflow.DEFAULT_TAU_NOISE,
        seed=derived_seed(case.seed, 1),
    )
    data, _ = rec.measured_dataset()
    other = excite(seed=derived_seed(case.seed, 2) % 2**32, max_evaluations=50, restarts=2)
    tau = chain.inverse_dynamics(other["q"], other["qd"], other["qdd"])
    validation = prrrp.Dataset(other["t"], other["q"], other["qd"], other["qdd"], tau)
    return chain, data, validation, float(design["cond_final"])


def _row(case: Case, method: str, **values: Any) -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(COLUMNS)
    row.update(seed=case.seed, noise=case.noise, rate=case.rate, method=method)
    row["excitation_evaluations"] = case.excitation_evaluations
    row["attempts"] = case.attempt + 1
    row.update(values)
    return row


def failed_rows(case: Case, error: str) -> list[dict[str, Any]]:
    """The rows of a case that could not run at all (worker died, timeout, ...)."""
    return [_row(case, m, status="failed", error=error) for m in case.methods]


def _describe(e: BaseException) -> str:
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0] if text else ''}".strip().rstrip(":")


def run_case(case: Case) -> list[dict[str, Any]]:
    """Runs one case; returns one row per method (see :data:`COLUMNS`). A method that
    fails (diverges, a rank-deficient record, ...) gives a row with ``status="failed"``
    and the error; a failure of the simulation fails every method's row. Per-method
    ``seconds`` is the wall time of ``prrrp.identify``."""
    if case.fault == "exit" or (case.fault == "exit-once" and case.attempt == 0):
        os._exit(3)
    if case.fault == "hang":
        time.sleep(3600)
    import prrrp

    try:
        if case.robot_json is None:
            robot, data, validation, cond = _paper_data(case)
        else:
            robot, data, validation, cond = _chain_data(case)
        names, truth = _truth(case.robot_json)
    except Exception as e:  # the case cannot run; the benchmark goes on
        return failed_rows(case, _describe(e))
    rows = []
    for method in case.methods:
        t0 = time.perf_counter()
        try:
            model = prrrp.identify(robot, data, method)
            seconds = time.perf_counter() - t0
            if list(model.base_names) != names:
                raise RuntimeError(
                    f"the model's base parameters {model.base_names} are not the truth's {names}"
                )
            beta = np.asarray(model.beta)
            if not np.all(np.isfinite(beta)):
                raise prrrp.NonFiniteError(f"{method} gave non-finite parameters")
            torque = prrrp.validate_model(model, validation)
            rows.append(
                _row(
                    case,
                    method,
                    status="ok",
                    **parameter_errors(beta, truth),
                    torque_rms_relative_percent=float(100.0 * np.mean(torque["rsd"])),
                    converged=converged(model),
                    epochs=epochs(model),
                    seconds=seconds,
                    samples=len(data),
                    excitation_cond=cond,
                )
            )
        except Exception as e:
            rows.append(
                _row(
                    case,
                    method,
                    status="failed",
                    seconds=time.perf_counter() - t0,
                    samples=len(data),
                    excitation_cond=cond,
                    error=_describe(e),
                )
            )
    return rows


def ping() -> int:
    """What the runner sends first to check that an executor runs tasks (a process id)."""
    return os.getpid()
