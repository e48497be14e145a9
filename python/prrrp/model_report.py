"""The report of an identified model of any robot: ``report.md`` and PNG figures (torque
prediction per joint, residual histograms, friction curves), written by
``prrrp identify --robot ... --out DIR`` and :func:`write_report`.

Every torque error is against the torque **as measured**, at the rows it was measured
(:mod:`prrrp.prediction`): the model is evaluated on the processed signals and its
prediction mapped back to the log's time stamps; the low-passed torque that identification
fits is shown beside it, labelled, never in its place. Rows in the filter's edge transient
and repeated time stamps are counted and left out of the errors.

The friction curve of joint j plots the friction torque the model identified,
fv·q̇ + fc·tanh(q̇/v_s) + fo (the exact sign when v_s = 0), over the data's
*residual-corrected* points τ_j − τ̂_rigid,j: the measured torque minus the model's
rigid-body part, i.e. the friction the data shows. A model that fits puts the curve
through the cloud. With coupled actuators (``SerialChain.actuators``) the curves are per
actuator over its velocity (C·q̇)ₘ, the points C⁻ᵀ·(τ − τ̂_rigid).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from prrrp import canvas, drawing, measurements
from prrrp._prrrp import Dataset, IdentifiedModel, InvalidInputError
from prrrp.prediction import LogGrid, _at_rows, prepare, recorded_settings

FRICTION_TERMS = ("fv", "fc", "fo")


def _grid(n: int) -> tuple[int, int]:
    cols = min(n, 3)
    return (n + cols - 1) // cols, cols


def friction_split(model: IdentifiedModel) -> tuple[np.ndarray, np.ndarray]:
    """(friction (n, 3) [fv, fc, fo] per joint read from β̂, mask (b,) of the friction
    base parameters). A friction term that the base analysis merged with other
    parameters (e.g. an offset with gravity on a horizontal joint) is left at 0 and not
    masked: it stays in the rigid-body part."""
    names = list(model.base_names)
    combos = list(model.combinations)
    n = model.robot.dof
    friction = np.zeros((n, 3))
    mask = np.zeros(len(names), dtype=bool)
    for i, (name, combo) in enumerate(zip(names, combos, strict=True)):
        for k, term in enumerate(FRICTION_TERMS):
            if name.startswith(term) and name[len(term) :].isdigit() and combo == name:
                friction[int(name[len(term) :]) - 1, k] = model.beta[i]
                mask[i] = True
    return friction, mask


def friction_torque(friction: np.ndarray, qd: np.ndarray, v_s: float) -> np.ndarray:
    """fv·q̇ + fc·s(q̇) + fo per joint, s = tanh(q̇/v_s) (sign when v_s = 0); qd (S, n)."""
    s = np.tanh(qd / v_s) if v_s > 0 else np.sign(qd)
    return friction[:, 0] * qd + friction[:, 1] * s + friction[:, 2]


def _rms(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(np.asarray(x) ** 2, axis=0))


#: What the report and the command line accept as data: the measurements as read
#: (``prrrp.read_measurements``'s dict: scored at their rows), a prepared
#: :class:`~prrrp.prediction.LogGrid`, or a ready ``Dataset`` (scored against its own τ).
DataLike = Mapping[str, np.ndarray] | LogGrid | Dataset


def as_grid(data: DataLike, model: IdentifiedModel) -> LogGrid:
    """``data`` prepared for predictions at its rows with ``model``'s recorded
    preprocessing settings."""
    if isinstance(data, LogGrid):
        return data
    if isinstance(data, Dataset):
        return prepare(data)
    return prepare(data, recorded_settings(model))


def prediction_table(model: IdentifiedModel, data: DataLike) -> dict[str, Any]:
    """Per joint over the scored rows of ``data``: RMS of the prediction error against the
    measured torque (N·m, N), RMS of the measured torque, and the error as % of it; with
    the figures against the low-passed torque beside them and the rows scored
    (:meth:`prrrp.prediction.LogGrid.errors`)."""
    grid = as_grid(data, model)
    return grid.errors(grid.predict(model))


#: A link whose identified mass is outside [1/MASS_FACTOR, MASS_FACTOR] times its robot
#: file's is flagged: CAD masses of arm links are within tens of percent of the built
#: links (cables, motors and covers moved between links make up to ≈ 2×); beyond 3× the
#: identified body is not that link but a direction the data do not constrain, or an
#: unmodelled load (a tool, a payload).
MASS_FACTOR = 3.0
#: A link whose rotational inertia about its centre of mass (the trace of I_c) is outside
#: [1/INERTIA_FACTOR, INERTIA_FACTOR] times the file's is flagged: I ~ m·r², so this is the
#: mass bound compounded with a √3 change of size.
INERTIA_FACTOR = 9.0


def prior_comparison(model: IdentifiedModel) -> list[dict[str, Any]] | None:
    """Each link of a physically consistent model (method "physical") against its prior
    (the robot file's inertials unless the identification was given another ``prior``):
    identified and prior mass (kg) and their ratio, the shift of the centre of mass (m),
    the prior's radius of gyration about its centre of mass r_g = √(tr I_c / 2m) (m, the
    RMS distance of its mass from the centre of mass), the ratio of tr I_c, and ``flags``
    naming what departs far: ``mass`` (ratio outside 1/3..3, :data:`MASS_FACTOR`), ``com``
    (a shift larger than r_g: the centre of mass left the bulk of the prior body),
    ``inertia`` (ratio outside 1/9..9, :data:`INERTIA_FACTOR`). None for models without
    standard parameters."""
    est = model.standard_parameters
    if est is None:
        return None
    prior_setting = (model.settings or {}).get("prior")
    if isinstance(prior_setting, list):
        prior = np.asarray(prior_setting, dtype=float)
    else:
        prior = np.asarray(model.robot.parameters, dtype=float)
    robot = model.robot
    now = robot.feasibility(np.asarray(est))["links"]
    before = robot.feasibility(prior)["links"]
    rows = []
    for a, b in zip(now, before, strict=True):
        m, m0 = float(a["mass"]), float(b["mass"])
        ratio = m / m0 if m0 > 0 else float("nan")
        shift = r_g = inertia_ratio = float("nan")
        if a["com"] is not None and b["com"] is not None:
            shift = float(np.linalg.norm(np.subtract(a["com"], b["com"])))
        if b["principal_moments"] is not None and m0 > 0:
            tr0 = float(np.sum(b["principal_moments"]))
            r_g = float(np.sqrt(max(tr0, 0.0) / (2 * m0)))
            if a["principal_moments"] is not None and tr0 > 0:
                inertia_ratio = float(np.sum(a["principal_moments"])) / tr0
        flags = []
        if not (1 / MASS_FACTOR <= ratio <= MASS_FACTOR):
            flags.append("mass")
        if shift > r_g:
            flags.append("com")
        if not (1 / INERTIA_FACTOR <= inertia_ratio <= INERTIA_FACTOR):
            flags.append("inertia")
        rows.append(
            {
                "link": a["link"],
                "mass": m,
                "prior_mass": m0,
                "mass_ratio": ratio,
                "com_shift": shift,
                "prior_radius_of_gyration": r_g,
                "inertia_ratio": inertia_ratio,
                "flags": flags,
            }
        )
    return rows


def _prior_section(model: IdentifiedModel) -> list[str]:
    """The report's "Links against the prior" section (empty without standard parameters)."""
    rows = prior_comparison(model)
    if rows is None:
        return []
    lines = [
        "## Links against the prior",
        "",
        "Each identified link beside the robot file's (the prior the fit is held to where "
        "the data do not decide; see the settings' divergence_weight). Flagged: a mass "
        f"outside 1/{MASS_FACTOR:g}..{MASS_FACTOR:g}× the file's (CAD masses are within tens "
        "of percent of the built link; beyond 3× it is not that link but a direction the "
        "data do not constrain, or an unmodelled load), a centre of mass moved further than "
        "the prior body's radius of gyration r_g (out of the bulk of its mass), a rotational "
        f"inertia about it outside 1/{INERTIA_FACTOR:g}..{INERTIA_FACTOR:g}× (the mass bound "
        "with a √3 change of size).",
        "",
    ]
    lines += _table(
        [
            "link",
            "mass (kg)",
            "prior (kg)",
            "ratio",
            "COM shift (m)",
            "prior r_g (m)",
            "tr I_c ratio",
            "flag",
        ],
        [
            [
                r["link"],
                _g(r["mass"]),
                _g(r["prior_mass"]),
                _g(r["mass_ratio"], 3),
                _g(r["com_shift"], 3),
                _g(r["prior_radius_of_gyration"], 3),
                _g(r["inertia_ratio"], 3),
                ", ".join(r["flags"]).upper() or "–",
            ]
            for r in rows
        ],
    )
    flagged = [r["link"] for r in rows if r["flags"]]
    lines.append("")
    if flagged:
        lines.append(
            f"**Far from the prior: {', '.join(flagged)}.** Check the data excite these links "
            "(prrrp excite), the robot file (a tool or payload missing from it), or raise "
            "divergence_weight to hold them nearer the file."
        )
    else:
        lines.append("Every link is within these bounds of its prior.")
    lines.append("")
    return lines


