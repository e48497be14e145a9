"""What the arm carries: identify a payload on a known arm, and drive gains from a payload of
known mass — what ``prrrp payload`` and ``prrrp identify --payload-run`` run, for notebook
users, and their report.

>>> arm = prrrp.IdentifiedModel.load("arm/model.json")                  # doctest: +SKIP
>>> loaded = prrrp.payload.identify(arm, prrrp.read_measurements("loaded.csv", arm.robot))
...                                                                     # doctest: +SKIP
>>> loaded.payload["mass"], loaded.payload["com"]                       # doctest: +SKIP

The payload is one rigid body fixed to a link of the chain (the tip unless ``tip`` says
otherwise): mass (kg), centre of mass (m) in that link's frame — the frame of the link's
URDF joint, with everything rigidly attached to the link merged into it — and inertia about
the centre of mass (kg·m², link-frame axes), each with σ and an ``identifiable`` flag.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from prrrp._prrrp import Dataset, IdentifiedModel, InvalidInputError, identify_drive_gains
from prrrp.measurements import measurements_to_dataset

#: Names of the inertia entries about the centre of mass, in the JSON's order.
INERTIA_NAMES = ("Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def recorded_settings(model: IdentifiedModel) -> dict[str, Any]:
    """The preprocessing settings ``model`` was identified with (re-applied to new logs)."""
    pre = model.preprocessing if isinstance(model.preprocessing, dict) else {}
    settings = pre.get("settings")
    return settings if isinstance(settings, dict) else {}


def to_dataset(model: IdentifiedModel, raw: dict[str, np.ndarray] | Dataset) -> Dataset:
    """A run as the model's data set: ``prrrp.read_measurements``'s dict preprocessed as the
    model recorded (a ready ``Dataset`` as it is)."""
    if isinstance(raw, Dataset):
        return raw
    data, _ = measurements_to_dataset(raw, recorded_settings(model))
    return data


def identify(
    arm: IdentifiedModel,
    loaded: dict[str, np.ndarray] | Dataset,
    mass: float | None = None,
    *,
    tip: str | int | None = None,
    **thresholds: Any,
) -> IdentifiedModel:
    """The arm + payload model from a run with the payload (``IdentifiedModel.identify_payload``
    on the run preprocessed as the arm model recorded)."""
    return arm.identify_payload(to_dataset(arm, loaded), mass, tip=tip, **thresholds)


def drive_gains(
    arm: IdentifiedModel,
    unloaded: Dataset,
    loaded: Dataset,
    mass: float,
    *,
    tip: str | int | None = None,
    **settings: Any,
) -> tuple[IdentifiedModel, dict[str, Any], list[float]]:
    """Drive gains (Gautier & Briot): ``unloaded`` and ``loaded`` hold currents (A) in their
    torque columns; ``arm`` gives the robot and the base analysis (e.g. the unloaded run
    identified with unit gains). Returns the arm model in torque units with its
    ``drive_gains``, the payload (dict) and the naive least-squares gains."""
    return identify_drive_gains(arm, unloaded, loaded, mass, tip=tip, **settings)


# ----------------------------------------------------------------------------------- report


def _g(x: Any, digits: int = 4) -> str:
    if x is None:
        return "-"
    return f"{float(x):.{digits}g}"


def payload_lines(payload: dict[str, Any]) -> list[str]:
    """Markdown table rows of a payload: each quantity, its value and σ, or 'not
    identifiable' where the data cannot tell."""
    ident = payload["identifiable"]
    rows = []

    def row(name: str, unit: str, value: Any, sigma: Any, ok: bool, given: bool = False) -> None:
        if given:
            shown, note = _g(value), "given"
        elif ok:
            shown, note = _g(value), "identified"
        else:
            shown, note = "not identifiable", f"estimate {_g(value)}, σ too large"
        rows.append(f"| {name} | {unit} | {shown} | {_g(sigma, 2)} | {note} |")

    row(
        "mass",
        "kg",
        payload["mass"],
        payload.get("mass_sigma"),
        ident["mass"],
        payload.get("mass_given", False),
    )
    com = payload.get("com") or [None] * 3
    com_s = payload.get("com_sigma") or [None] * 3
    for k, axis in enumerate("xyz"):
        row(f"COM {axis}", "m", com[k], com_s[k], ident["com"][k])
    inertia = payload.get("inertia") or [None] * 6
    inertia_s = payload.get("inertia_sigma") or [None] * 6
    for k, name in enumerate(INERTIA_NAMES):
        row(f"{name} (about COM)", "kg·m²", inertia[k], inertia_s[k], ident["inertia"][k])
    none = no_payload(payload)
    return [
        "| quantity | unit | value | σ | |",
        "|---|---|---|---|---|",
        *rows,
        *(["", none[0].upper() + none[1:] + "."] if none else []),
    ]


def no_payload(payload: dict[str, Any]) -> str | None:
    """A sentence when the run shows no payload: a fitted mass within 2σ of zero (the
    mass is then "not identifiable" as a fraction of itself, yet the run bounds it)."""
    m, s = payload.get("mass"), payload.get("mass_sigma")
    if payload.get("mass_given") or m is None or s is None or not abs(m) <= 2 * s:
        return None
    return (
        f"no payload detected: the fitted mass {_g(m, 2)} ± {_g(s, 2)} kg is within 2σ of 0, "
        f"so anything carried at {payload['link']} weighs less than {_g(abs(m) + 2 * s, 2)} kg"
    )


