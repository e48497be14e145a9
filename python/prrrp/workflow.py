"""The main job for any robot, as functions: load a robot file, identify it from a log,
and report — what ``prrrp identify`` runs, for notebook users.

>>> robot = prrrp.load_robot("panda.urdf", tip="panda_link8",
...                          friction="viscous+coulomb+offset")      # doctest: +SKIP
>>> run = prrrp.identify_measurements(robot, prrrp.read_measurements("log.csv", robot))
...                                                                   # doctest: +SKIP
>>> run.model.save("model.json"); run.report("report_dir")           # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from prrrp import model_report
from prrrp._prrrp import (
    MAX_FACTOR,
    MAX_HARMONICS,
    BaseParameters,
    Dataset,
    FitCache,
    IdentifiedModel,
    InvalidInputError,
    PrrrpError,
    RankDeficientError,
    SerialChain,
    clear_stop,
    design_excitation,
    identify,
    request_stop,
    simulate_chain,
    stop_requested,
)
from prrrp.measurements import PREPROCESS_KEYS, barely_moving, measurements_to_dataset

#: Methods of :func:`identify_measurements`, in the order ``--method all`` runs them.
METHODS = ("ls", "wls", "rls", "adaline", "hopfield", "ekf", "physical")
#: The default method of :func:`identify_measurements` and ``prrrp identify``: least
#: squares with each joint's equations weighted by 1/σ_j, σ_j estimated from the residuals
#: (IDIM-WLS). Ordinary least squares adds the N²
#: of a prismatic joint to the (N·m)² of a revolute one, a sum that depends on the units;
#: weighting by each joint's noise makes the fit unit-free and is the best linear unbiased
#: estimate when the joints' noise differs, as it does on real arms (different sensors,
#: gears, friction). On the convergence protocol of issue 16 (the paper's arm, 50–1000 Hz,
#: 1× and 3× noise, 10 and 30 s, 20 seeds) its worst λ error is 1.6 % against 2.6 % for
#: ordinary least squares, as their σ_i predict (docs/protocol-table.md).
DEFAULT_METHOD = "wls"

#: Largest |q − q_ref| (rad or m) :func:`simulate` accepts anywhere in a run by default.
MAX_TRACKING_ERROR = 0.01


class TrackingError(PrrrpError, RuntimeError):
    """A simulated robot strayed from its reference further than the bound: ``error``
    (rad or m) on joint ``joint`` (0-based, named ``joint_name``) at time ``t`` (s)."""

    def __init__(
        self, error: float, joint: int, joint_name: str, t: float, bound: float, robot: str
    ) -> None:
        self.error, self.joint, self.joint_name, self.t, self.bound, self.robot = (
            error,
            joint,
            joint_name,
            t,
            bound,
            robot,
        )
        super().__init__(self.describe("the bound", "max_tracking_error"))

    def describe(self, bound_name: str, option: str) -> str:
        """The message, naming the bound as ``bound_name`` and its setting as ``option``
        (the command line names its flag)."""
        return (
            f"the simulated {self.robot} strays {self.error:.3g} rad or m from the trajectory "
            f"(joint {self.joint + 1}, {self.joint_name}, at t = {self.t:g} s), more than "
            f"{bound_name} {self.bound:g}. Check the trajectory against the robot's limits, "
            "inertials and friction; a slower trajectory (longer, or lower velocity limits) "
            f"is followed more closely, or allow more with {option}"
        )


#: Robots known by name to :func:`load_robot` and every ``--robot``: ``"paper"`` is Urrea &
#: Pascal's PRRRP arm as a chain (``SerialChain.paper()``: the dynamics of ``Robot.paper()``,
#: 9 base parameters), so that the paper's arm runs through the same commands as a file.
BUILT_IN_ROBOTS = {"paper": SerialChain.paper}


def load_robot(
    path: str | os.PathLike[str],
    *,
    base: str | None = None,
    tip: str | None = None,
    friction: str | list[str] | None = None,
    coulomb_scale: float = 0.0,
    armature: bool | None = None,
) -> SerialChain:
    """A robot from a ``.urdf`` (the chain from link ``base`` to link ``tip``) or ``.toml``
    file, with the friction terms to identify (``"viscous+coulomb+offset"``, a list of
    them, or None for the file's own), the Coulomb speed scale (rad/s; 0 = exact sign) and
    whether to identify one rotor inertia (armature) per actuator (None: as the file says;
    see ``SerialChain.with_actuators``). ``path`` may also name a built-in robot
    (:data:`BUILT_IN_ROBOTS`): ``"paper"`` is the paper's PRRRP arm."""
    name = os.fspath(path)
    if name in BUILT_IN_ROBOTS:
        if base is not None or tip is not None:
            raise InvalidInputError(
                f"--base and --tip pick the chain of a URDF; the built-in robot {name!r} is "
                "one chain already"
            )
        robot = BUILT_IN_ROBOTS[name]()
    elif not os.path.splitext(name)[1] and not os.path.exists(name):
        # "PAPER" or "puma560" read as a file without an extension.
        raise InvalidInputError(
            f"{name!r} is neither a built-in robot ({', '.join(map(repr, BUILT_IN_ROBOTS))}) "
            "nor a robot file (.urdf or .toml)"
        )
    else:
        robot = SerialChain.from_file(path, base=base, tip=tip)
    if friction is not None:
        terms = friction if isinstance(friction, str) else "+".join(friction)
        robot = robot.with_friction(terms or None, None, coulomb_smoothing=coulomb_scale)
    if armature is not None:
        robot = robot.with_actuators(armature=armature)
    return robot


@dataclasses.dataclass
class Identification:
    """The result of :func:`identify_measurements`: the model, the data set it was
    identified from, what the preprocessing did (None when q̇, q̈ were given), the
    Coulomb speed-scale search (None when not run) and the measurements as read (None
    when a ready Dataset was given), which the report scores the model against."""

    model: IdentifiedModel
    data: Dataset
    log_report: dict[str, Any] | None
    coulomb: dict[str, Any] | None
    raw: dict[str, np.ndarray] | None = None

    def report(
        self,
        directory: str | os.PathLike[str],
        validation: Any = None,
        **kwargs: Any,
    ) -> list[Path]:
        """Writes ``report.md`` and the figures into the existing folder ``directory``.
        ``validation``: measurements as read (``prrrp.read_measurements``: scored against
        the measured torque at their rows) or a Dataset (scored against its own τ)."""
        return model_report.write_report(
            self.model,
            directory,
            self.raw if self.raw is not None else self.data,
            validation=validation,
            log_report=self.log_report,
            coulomb=self.coulomb,
            **kwargs,
        )


def with_coulomb_scale(robot: SerialChain, v_s: float) -> SerialChain:
    """The robot with Coulomb speed scale ``v_s`` (rad/s; 0 = exact sign)."""
    terms = "+".join(robot.friction) or None
    return robot.with_friction(terms, robot.friction_params, coulomb_smoothing=v_s)


def identify_measurements(
    robot: SerialChain,
    raw: dict[str, np.ndarray] | Dataset,
    method: str = DEFAULT_METHOD,
    *,
    coulomb_scale: str | float = "auto",
    preprocessing: dict[str, Any] | None = None,
    drives: dict[str, Any] | None = None,
    **settings: Any,
) -> Identification:
    """Identifies ``robot`` from measurements (``prrrp.read_measurements``'s dict, or a
    ready ``Dataset``): preprocessing when q̇ and q̈ are not given (``preprocessing``:
    settings of ``prrrp.preprocess_log``, e.g. ``{"cutoff_hz": 5.0}``), the Coulomb speed
    scale (``"auto"``: chosen from the data when the robot has a Coulomb term, see
    ``SerialChain.coulomb_scale``; a number: that scale, 0 = exact sign), then
    ``prrrp.identify(robot, data, method, **settings)`` (default :data:`DEFAULT_METHOD`,
    joint-weighted least squares). The model records the
    preprocessing settings and report and the speed-scale search (and ``drives``, how
    currents or motor-side data were converted: ``prrrp.drives.record``), so ``prrrp
    predict`` can treat new logs the same way."""
    prepared = _prepare(robot, raw, coulomb_scale, preprocessing, drives)
    try:
        model = identify(
            prepared.robot, prepared.data, method, preprocessing=prepared.record, **settings
        )
    except RankDeficientError as e:
        e.args = (explain_rank(e, prepared.robot, prepared.data, settings.get("base")),)
        raise
    return prepared.result(model)


#: A joint whose position spans less than this over the data (rad or m) is named as one
#: that does not move when the data do not determine the parameters.
STILL_SPAN = 1e-3

#: A base parameter is named in an undetermined direction (a unit vector) when its
#: component there is at least this large.
DIRECTION_SHARE = 0.3


def explain_rank(
    e: RankDeficientError,
    robot: SerialChain,
    data: Dataset,
    base: BaseParameters | None = None,
) -> str:
    """``e``'s message as what a user can act on: the joints that do not move in ``data``
    and the base parameters (of ``base``, default the robot's analysis) that make up each
    direction the data do not determine, instead of its unit vectors (``e``'s own first
    line when it names neither)."""
    message = (str(e).strip() or "rank deficient").splitlines()[0]
    directions = getattr(e, "directions", None) or []
    try:
        names = list((base or robot.base_parameters()).independent_names)
    except (PrrrpError, ValueError):
        names = []
    parts = []
    still = barely_moving(robot, data.q, STILL_SPAN)
    if still:
        parts.append(f"joints that do not move in the data: {', '.join(still)}")
    named = []
    for d in directions:
        d = np.asarray(d, dtype=float)
        if len(d) != len(names):
            named = []
            break
        big = np.flatnonzero(np.abs(d) >= DIRECTION_SHARE)
        if len(big) == 1:
            named.append(names[big[0]])
        else:
            named.append(" ".join(f"{d[k]:+.2g}·{names[k]}" for k in big) or "(spread)")
    if named:
        parts.append(
            f"{len(named)} of {len(names)} base parameters are not determined: "
            + "; ".join(named[:8])
            + ("; …" if len(named) > 8 else "")
        )
    if not parts:
        return message
    return f"{'; '.join(parts)}; move every joint, or excite them with a richer trajectory"


@dataclasses.dataclass
class _Prepared:
    """What every method identifies from: the robot with its Coulomb speed scale, the data
    set, and the record the model keeps."""

    robot: SerialChain
    data: Dataset
    log_report: dict[str, Any] | None
    coulomb: dict[str, Any] | None
    record: dict[str, Any]
    raw: dict[str, np.ndarray] | None

    def result(self, model: IdentifiedModel) -> Identification:
        return Identification(model, self.data, self.log_report, self.coulomb, self.raw)


def _prepare(
    robot: SerialChain,
    raw: dict[str, np.ndarray] | Dataset,
    coulomb_scale: str | float,
    preprocessing: dict[str, Any] | None,
    drives: dict[str, Any] | None = None,
) -> _Prepared:
    """The preprocessing and Coulomb speed scale of :func:`identify_measurements`."""
    preprocessing = {k: v for k, v in (preprocessing or {}).items() if v is not None}
    unknown = sorted(set(preprocessing) - set(PREPROCESS_KEYS))
    if unknown:
        raise TypeError(f"unknown preprocessing settings {unknown}; valid: {PREPROCESS_KEYS}")
    if isinstance(raw, Dataset):
        data, log_report = raw, None
    else:
        data, log_report = measurements_to_dataset(raw, preprocessing)
    coulomb = None
    if isinstance(coulomb_scale, str):
        if coulomb_scale != "auto":
            raise InvalidInputError(
                f"coulomb_scale must be 'auto' or a number, got {coulomb_scale!r}"
            )
        if "coulomb" in robot.friction:
            coulomb = robot.coulomb_scale(_measured_torque_on(data, raw))
            robot = with_coulomb_scale(robot, coulomb["chosen"])
    else:
        v_s = float(coulomb_scale)
        if not (np.isfinite(v_s) and v_s >= 0):
            raise InvalidInputError(f"coulomb_scale must be finite and >= 0 rad/s, got {v_s}")
        robot = with_coulomb_scale(robot, v_s)
    record = {"settings": preprocessing, "report": log_report, "coulomb_scale": coulomb}
    if drives:
        record["drives"] = drives
    kept = None if isinstance(raw, Dataset) else raw
    return _Prepared(robot, data, log_report, coulomb, record, kept)


def _measured_torque_on(data: Dataset, raw: dict[str, np.ndarray] | Dataset) -> Dataset:
    """``data`` with its torque replaced by the torque as measured, at its time stamps.

    The Coulomb speed scale is chosen by cross-validation, and a cross-validation against
    the low-passed torque scores the filter, not the friction: low-passing smears the
    jump of fc·sgn(q̇) at each reversal into a ramp as wide as the filter's impulse
    response, which a smooth tanh(q̇/v_s) then fits best, with a v_s set by the cut-off
    (a simulated exact sign came out at 0.014 rad/s, and the model with it predicted the
    measured torque worse than v_s = 0). Fitted and scored against the measured torque,
    the search sees the friction law itself."""
    if isinstance(raw, Dataset) or "tau" not in raw:
        return data
    t = np.asarray(raw["t"], dtype=float)
    tau = np.asarray(raw["tau"], dtype=float)
    order = np.argsort(t, kind="stable")
    t, tau = t[order], tau[order]
    # Of repeated time stamps (a logger's duplicates) the first row counts, as in the
    # preprocessing.
    stamps, first = np.unique(t, return_index=True)
    kept = tau[first]
    grid = np.asarray(data.t, dtype=float)
    measured = np.column_stack([np.interp(grid, stamps, kept[:, j]) for j in range(kept.shape[1])])
    return Dataset(grid, data.q, data.qd, data.qdd, measured)


@dataclasses.dataclass
class MethodRun:
    """One method of :func:`identify_methods`: its result (None when it failed), the
    error's first line (None when it succeeded) and the identification's wall time, s."""

    method: str
    result: Identification | None
    error: str | None
    seconds: float


def identify_methods(
    robot: SerialChain,
    raw: dict[str, np.ndarray] | Dataset,
    methods: Sequence[str] = METHODS,
    *,
    coulomb_scale: str | float = "auto",
    preprocessing: dict[str, Any] | None = None,
    drives: dict[str, Any] | None = None,
    progress: Callable[[int, int], object] | None = None,
    per_method: dict[str, dict[str, Any]] | None = None,
    workers: int | None = None,
    **settings: Any,
) -> list[MethodRun]:
    """:func:`identify_measurements` with several methods on one preprocessing, one
    Coulomb speed-scale search and one base analysis (what ``prrrp identify --method all``
    compares), sharing the least-squares stack of the regressor between methods
    (:class:`FitCache`). A method
    that fails (a PrrrpError or ValueError: diverged, rank deficient, ...) is
    returned with its error and does not stop the others; errors of the shared
    preprocessing are raised. ``per_method``: settings of one method only (e.g.
    ``{"ekf": {"least_squares_prior_width": 2.0}}``), added to ``settings`` for it.
    ``workers``: methods run at once on threads (default: the usable CPUs, at most
    :data:`MAX_METHOD_WORKERS`; 1: one after another); each method's ``seconds`` is its
    own wall time, shared CPUs included. Results come in the order of ``methods``,
    equal whatever ``workers`` is."""
    prepared = _prepare(robot, raw, coulomb_scale, preprocessing, drives)
    if isinstance(prepared.robot, SerialChain) and settings.get("base") is None:
        # One base analysis for every method: the same base parameters to compare.
        settings["base"] = prepared.robot.base_parameters()
    # One least-squares stack of W_b per weighting for every method (the same models as
    # separate calls); dropped with this call.
    cache = FitCache()

    def run(method: str) -> MethodRun:
        t0 = time.perf_counter()
        try:
            own = {**settings, **(per_method or {}).get(method, {})}
            if own.get("base") is settings.get("base"):
                # (A method's own base analysis is other inputs: the cache would refuse it.)
                own.setdefault("cache", cache)
            model = identify(
                prepared.robot, prepared.data, method, preprocessing=prepared.record, **own
            )
        except (PrrrpError, ValueError) as e:
            if isinstance(e, RankDeficientError):
                text = explain_rank(e, prepared.robot, prepared.data, own.get("base"))
            else:
                text = (str(e).strip() or type(e).__name__).splitlines()[0]
            return MethodRun(method, None, text, time.perf_counter() - t0)
        seconds = time.perf_counter() - t0
        return MethodRun(method, prepared.result(model), None, seconds)

    if workers is None:
        workers = min(len(methods), usable_cpus(), MAX_METHOD_WORKERS)
        # Each running gradient method may hold the stored regressors (samples × joints ×
        # parameters float64; above the core's MAX_STORED_REGRESSOR_BYTES it builds them per
        # sample instead): run one at a time when two copies would not fit the memory share.
        dof = len(prepared.data.q[0])
        params = getattr(prepared.robot, "num_params", 10 * dof)
        stored = len(prepared.data.t) * dof * params * 8
        stored = stored if stored <= MAX_STORED_REGRESSOR_BYTES else 0
        available = available_memory()
        if available is not None and workers * stored > MEMORY_SHARE * available:
            workers = 1
    if progress is not None:
        progress(0, len(methods))
    if workers <= 1:
        runs = []
        for k, method in enumerate(methods):
            runs.append(run(method))
            if progress is not None:
                progress(k + 1, len(methods))
        return runs
    return _run_concurrently(run, methods, workers, progress)


#: The core's bound on the regressors a gradient method stores (1 GiB).
MAX_STORED_REGRESSOR_BYTES = 1 << 30

#: Most methods :func:`identify_methods` runs at once (each may hold its regressors,
#: up to the core's MAX_STORED_REGRESSOR_BYTES).
MAX_METHOD_WORKERS = 2


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity where the system says, else the count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def _run_concurrently(
    run: Callable[[str], MethodRun],
    methods: Sequence[str],
    workers: int,
    progress: Callable[[int, int], object] | None,
) -> list[MethodRun]:
    """``run`` of every method on ``workers`` threads (each call computes with the GIL
    released), in the order of ``methods``. A Ctrl-C reaches only the main thread, which
    waits here: it asks every prrrp computation of the process to stop
    (``request_stop``), waits for the threads (each ends at its next check) and
    re-raises, so the run stops as fast as a single method would and leaves no thread."""
    import concurrent.futures  # only here: `prrrp --help` imports nothing heavy

    out: list[MethodRun | None] = [None] * len(methods)
    pool = concurrent.futures.ThreadPoolExecutor(workers, thread_name_prefix="prrrp-method")
    futures = {pool.submit(run, m): k for k, m in enumerate(methods)}
    try:
        for done, f in enumerate(concurrent.futures.as_completed(futures), start=1):
            out[futures[f]] = f.result()
            if progress is not None:
                progress(done, len(methods))
    except BaseException:
        # A host's own request_stop() stays raised: lowering it let its next call run.
        raised_before = stop_requested()
        request_stop()
        try:
            for f in futures:
                f.cancel()
            pool.shutdown(wait=True)
        finally:
            if not raised_before:
                clear_stop()
        raise
    pool.shutdown(wait=True)
    return [r for r in out if r is not None]


#: Most samples :func:`excite` makes (the core's MAX_SAMPLES).
MAX_SAMPLES = 10_000_000
#: Share of the available memory a result's arrays may take (the caller's own copies,
#: e.g. a table for a CSV file, need about as much again).
MEMORY_SHARE = 0.4


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux ``MemAvailable``; elsewhere
    the free physical pages), or None when the system does not say."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(samples: int, joints: int, columns: int, lower: str) -> None:
    """Raises InvalidInputError, before anything is allocated, when ``samples`` rows of
    ``columns`` float64 values would take more than :data:`MEMORY_SHARE` of the available
    memory; the message says how much and what to lower (``lower``)."""
    need = samples * columns * 8
    available = available_memory()
    if available is None or need <= MEMORY_SHARE * available:
        return
    raise InvalidInputError(
        f"{samples:.3g} samples × {joints} joints need about {need / 2**30:.3g} GiB for the "
        f"trajectory's arrays (t, q, q̇, q̈), more than {MEMORY_SHARE:.0%} of the "
        f"{available / 2**30:.3g} GiB of memory available: lower the {lower}"
    )


