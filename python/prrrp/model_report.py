"""The report of an identified model of any robot: ``report.md`` and PNG figures (torque
prediction per joint, residual histograms, friction curves), written by
``prrrp identify --robot ... --out DIR`` and :func:`write_report`.

The friction curve of joint j plots the friction torque the model identified,
fv·q̇ + fc·tanh(q̇/v_s) + fo (the exact sign when v_s = 0), over the data's
*residual-corrected* points τ_j − τ̂_rigid,j: the measured torque minus the model's
rigid-body part, i.e. the friction the data shows. A model that fits puts the curve
through the cloud.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from prrrp._prrrp import Dataset, IdentifiedModel

FRICTION_TERMS = ("fv", "fc", "fo")


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=100, format="png")
    _pyplot().close(fig)


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


def prediction_table(model: IdentifiedModel, data: Dataset) -> dict[str, np.ndarray]:
    """Per joint: RMS of the prediction error (N·m, N), RMS of the measured torque, and the
    error as % of it."""
    err = np.asarray(model.predict(data.q, data.qd, data.qdd)) - np.asarray(data.tau)
    rms, ref = _rms(err), _rms(data.tau)
    pct = np.where(ref > 0, 100 * rms / np.where(ref > 0, ref, 1), np.nan)
    return {"rms": rms, "tau_rms": ref, "percent": pct}


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


def write_figures(
    model: IdentifiedModel, data: Dataset, directory: Path, validation: Dataset | None = None
) -> list[tuple[str, str]]:
    """Writes the figures; returns (file name, caption) pairs."""
    plt = _pyplot()
    joints = list(model.robot.joint_names)
    n = len(joints)
    rows, cols = _grid(n)
    out: list[tuple[str, str]] = []

    check = validation if validation is not None else data
    which = "validation" if validation is not None else "identification"
    pred = np.asarray(model.predict(check.q, check.qd, check.qdd))
    t = np.asarray(check.t)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.6 * rows), squeeze=False)
    for j in range(n):
        ax = axes[j // cols][j % cols]
        ax.plot(t, check.tau[:, j], lw=0.8, label="measured")
        ax.plot(t, pred[:, j], lw=0.8, ls="--", label="predicted")
        ax.set_title(joints[j], fontsize=9)
        ax.set_xlabel("t (s)")
    for j in range(n, rows * cols):
        axes[j // cols][j % cols].axis("off")
    axes[0][0].legend(fontsize=7)
    _save(fig, directory / "torque.png")
    out.append(("torque.png", f"Measured and predicted joint torques on the {which} data"))

    resid = np.asarray(check.tau) - pred
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.4 * rows), squeeze=False)
    for j in range(n):
        ax = axes[j // cols][j % cols]
        ax.hist(resid[:, j], bins=40)
        ax.set_title(f"{joints[j]}: RMS {_rms(resid[:, j]):.3g}", fontsize=9)
    for j in range(n, rows * cols):
        axes[j // cols][j % cols].axis("off")
    _save(fig, directory / "residual.png")
    out.append(("residual.png", f"Histogram of the torque residual per joint ({which} data)"))

    friction, mask = friction_split(model)
    if mask.any():
        v_s = float(model.robot.coulomb_smoothing)
        beta_rigid = np.where(mask, 0.0, model.beta)
        rigid = _predict_with(model, beta_rigid, data)
        points = np.asarray(data.tau) - rigid
        qd = np.asarray(data.qd)
        fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.8 * rows), squeeze=False)
        for j in range(n):
            ax = axes[j // cols][j % cols]
            ax.plot(qd[:, j], points[:, j], ".", ms=1.5, alpha=0.4, label="data")
            span = max(float(np.abs(qd[:, j]).max()), 1e-6)
            grid = np.linspace(-span, span, 401)
            curve = friction_torque(friction[j : j + 1], grid[:, None], v_s)[:, 0]
            ax.plot(grid, curve, "r", lw=1.2, label="model")
            ax.set_title(joints[j], fontsize=9)
            ax.set_xlabel("q̇ (rad/s, m/s)")
        for j in range(n, rows * cols):
            axes[j // cols][j % cols].axis("off")
        axes[0][0].legend(fontsize=7)
        _save(fig, directory / "friction.png")
        out.append(
            (
                "friction.png",
                "Friction torque vs speed per joint: the identified model over the measured "
                "torque minus the model's rigid-body part",
            )
        )
    return out


def _predict_with(model: IdentifiedModel, beta: np.ndarray, data: Dataset) -> np.ndarray:
    from prrrp._prrrp import identified_model_from_parts

    other = identified_model_from_parts(model.robot, beta)
    return np.asarray(other.predict(data.q, data.qd, data.qdd))


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return lines


def _g(x: Any, digits: int = 4) -> str:
    if x is None:
        return "–"
    x = float(x)
    return "–" if not np.isfinite(x) else f"{x:.{digits}g}"


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
    data: Dataset,
    *,
    figures: Sequence[tuple[str, str]] = (),
    validation: Dataset | None = None,
    log_report: dict[str, Any] | None = None,
    coulomb: dict[str, Any] | None = None,
    feasibility: Any = None,
    sources: dict[str, str] | None = None,
) -> str:
    """The markdown report."""
    robot = model.robot
    joints = list(robot.joint_names)
    lines = [f"# Identified model of {robot.name} ({model.method})", ""]
    for k, v in (sources or {}).items():
        lines.append(f"- {k}: `{v}`")
    lines += [
        f"- joints: {robot.dof} ({', '.join(joints)})",
        f"- friction: {', '.join(robot.friction) or 'none'}; Coulomb speed scale v_s = "
        f"{_g(robot.coulomb_smoothing)} rad/s (0 = exact sign)",
        f"- identification samples: {len(data)} over {data.duration:.3g} s",
        f"- base parameters: {len(model.beta)}; cond(W_b) = {_g(model.cond)}",
        "",
        "## Torque prediction",
        "",
    ]
    tables = [("identification data", data)]
    if validation is not None:
        tables.append(("validation data", validation))
    for label, d in tables:
        p = prediction_table(model, d)
        lines.append(f"On the {label} ({len(d)} samples):")
        lines.append("")
        lines += _table(
            ["joint", "error RMS (N·m, N)", "torque RMS", "error % of torque RMS"],
            [
                [j, _g(p["rms"][i]), _g(p["tau_rms"][i]), _g(p["percent"][i], 3)]
                for i, j in enumerate(joints)
            ],
        )
        lines.append("")
    lines += ["## Base parameters", ""]
    sigma = model.sigma
    rsd = model.rsd_percent
    rows = []
    for i, (name, combo) in enumerate(zip(model.base_names, model.combinations, strict=True)):
        rows.append(
            [
                name,
                f"`{combo}`",
                _g(model.beta[i], 6),
                _g(None if sigma is None else sigma[i], 3),
                _g(None if rsd is None else rsd[i], 3),
            ]
        )
    lines += _table(["β", "combination", "value (SI)", "σ", "%σ"], rows)
    lines.append("")
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
            lines.append(f"- {k}: {v}")
    else:
        lines.append("- none: velocities and accelerations were given in the data")
    lines.append("")
    if figures:
        lines += ["## Figures", ""]
        lines += [f"- `{name}`: {caption}" for name, caption in figures]
        lines.append("")
    return "\n".join(lines)


def write_report(
    model: IdentifiedModel,
    directory: str | os.PathLike[str],
    data: Dataset,
    **kwargs: Any,
) -> list[Path]:
    """Writes ``report.md`` and the figures into ``directory`` (which must exist; callers
    that want all-or-nothing output build it with :func:`prrrp.outdir.write_dir`).
    Keyword arguments as :func:`render`. Returns the written paths."""
    d = Path(directory)
    figures = write_figures(model, data, d, kwargs.get("validation"))
    (d / "report.md").write_text(render(model, data, figures=figures, **kwargs), "utf-8")
    return [d / "report.md", *(d / name for name, _ in figures)]


def write_report_dir(
    model: IdentifiedModel,
    directory: str | os.PathLike[str],
    data: Dataset,
    validation: Dataset | None = None,
) -> list[Path]:
    """``IdentifiedModel.report``: :func:`write_report` into ``directory``, built aside and
    swapped in whole (:func:`prrrp.outdir.write_dir`), with the preprocessing and Coulomb
    speed-scale records the model carries."""
    from prrrp import outdir

    pre = model.preprocessing if isinstance(model.preprocessing, dict) else {}
    log_report = pre.get("report") if isinstance(pre.get("report"), dict) else None
    coulomb = pre.get("coulomb_scale") if isinstance(pre.get("coulomb_scale"), dict) else None

    def build(tmp: Path) -> list[Path]:
        written = write_report(
            model, tmp, data, validation=validation, log_report=log_report, coulomb=coulomb
        )
        return [Path(directory) / p.name for p in written]

    return outdir.write_dir(Path(directory), build)