def _units(model: IdentifiedModel) -> tuple[list[str], list[str]]:
    """Per joint: the unit of its generalised force (N·m, N) and of its velocity."""
    prismatic = [t == "P" for t in model.robot.joint_types]
    return (["N" if p else "N·m" for p in prismatic], ["m/s" if p else "rad/s" for p in prismatic])


#: (file name, caption template) of the report's figures, in the order they are drawn;
#: ``{which}`` is the data they show ("identification" or "validation").
FIGURE_CAPTIONS: dict[str, str] = {
    "torque.png": "Measured and predicted joint torques on the {which} data (grey spans: the "
    "filter's edge transient, not scored)",
    "residual.png": "Histogram of the torque residual, measured − predicted, per joint "
    "({which} data, scored rows)",
    "friction.png": "Friction torque vs speed per joint: the identified model over the "
    "measured torque minus the model's rigid-body part",
}


def figure_list(model: IdentifiedModel, validation: bool = False) -> list[tuple[str, str]]:
    """The (file name, caption) pairs :func:`write_figures` writes for ``model``, known
    before any is drawn (the report links them)."""
    which = "validation" if validation else "identification"
    names = ["torque.png", "residual.png"]
    if friction_split(model)[1].any():
        names.append("friction.png")
    return [(name, FIGURE_CAPTIONS[name].format(which=which)) for name in names]