#: Default sensor noise of :func:`simulate` (standard deviations, scaled by ``noise``):
#: positions 1e-4 rad or m (an encoder of ~16 bits per turn), joint torques 0.05 N·m or N
#: (a strain-gauge joint torque sensor).
DEFAULT_Q_NOISE = 1e-4
DEFAULT_TAU_NOISE = 0.05


def excite(
    robot: SerialChain,
    duration: float = 10.0,
    *,
    harmonics: int = 5,
    base_frequency: float | None = None,
    rate: float = 100.0,
    seed: int = 0,
    limits: dict[str, Any] | None = None,
    progress: Callable[[int, int], object] | None = None,
    **design: Any,
) -> dict[str, Any]:
    """An exciting trajectory of ``robot`` (see ``prrrp.design_excitation``) sampled at
    ``rate`` Hz over ``duration`` s, which must be a whole number of periods of
    ``base_frequency`` (default 1/duration: one period) so that it ends at rest. Returns
    the design's dict plus ``t``, ``q``, ``qd``, ``qdd`` (SI units). Sizes are checked
    before the design starts: more than :data:`MAX_SAMPLES` samples, or arrays that would
    not fit in the available memory (:func:`check_memory`), are an InvalidInputError
    saying what to lower."""
    if not (math.isfinite(duration) and duration > 0):
        raise InvalidInputError(f"duration must be a positive number of seconds, got {duration}")
    if not (math.isfinite(rate) and rate > 0):
        raise InvalidInputError(f"rate must be a positive number of Hz, got {rate}")
    f0 = 1.0 / duration if base_frequency is None else float(base_frequency)
    periods = duration * f0
    whole = math.isfinite(periods) and abs(periods - round(periods)) < 1e-6
    if not (whole and periods >= 1 - 1e-9):
        raise InvalidInputError(
            f"duration {duration} s is not a whole number of periods of {f0} Hz "
            "(the trajectory would not end at rest)"
        )
    # Below twice the highest harmonic the samples alias it (at 1e-300 Hz the trajectory
    # was one sample over 10 s, written without a word).
    if harmonics <= MAX_HARMONICS and rate <= 2.0 * harmonics * f0:
        raise InvalidInputError(
            f"rate {rate:g} Hz is not above twice the highest harmonic, {harmonics} × "
            f"{f0:g} Hz: the samples would not follow the trajectory; raise the rate"
        )
    if duration * rate > MAX_SAMPLES:
        raise InvalidInputError(
            f"rate {rate:g} Hz × duration {duration:g} s = {duration * rate:.3g} samples; at "
            f"most {MAX_SAMPLES:.0e} (MAX_SAMPLES): lower the rate or the duration"
        )
    samples = round(duration * rate) + 1
    check_memory(samples, robot.dof, 1 + 3 * robot.dof, "rate or duration")
    out = design_excitation(
        robot,
        harmonics=harmonics,
        base_frequency=f0,
        seed=seed,
        limits=limits,
        progress=progress,
        **design,
    )
    t = np.arange(samples) / rate
    out["t"] = t
    out["q"], out["qd"], out["qdd"] = out["trajectory"].eval(t)
    out["duration"] = duration
    return out