def explained_torque_figure(
    arm: IdentifiedModel, loaded: IdentifiedModel, data: Dataset, path: Path
) -> None:
    """Per joint: the measured torque minus the bare arm's prediction (what the arm model
    does not explain) and the payload's share of the arm + payload model."""
    from prrrp import drawing
    from prrrp.model_report import _grid, _units

    q, qd, qdd = data.q, data.qd, data.qdd
    unexplained = np.asarray(data.tau) - np.asarray(arm.predict(q, qd, qdd))
    # The payload's torque plus the change of the re-fitted friction: the whole difference
    # between the two models.
    explained = np.asarray(loaded.predict(q, qd, qdd)) - np.asarray(arm.predict(q, qd, qdd))
    joints = list(arm.robot.joint_names)
    force_units, _ = _units(arm)
    n = len(joints)
    rows, cols = _grid(n)
    t = np.asarray(data.t)
    fig, axes = drawing.figure(rows, cols, top=0.7)
    for j in range(n):
        ax = axes[j // cols][j % cols]
        drawing.lines(ax, t, unexplained[:, j], lw=0.6, color="0.5", label="measured − arm model")
        drawing.lines(
            ax,
            t,
            explained[:, j],
            lw=0.9,
            ls="--",
            color="tab:red",
            label="payload (+ re-fitted friction)",
        )
        ax.set_title(joints[j], fontsize=9)
        ax.set_xlabel("time (s)", fontsize=8)
        ax.set_ylabel(f"torque ({force_units[j]})", fontsize=8)
    for j in range(n, rows * cols):
        axes[j // cols][j % cols].axis("off")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=2, fontsize=8, frameon=False)
    drawing.save(fig, path)


def write_report(
    directory: str | os.PathLike[str],
    arm: IdentifiedModel,
    loaded: IdentifiedModel,
    data: Dataset,
    sources: dict[str, str] | None = None,
) -> list[Path]:
    """Writes ``report.md`` and ``explained_torque.png`` about the payload of ``loaded`` (the
    arm + payload model) on the run ``data`` into the existing folder ``directory``."""
    d = Path(directory)
    payload = loaded.payload
    if payload is None:
        raise InvalidInputError("the model carries no payload")
    explained_torque_figure(arm, loaded, data, d / "explained_torque.png")
    ident = payload.get("identification") or {}
    unexplained = np.asarray(data.tau) - np.asarray(arm.predict(data.q, data.qd, data.qdd))
    rest = np.asarray(data.tau) - np.asarray(loaded.predict(data.q, data.qd, data.qdd))
    rms = lambda x: np.sqrt(np.mean(x**2, axis=0))  # noqa: E731
    joints = list(arm.robot.joint_names)
    lines = [
        f"# Payload of {arm.robot.name}",
        "",
        f"Carried by link `{payload['link']}` (link {payload['link_index'] + 1} of the chain); "
        "centre of mass and inertia in that link's frame, the inertia about the centre of mass. "
        f"{len(data)} samples over {data.duration:.3g} s.",
        "",
    ]
    if sources:
        lines += [", ".join(f"{k}: `{v}`" for k, v in sources.items()), ""]
    lines += payload_lines(payload)
    lines += [
        "",
        "A quantity is *identifiable* when its σ is at most "
        f"{100 * ident.get('thresholds', {}).get('max_relative_sigma', 0.1):.3g} % of the mass "
        "(mass) or of the moment scale ½·tr(I_C) (inertia), or at most "
        f"{1000 * ident.get('thresholds', {}).get('com_tolerance_m', 0.01):.3g} mm (centre of "
        "mass). σ from the unconstrained least-squares fit (per-joint residual variances and "
        "correlation times); where it was not physical, the fit was projected onto the "
        "rigid bodies (pseudo-inertia ⪰ 0)"
        + (" — it was here." if ident.get("projected") else "."),
        "",
        "## Torque the arm model does not explain",
        "",
        "| joint | measured − arm (RMS) | after the payload (RMS) |",
        "|---|---|---|",
        *(
            f"| {j} | {_g(a)} | {_g(b)} |"
            for j, a, b in zip(joints, rms(unexplained), rms(rest), strict=True)
        ),
        "",
        "![explained torque](explained_torque.png)",
        "",
        "*Per joint: the measured torque minus the bare arm model's, and the payload's torque "
        "(with the re-fitted friction) of the arm + payload model.*",
        "",
    ]
    if ident.get("refit"):
        lines += [
            "Re-fitted on this run: " + ", ".join(f"`{r}`" for r in ident["refit"]) + ".",
            "",
        ]
    (d / "report.md").write_text("\n".join(lines), "utf-8")
    return [d / "report.md", d / "explained_torque.png"]


def gain_lines(gains: dict[str, Any], joints: list[str]) -> list[str]:
    """Markdown rows of identified drive gains, with the naive least-squares ones beside."""
    naive = (gains.get("identification") or {}).get("naive_least_squares") or [None] * len(joints)
    rows = []
    for j, name in enumerate(joints):
        value, sigma, ok = gains["values"][j], gains["sigma"][j], gains["identifiable"][j]
        shown = _g(value) if ok else f"not identifiable ({_g(value)})"
        rows.append(f"| {name} | {shown} | {_g(sigma, 2)} | {_g(naive[j])} |")
    return [
        "| actuator of | K (N·m/A) | σ | naive least squares |",
        "|---|---|---|---|",
        *rows,
    ]