def write_figures(
    model: IdentifiedModel,
    data: DataLike,
    directory: Path,
    validation: DataLike | None = None,
) -> list[tuple[str, str]]:
    """Writes the figures of :func:`figure_list`; returns their (file name, caption)
    pairs."""
    for draw in figure_drawings(model, data, directory, validation):
        draw()
    return figure_list(model, validation is not None)


def figure_drawings(
    model: IdentifiedModel,
    data: DataLike,
    directory: Path,
    validation: DataLike | None = None,
) -> list[Callable[[], None]]:
    """The figures of :func:`figure_list` as calls that each draw one into ``directory``,
    in its order. What they plot (predictions, residuals) is computed here, at once: a
    call only draws, so that the calls can run in any order or in other processes
    (:func:`prrrp.drawing.draw_all`). Each call is a ``functools.partial`` of a function of
    this module over arrays and strings, named by ``__name__``: it pickles, so that a
    process started before the results existed can draw it."""
    joints = list(model.robot.joint_names)
    force_units, speed_units = _units(model)
    n = len(joints)
    fit = as_grid(data, model)
    check = as_grid(validation, model) if validation is not None else fit
    pred = check.predict(model)
    cutoff = (check.report or {}).get("cutoff_hz")
    directory = Path(directory)
    k = check.scored
    drawings = [
        drawing.job(
            "torque",
            _torque_figure,
            directory / "torque.png",
            joints,
            force_units,
            check.t,
            check.measured,
            check.filtered,
            pred,
            _edge_spans(check),
            cutoff,
        ),
        drawing.job(
            "residual",
            _residual_figure,
            directory / "residual.png",
            joints,
            force_units,
            check.measured[k] - pred[k],
        ),
    ]
    friction, mask = friction_split(model)
    if mask.any():
        v_s = float(model.robot.coulomb_smoothing)
        qd, points = friction_points(model, fit)
        coupling = model.robot.actuators["coupling"]
        titles = joints if coupling is None else [f"actuator {m + 1}" for m in range(n)]
        drawings.append(
            drawing.job(
                "friction_curves",
                _friction_figure,
                directory / "friction.png",
                titles,
                force_units,
                speed_units,
                qd,
                points,
                friction,
                v_s,
                coupling is not None,
            )
        )
    return drawings


def friction_points(model: IdentifiedModel, grid: LogGrid) -> tuple[np.ndarray, np.ndarray]:
    """The friction figure's points on the scored rows of ``grid``: (velocity, friction the
    data show) per joint, (k, n) each — q̇ and τ − τ̂_rigid, τ̂_rigid the model's torque
    without its friction base parameters (:func:`friction_split`); per actuator with a
    coupling C: C·q̇ and C⁻ᵀ·(τ − τ̂_rigid). τ̂_rigid is the model's prediction minus
    those terms' torque Cᵀ·f(C·q̇), on the processed signals like the prediction: the
    same numbers as predicting with them zeroed, without a second model and
    prediction."""
    friction, _ = friction_split(model)
    v_s = float(model.robot.coulomb_smoothing)
    p = grid.processed
    t, qd = np.asarray(p.t), np.asarray(p.qd)
    coupling = model.robot.actuators["coupling"]
    c = None if coupling is None else np.asarray(coupling, dtype=float)
    speed = qd if c is None else qd @ c.T
    f = friction_torque(friction, speed, v_s)
    if c is not None:
        f = f @ c  # Cᵀ·f per sample
    k = grid.scored
    points = grid.measured[k] - grid.predict(model)[k] + _at_rows(t, f, grid.t)[k]
    speed = _at_rows(t, qd, grid.t)[k]
    if c is not None:
        speed = speed @ c.T
        points = np.linalg.solve(c.T, points.T).T
    return speed, points