def simulate(
    robot: SerialChain,
    trajectory: dict[str, np.ndarray],
    *,
    noise: float = 1.0,
    seed: int = 0,
    substeps: int = 10,
    max_tracking_error: float | None = MAX_TRACKING_ERROR,
) -> dict[str, np.ndarray]:
    """``robot`` (its file's inertials and friction) tracking ``trajectory`` (``t``, ``q``,
    ``qd``, ``qdd`` at a uniform rate) in closed loop, with sensor noise ``noise`` times
    :data:`DEFAULT_Q_NOISE` / :data:`DEFAULT_TAU_NOISE` (0: none). Returns the measurements
    ``t``, ``q``, ``tau``, the truth ``q_true``, ``qd_true``, ``qdd_true``, ``tau_true`` and
    ``tracking_error`` (each joint's largest |q_true − q_ref|, rad or m).

    The simulated controller is computed torque with the robot's own model, friction
    compensated from the reference velocity. A run that strays further than
    ``max_tracking_error`` (rad or m; None: no bound) from its reference raises
    :class:`TrackingError`: its data would not be the trajectory that was asked for."""
    # Above MAX_FACTOR the noise alone is beyond any arm, and the log is one prrrp's
    # readers refuse (values of 1e100 or more).
    if not (math.isfinite(noise) and 0 <= noise <= MAX_FACTOR):
        raise InvalidInputError(
            f"noise must be a factor between 0 and {MAX_FACTOR:g}, got {noise:g}"
        )
    if max_tracking_error is not None and not (
        math.isfinite(max_tracking_error) and max_tracking_error > 0
    ):
        raise InvalidInputError(
            f"max_tracking_error must be a positive number or None, got {max_tracking_error}"
        )
    missing = [k for k in ("t", "q", "qd", "qdd") if k not in trajectory]
    if missing:
        # A plain KeyError named neither the argument nor what it should hold.
        raise InvalidInputError(
            f"the trajectory has no {', '.join(missing)}: give a dict of t, q, qd and qdd "
            "(as prrrp.excite returns)"
        )
    t = np.asarray(trajectory["t"], dtype=float)
    if t.ndim != 1 or len(t) < 2:
        raise InvalidInputError("the trajectory needs at least two time stamps")
    dt = np.diff(t)
    # Round-off of the stamps themselves counts as uniform: epoch-sized stamps (t + 1e9 s)
    # carry 1e-7 s of it, above 1e-6 of a 10 ms step.
    spread = 1e-6 * dt.mean() + 8 * np.finfo(float).eps * np.abs(t).max()
    if not (np.all(dt > 0) and np.ptp(dt) <= spread):
        raise InvalidInputError(
            f"the trajectory's time stamps must be uniformly spaced (steps from "
            f"{dt.min():.6g} to {dt.max():.6g} s)"
        )
    rate = 1.0 / dt.mean()
    ref = (t - t[0], trajectory["q"], trajectory["qd"], trajectory["qdd"])
    rec = simulate_chain(
        robot,
        ref,
        float(t[-1] - t[0]),
        rate=rate,
        substeps=substeps,
        q_noise=noise * DEFAULT_Q_NOISE,
        tau_noise=noise * DEFAULT_TAU_NOISE,
        seed=seed,
    )
    q_true = np.asarray(rec.q)
    errors = np.abs(q_true - np.asarray(trajectory["q"], dtype=float)[: len(q_true)])
    if max_tracking_error is not None and not errors.max() <= max_tracking_error:
        k, j = np.unravel_index(np.argmax(errors), errors.shape)
        raise TrackingError(
            float(errors[k, j]),
            int(j),
            robot.joint_names[j],
            float(rec.t[k] + t[0]),
            max_tracking_error,
            robot.name,
        )
    return {
        "t": np.asarray(rec.t) + t[0],
        "q": np.asarray(rec.q_measured),
        "tau": np.asarray(rec.tau_measured),
        "q_true": q_true,
        "qd_true": np.asarray(rec.qd),
        "qdd_true": np.asarray(rec.qdd),
        "tau_true": np.asarray(rec.tau),
        "tracking_error": errors.max(axis=0),
    }