def _edge_spans(grid: LogGrid) -> list[tuple[float, float]]:
    """The time spans (s) of the rows in the filter's edge transient (not scored)."""
    t = grid.t
    inside = t[~grid.edge]
    if not grid.edge.any() or len(inside) == 0:
        return []
    spans = []
    if t[0] < inside[0]:
        spans.append((float(t[0]), float(inside[0])))
    if t[-1] > inside[-1]:
        spans.append((float(inside[-1]), float(t[-1])))
    return spans


def _torque_figure(
    path: Path,
    joints: list[str],
    force_units: list[str],
    t: np.ndarray,
    measured: np.ndarray,
    filtered: np.ndarray | None,
    pred: np.ndarray,
    edges: list[tuple[float, float]],
    cutoff: float | None,
) -> None:
    """Measured, low-passed (fitted) and predicted torque per joint over time."""
    n = len(joints)
    rows, cols = _grid(n)
    fig, axes = canvas.figure(rows, cols, top=0.7)
    for j in range(n):
        ax = axes[j // cols][j % cols]
        for a, b in edges:
            ax.axvspan(a, b, color="0.85")
        ax.lines(t, measured[:, j], lw=0.6, color="0.55", label="measured")
        if filtered is not None:
            ax.lines(
                t,
                filtered[:, j],
                lw=0.8,
                color="tab:blue",
                label=f"measured, low-passed at {cutoff:.3g} Hz (fitted)",
            )
        ax.lines(t, pred[:, j], lw=0.8, ls="--", color="tab:red", label="predicted")
        ax.set_title(joints[j], fontsize=9)
        ax.set_xlabel("time (s)", fontsize=8)
        ax.set_ylabel(f"torque ({force_units[j]})", fontsize=8)
    _blank(axes, n, cols)
    # Above the panels, never over the data.
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, ncol=3, fontsize=8)
    drawing.save(fig, path)


def _residual_figure(
    path: Path, joints: list[str], force_units: list[str], resid: np.ndarray
) -> None:
    """Histogram of the torque residual per joint."""
    n = len(joints)
    rows, cols = _grid(n)
    fig, axes = canvas.figure(rows, cols)
    for j in range(n):
        ax = axes[j // cols][j % cols]
        _histogram(ax, resid[:, j], force_units[j], joints[j])
    _blank(axes, n, cols)
    drawing.save(fig, path)


def _friction_figure(
    path: Path,
    titles: list[str],
    force_units: list[str],
    speed_units: list[str],
    qd: np.ndarray,
    points: np.ndarray,
    friction: np.ndarray,
    v_s: float,
    coupled: bool,
) -> None:
    """The identified friction curve over the residual-corrected points, per joint (per
    actuator when ``coupled``)."""
    n = len(titles)
    rows, cols = _grid(n)
    fig, axes = canvas.figure(rows, cols, panel=(3.6, 2.1))
    for j in range(n):
        ax = axes[j // cols][j % cols]
        keep = drawing.thin_points(qd[:, j], points[:, j], ax.pixels())
        ax.points(qd[keep, j], points[keep, j], ms=1.5, color="tab:blue", alpha=0.4, label="data")
        span = max(float(np.abs(qd[:, j]).max()), 1e-6)
        grid = np.linspace(-span, span, 401)
        curve = friction_torque(friction[j : j + 1], grid[:, None], v_s)[:, 0]
        ax.plot(grid, curve, color="r", lw=1.2, label="model")
        ax.set_title(titles[j], fontsize=9)
        if not coupled:
            ax.set_xlabel(f"joint velocity q̇ ({speed_units[j]})", fontsize=8)
            ax.set_ylabel(f"friction torque ({force_units[j]})", fontsize=8)
        else:
            ax.set_xlabel("actuator velocity (C·q̇)ₘ (rad/s or m/s)", fontsize=8)
            ax.set_ylabel("friction torque (N·m or N)", fontsize=8)
    _blank(axes, n, cols)
    axes[0][0].legend(fontsize=7, markerscale=4)
    drawing.save(fig, path)


def _blank(axes: Any, n: int, cols: int) -> None:
    """Hides the panels after the n-th."""
    for j in range(n, axes.size):
        axes[j // cols][j % cols].axis("off")


#: Bins of the residual histograms.
HIST_BINS = 50
#: The residual histograms span this central share of the rows (widened by a tenth): a few
#: rows far out (a torque spike, the filter's settling) would otherwise squeeze the bulk
#: into one bin. The rows outside are counted in the panel's title.
HIST_SHARE = 0.99


def _histogram(ax: Any, r: np.ndarray, unit: str, joint: str) -> None:
    """One joint's residual histogram: counts per bin over the central rows."""
    r = r[np.isfinite(r)]
    title = f"{joint}: RMS {_g(_rms(r), 3)} {unit}"
    if len(r) == 0:
        ax.set_title(title, fontsize=9)
        return
    tail = (1 - HIST_SHARE) / 2
    lo, hi = np.quantile(r, [tail, 1 - tail])
    pad = 0.1 * (hi - lo) if hi > lo else max(abs(hi), 1e-12)
    lo, hi = lo - pad, hi + pad
    counts, edges = np.histogram(r, bins=HIST_BINS, range=(lo, hi))
    ax.stairs(counts, edges, color="tab:blue")
    outside = len(r) - int(counts.sum())
    if outside:
        title += f" ({outside} rows off scale)"
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(f"measured − predicted torque ({unit})", fontsize=8)
    ax.set_ylabel("rows per bin", fontsize=8)


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return lines


def _g(x: Any, digits: int = 4) -> str:
    if x is None:
        return "–"
    if isinstance(x, str | bool) or not isinstance(x, int | float | np.number):
        return str(x)  # a hand-edited record: shown, not computed with
    x = float(x)
    return "–" if not np.isfinite(x) else f"{x:.{digits}g}"


#: Significant digits of a measured quantity in a report record (e.g. the log's median
#: rate, a largest gap): a clock's jitter is far above 1e-6 of its rate.
RECORD_DIGITS = 6


def _record_value(v: Any) -> str:
    """A preprocessing record's value for the report: floats to :data:`RECORD_DIGITS`
    significant digits (500.0000000000551 Hz → 500), the rest as they are."""
    if isinstance(v, float):
        return _g(v, RECORD_DIGITS)
    return str(v)


def _with_sigma(x: Any, sigma: Any, digits: int = 6) -> str:
    """``x`` to the decimal place of the second significant digit of its standard
    deviation ``sigma`` (the digits σ supports; at least one significant digit of x);
    ``digits`` significant digits when there is no finite σ > 0."""
    if x is None or isinstance(x, str | bool) or not isinstance(x, int | float | np.number):
        return _g(x)
    x = float(x)
    if not np.isfinite(x):
        return "–"
    if sigma is None or not np.isfinite(sigma) or not sigma > 0:
        return _g(x, digits)
    # Decimal place of σ's second significant digit; kept when x is smaller than σ.
    place = int(np.floor(np.log10(float(sigma)))) - 1
    if x != 0 and int(np.floor(np.log10(abs(x)))) < place:
        return _g(x, 1)
    decimals = max(-place, 0)
    return f"{round(x, -place):.{decimals}f}"


def _error_rows(joints: Sequence[str], p: dict[str, Any]) -> list[list[str]]:
    rows = []
    for i, j in enumerate(joints):
        row = [j, _g(p["rms"][i]), _g(p["noise_rms"][i], 2), _g(p["tau_rms"][i])]
        row.append(_g(p["percent"][i], 3))
        if p["filtered_percent"] is not None:
            row.append(_g(p["filtered_percent"][i], 3))
        rows.append(row)
    return rows


def prediction_section(model: IdentifiedModel, tables: Sequence[tuple[str, LogGrid]]) -> list[str]:
    """The "Torque prediction" tables (markdown lines) of ``model`` on each labelled grid."""
    joints = list(model.robot.joint_names)
    lines = [
        "## Torque prediction",
        "",
        "Errors against the torque as measured, at the rows it was measured (the model "
        "evaluated on the processed signals, mapped back to the log's time stamps). The last "
        "column, for reference only, scores against the low-passed torque the "
        "identification fitted: it moves with the cut-off and flatters every model. The "
        "torque noise is estimated from the measured torque's third differences: an error "
        "close to it is as small as this log can show, and a joint whose torque RMS is close "
        "to it moved too little against its noise for its error % to say much.",
        "",
    ]
    for label, grid in tables:
        p = grid.errors(grid.predict(model))
        lines.append(f"On the {label}: {grid.describe()}.")
        lines.append("")
        header = ["joint", "error RMS (N·m, N)", "torque noise RMS", "measured torque RMS"]
        header.append("error % of measured")
        if p["filtered_percent"] is not None:
            cutoff = (grid.report or {}).get("cutoff_hz")
            header.append(f"error % vs low-passed at {_g(cutoff, 3)} Hz (reference only)")
        lines += _table(header, _error_rows(joints, p))
        lines.append("")
    return lines


def comparison_section(
    runs: Sequence[dict[str, Any]],
    joints: Sequence[str],
    main: str,
    figure: str | None,
    default: str = "wls",
) -> list[str]:
    """The "Methods compared" section of ``--method all``: one row per method (its
    ``method``, ``status``, ``error``, ``converged``, ``epochs``, ``seconds``,
    ``identification`` and ``validation`` error tables, None where not run); ``main`` is
    the method of model.json, ``default`` the default method."""
    held_out = any(r.get("validation") is not None for r in runs)
    which = (
        "the default method"
        if main == default
        else f"the default, {default}, failed: the first method that succeeded"
    )
    lines = [
        "## Methods compared",
        "",
        f"`model.json` is the {main} model ({which}); every method's model is in "
        "`model-<method>.json`. Torque error per joint, % of "
        "the measured torque's RMS"
        + (", on the held-out validation data" if held_out else ", on the identification data")
        + "; time is the identification's wall time (preprocessing and the Coulomb "
        "speed-scale search are shared and not counted).",
        "",
    ]
    header = ["method", "status", "converged", "epochs", "time (s)"]
    header += [f"{j} (held out)" for j in joints] if held_out else []
    header += [f"{j} (identification)" for j in joints]
    rows = []
    for r in runs:
        if r["status"] != "ok":
            blank = ["–"] * (len(header) - 5)
            rows.append([r["method"], f"failed: {r['error']}", "–", "–", _g(r["seconds"], 3)])
            rows[-1] += blank
            continue
        row = [
            r["method"],
            "ok",
            "yes" if r["converged"] else "**NO**",
            "–" if r["epochs"] is None else str(r["epochs"]),
            _g(r["seconds"], 3),
        ]
        if held_out:
            row += [_g(x, 3) for x in r["validation"]["percent"]]
        row += [_g(x, 3) for x in r["identification"]["percent"]]
        rows.append(row)
    lines += _table(header, rows)
    lines.append("")
    if figure:
        lines += [f"![torque error per joint and method]({figure})", ""]
    return lines


def comparison_figure(runs: Sequence[dict[str, Any]], joints: Sequence[str], path: Path) -> None:
    """Bars of the torque error per joint (% of the measured torque's RMS), one bar per
    method that succeeded, on the held-out data when there is some."""
    ok = [r for r in runs if r["status"] == "ok"]
    held_out = any(r.get("validation") is not None for r in ok)
    key = "validation" if held_out else "identification"
    width_in = 0.9 + 0.3 * len(joints) * max(len(ok), 1)
    # Legend on the right, outside the bars; room below for the slanted joint names.
    fig, axes = canvas.figure(1, 1, panel=(width_in, 2.6), bottom=1.1, right=2.0, top=0.4)
    ax = axes[0][0]
    width = 0.8 / max(len(ok), 1)
    x = np.arange(len(joints))
    for k, r in enumerate(ok):
        values = np.asarray(r[key]["percent"], dtype=float)
        label = r["method"] + ("" if r["converged"] else " (not converged)")
        ax.bar(x + (k - (len(ok) - 1) / 2) * width, values, width, label=label)
    ax.set_xticks(x, list(joints), rotation=30, fontsize=8)
    ax.set_xlabel("joint", fontsize=8)
    ax.set_ylabel("torque error (% of measured RMS)", fontsize=8)
    ax.set_title("held-out validation data" if held_out else "identification data", fontsize=9)
    ax.grid_y = True
    ax.legend(fontsize=7, outside=True, frameon=False)
    drawing.save(fig, path)


def _coulomb_summary(coulomb: dict[str, Any]) -> list[str]:
    """What the Coulomb speed-scale search decided (``SerialChain.coulomb_scale``'s dict),
    in a few lines for the report: the choice, whether the data identify it, the range."""
    v_s = _g(coulomb["chosen"])
    searched = ""
    lo, hi = coulomb.get("range") or (None, None)
    if lo and hi:
        widened = coulomb.get("widenings", 0)
        searched = f" Searched v_s = 0 and {_g(lo, 3)}..{_g(hi, 3)} rad/s" + (
            f" (widened {widened}× by a decade: the optimum sat on an edge)." if widened else "."
        )
    if coulomb.get("identifiable", not coulomb.get("note")):
        head = f"Chosen v_s = {v_s} rad/s by cross-validated least squares."
    else:
        head = f"**v_s = {v_s} rad/s is not identified by these data**: {coulomb.get('note')}."
    return [
        head + searched,
        "",
        "Cross-validated torque RMS (N·m, N) of least squares per candidate (lower is better):",
    ]


def render(
    model: IdentifiedModel,
    data: DataLike,
    *,
    figures: Sequence[tuple[str, str]] = (),
    validation: DataLike | None = None,
    log_report: dict[str, Any] | None = None,
    coulomb: dict[str, Any] | None = None,
    feasibility: Any = None,
    sources: dict[str, str] | None = None,
    comparison: Sequence[str] = (),
) -> str:
    """The markdown report (``comparison``: the lines of :func:`comparison_section`,
    placed before this model's details)."""
    robot = model.robot
    joints = list(robot.joint_names)
    fit = as_grid(data, model)
    title = f"# Identified model of {robot.name} ({model.method})"
    if comparison:
        title = f"# Identified models of {robot.name}: methods compared"
    lines = [title, ""]
    for k, v in (sources or {}).items():
        lines.append(f"- {k}: `{v}`")
    d = fit.data
    lines += [
        f"- joints: {robot.dof} ({', '.join(joints)})",
        f"- friction: {', '.join(robot.friction) or 'none'}; Coulomb speed scale v_s = "
        f"{_g(robot.coulomb_smoothing)} rad/s (0 = exact sign)",
        f"- identification samples: {len(d)} over {d.duration:.3g} s (after preprocessing)",
        f"- base parameters: {len(model.beta)}; cond(W_b) = {_g(model.cond)}",
    ]
    still = measurements.barely_moving(robot, d.q)
    if still:
        lines.append(f"- **warning**: {measurements.barely_moving_warning(still)}")
    lines.append("")
    if comparison:
        lines += list(comparison)
        lines += [f"## The {model.method} model (`model.json`)", ""]
    tables = [("identification data", fit)]
    if validation is not None:
        tables.append(("validation data", as_grid(validation, model)))
    lines += prediction_section(model, tables)
    lines += ["## Base parameters", ""]
    sigma = model.sigma
    rsd = model.rsd_percent
    rows = []
    for i, (name, combo) in enumerate(zip(model.base_names, model.combinations, strict=True)):
        rows.append(
            [
                name,
                f"`{combo}`",
                _with_sigma(model.beta[i], None if sigma is None else sigma[i]),
                _g(None if sigma is None else sigma[i], 2),
                _g(None if rsd is None else rsd[i], 3),
            ]
        )
    lines += _table(["β", "combination", "value (SI)", "σ", "%σ"], rows)
    lines.append("")
    lines += _actuator_lines(model)
    if coulomb is not None:
        lines += ["## Coulomb speed scale", ""]
        lines += _coulomb_summary(coulomb)
        lines.append("")
        order = np.argsort(coulomb["candidates"])
        lines += _table(
            ["v_s (rad/s)", "CV torque RMS"],
            [[_g(coulomb["candidates"][i]), _g(coulomb["cv_rms"][i])] for i in order],
        )
        lines.append("")
    if feasibility is None and model.standard_parameters is not None:
        st = model.settings
        weighting = (
            "each joint weighted by 1/σ_j² as wls estimates σ_j"
            if st.get("weighted")
            else "unweighted"
        )
        feasibility = (
            "The estimate is a set of rigid bodies (every link's pseudo-inertia positive "
            "semidefinite, fv, fc >= 0): non-physical links "
            f"{st.get('non_physical_links') or 'none'}; its residual is "
            f"{_g(st.get('residual_increase_percent'), 3)} % above the unconstrained least "
            f"squares' ({st.get('iterations')} barrier Newton steps; {weighting}; held to "
            f"the prior with divergence_weight {_g(st.get('divergence_weight'))}). "
            "`robot.urdf` carries its inertials."
        )
    if feasibility is not None:
        lines += ["## Physical feasibility", "", str(feasibility), ""]
        lines += _prior_section(model)
    lines += ["## Preprocessing", ""]
    if log_report:
        for k, v in log_report.items():
            lines.append(f"- {k}: {_record_value(v)}")
    else:
        lines.append("- none: velocities and accelerations were given in the data")
    lines.append("")
    if figures:
        lines += ["## Figures", ""]
        for name, caption in figures:
            lines += [f"{caption} (`{name}`):", "", f"![{caption}]({name})", ""]
    return "\n".join(lines)


def _actuator_lines(model: IdentifiedModel) -> list[str]:
    """The "Actuators" section: coupling, and each actuator's friction and rotor inertia
    with σ (none when the robot has no actuator terms)."""
    acts = model.actuators
    act = model.robot.actuators
    if not acts and act["coupling"] is None:
        return []
    lines = ["## Actuators", ""]
    if act["coupling"] is not None:
        lines.append(
            "Coupled actuators: velocities q̇ₘ = C·q̇ (joint-side units), their torques reach "
            "the joints through Cᵀ. C ="
        )
        lines.append("")
        lines += ["    " + "  ".join(f"{x:8.4g}" for x in row) for row in act["coupling"]]
        lines.append("")
    if act["gear_ratios"] is not None:
        lines.append(
            "Gear ratios (motor angle per joint-side angle): "
            + ", ".join(_g(r) for r in act["gear_ratios"])
        )
        lines.append("")
    if acts:
        lines.append(
            "Per actuator: friction on its velocity (fv N·m·s/rad, fc and fo N·m; N·s/m, N "
            "for a prismatic joint) and Ia, its rotor inertia reflected to the joint side "
            "(kg·m²). A term the data see only together with link parameters is given with "
            "that base parameter's value (its combination)."
        )
        lines.append("")
        rows = []
        for a in acts:
            for t in a["terms"]:
                if t["base_index"] is None:
                    how = "not identifiable"
                elif t["alone"]:
                    how = "alone"
                else:
                    how = f"`{t['combination']}`"
                rows.append(
                    [
                        str(a["actuator"]),
                        ", ".join(a["joints"]),
                        t["name"],
                        _with_sigma(t["value"], t["sigma"], 5),
                        _g(t["sigma"], 2),
                        how,
                        _g(t["standard"], 5),
                    ]
                )
        lines += _table(
            ["actuator", "moves", "term", "value (SI)", "σ", "identified as", "physical π"], rows
        )
        lines.append("")
    return lines


def write_report(
    model: IdentifiedModel,
    directory: str | os.PathLike[str],
    data: DataLike,
    *,
    drawings: list[Callable[[], object]] | None = None,
    **kwargs: Any,
) -> list[Path]:
    """Writes ``report.md`` and then the figures it links into ``directory`` (which must
    exist; callers that want all-or-nothing output build it with
    :func:`prrrp.outdir.write_dir`). ``data`` and ``validation``: the measurements as read
    (scored at their rows), a :class:`~prrrp.prediction.LogGrid` or a ``Dataset`` (scored
    against its own τ). With ``drawings`` (a list) the figures are not drawn: a call per
    figure is appended (:func:`figure_drawings`), for a caller that writes all its text
    first. Other keyword arguments as :func:`render`. Returns the paths written (or to be
    drawn)."""
    d = Path(directory)
    data = as_grid(data, model)
    if kwargs.get("validation") is not None:
        kwargs["validation"] = as_grid(kwargs["validation"], model)
    validation = kwargs.get("validation")
    own = figure_list(model, validation is not None)
    figures = [*kwargs.pop("figures", ()), *own]
    # The report first: it never waits for the figures it links.
    (d / "report.md").write_text(render(model, data, figures=figures, **kwargs), "utf-8")
    if drawings is None:
        write_figures(model, data, d, validation)
    else:
        drawings += figure_drawings(model, data, d, validation)
    return [d / "report.md", *(d / name for name, _ in figures)]


def write_report_dir(
    model: IdentifiedModel,
    directory: str | os.PathLike[str],
    data: DataLike,
    validation: DataLike | None = None,
) -> list[Path]:
    """``IdentifiedModel.report``: :func:`write_report` into ``directory``, built aside and
    swapped in whole (:func:`prrrp.outdir.write_dir`), with the preprocessing and Coulomb
    speed-scale records the model carries."""
    from prrrp import outdir

    pre = model.preprocessing if isinstance(model.preprocessing, dict) else {}
    log_report = pre.get("report") if isinstance(pre.get("report"), dict) else None
    coulomb = pre.get("coulomb_scale") if isinstance(pre.get("coulomb_scale"), dict) else None
    if coulomb is not None:
        _check_coulomb_record(coulomb)

    def build(tmp: Path) -> list[Path]:
        written = write_report(
            model, tmp, data, validation=validation, log_report=log_report, coulomb=coulomb
        )
        return [Path(directory) / p.name for p in written]

    return outdir.write_dir(Path(directory), build)


def _check_coulomb_record(c: dict[str, Any]) -> None:
    """A model's Coulomb speed-scale record (hand-edited model.json files reach here):
    ``chosen`` a number, ``candidates`` and ``cv_rms`` lists of numbers of one length;
    raises ValueError naming what is wrong."""

    def number(x: Any) -> bool:
        return isinstance(x, int | float) and not isinstance(x, bool)

    where = "the model's preprocessing 'coulomb_scale' record"
    if not number(c.get("chosen")):
        raise InvalidInputError(f"{where}: 'chosen' is {c.get('chosen')!r}, not a number (rad/s)")
    lists = [c.get("candidates"), c.get("cv_rms")]
    if not all(isinstance(v, list) and all(number(x) for x in v) for v in lists):
        raise InvalidInputError(f"{where}: 'candidates' and 'cv_rms' must be lists of numbers")
    if len(lists[0]) != len(lists[1]):
        raise InvalidInputError(f"{where}: 'candidates' and 'cv_rms' differ in length")
