"""Figures of ``prrrp reproduce`` (PNG, matplotlib's Agg backend), equivalent to the paper's
Figures 3, 5, 6, 7 and 8 plus a bar chart of λ per method against the truth.

Every function takes the study result dict (``prrrp.run_study``, schema_version 1) and a
path, and writes one PNG there.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from prrrp import drawing, paper

#: File name → (writer, one-line description), in the order the report lists them.
FIGURES: dict[str, tuple[str, str]] = {
    "fig3_trajectories.png": (
        "trajectories",
        "Fig. 3: excitation reference and the robot's output per joint",
    ),
    "fig5_hopfield.png": ("hopfield", "Fig. 5: Hopfield estimate of λ1..λ8 over time vs truth"),
    "fig6_ekf.png": ("ekf", "Fig. 6: EKF estimate of λ1..λ8 over time vs truth"),
    "fig7_validation.png": (
        "validation",
        "Fig. 7: validation trajectories per joint, each method's model minus the true robot",
    ),
    "fig8_sensitivity.png": (
        "sensitivity",
        "Fig. 8: position RMS vs variation of each λ_i, per joint (log scale; non-physical "
        "variations marked)",
    ),
    "lambda_bars.png": ("lambda_bars", "λ per method divided by the truth (1 = exact)"),
}


def _pyplot() -> Any:
    """pyplot on the Agg backend (the benchmark report's figures)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _joint_label(j: int) -> str:
    return f"{paper.JOINTS[j]} ({paper.POSITION_UNITS[j]})"


def _save(fig: Any, path: str | os.PathLike[str]) -> None:
    """Saves a pyplot figure (the benchmark report's) and closes it."""
    fig.tight_layout()
    # format= because the caller may write to a temporary name without the .png suffix.
    fig.savefig(path, dpi=110, format="png")
    _pyplot().close(fig)


def _legend_above(fig: Any, ax: Any, ncol: int = 4) -> None:
    """The legend of ``ax``'s lines in the figure's top margin, off the data."""
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(
        handles,
        labels,
        loc="upper center",
        ncol=ncol,
        fontsize=8,
        frameon=False,
        bbox_to_anchor=(0.5, 1.0 - 0.35 / fig.get_size_inches()[1]),
    )


def trajectories(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 3: reference and output (true and measured) positions of each joint over time."""
    data = results["estimation_data"]
    t = np.asarray(data["t"])
    q_ref, q = np.asarray(data["q_ref"]), np.asarray(data["q"])
    q_meas = np.asarray(data["q_measured"])
    fig, axes = drawing.figure(5, 1, panel=(8.0, 1.5), top=0.9, hspace=0.25, sharex=True)
    for j, ax in enumerate(axes[:, 0]):
        keep = drawing.thin_points(t, q_meas[:, j], drawing.pixels(ax))
        ax.plot(t[keep], q_meas[keep, j], ".", color="tab:orange", ms=1.5, label="measured")
        drawing.lines(ax, t, q_ref[:, j], "--", color="black", lw=1.2, label="reference")
        drawing.lines(ax, t, q[:, j], color="tab:blue", lw=1.0, label="output")
        ax.set_ylabel(_joint_label(j), fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)", fontsize=8)
    fig.suptitle("Excitation trajectory: reference and output per joint (Fig. 3)", fontsize=10)
    _legend_above(fig, axes[0, 0], ncol=3)
    drawing.save(fig, path)


def _data_duration(results: dict[str, Any]) -> float:
    """Duration of the estimation data, s (samples × sample period): one pass of an
    estimator whose clock advances one sample period per update."""
    t = np.asarray(results["estimation_data"]["t"], dtype=float)
    if len(t) < 2:
        return float("nan")
    return float(t[-1] - t[0]) + float(np.median(np.diff(t)))


def _history(
    results: dict[str, Any], method: str, title: str, path: str | os.PathLike[str]
) -> None:
    truth = np.asarray(results["truth"])
    est = next((e for e in results["estimates"] if e["method"] == method), None)
    fig, axes = drawing.figure(4, 2, panel=(4.0, 1.6), top=0.9, hspace=0.3, sharex=True)
    history = est.get("history") if est else None
    duration = _data_duration(results)
    passes = 1.0
    if history:
        t = np.asarray(history["t"], dtype=float)
        if len(t) and duration > 0:
            passes = float(t[-1]) / duration
    for i, ax in enumerate(axes.flat):
        if history:
            lam = np.asarray(history["lambda"], dtype=float)
            ax.plot(t, lam[:, i], color="tab:blue", lw=1.2, label="estimate")
            for k in range(1, int(np.ceil(passes - 1e-6))):
                ax.axvline(k * duration, color="0.6", lw=0.6, ls=":")
        ax.axhline(truth[i], color="black", ls="--", lw=1.0, label="truth")
        ax.set_ylabel(f"λ{i + 1} ({paper.PARAMETER_UNITS[i]})", fontsize=8)
        ax.grid(alpha=0.3)
    # Estimation time, not the robot's: the estimator's clock advances one sample period
    # per update, over every pass it makes through the data.
    if passes > 1 + 1e-6:
        xlabel = (
            f"estimation time (s): one update per sample of the {duration:.3g} s estimation "
            f"data, {passes:.3g} passes (dotted: a new pass)"
        )
    else:
        xlabel = "estimation time (s): one update per sample of the estimation data"
    fig.supxlabel(xlabel, fontsize=8, y=0.12 / fig.get_size_inches()[1])
    fig.suptitle(title if history else f"{title} — no history recorded", fontsize=10)
    _legend_above(fig, axes[0, 0], ncol=2)
    drawing.save(fig, path)


def hopfield(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 5: the Hopfield network's λ estimate over its estimation time against the
    truth."""
    _history(results, "hopfield", "Hopfield network: λ estimate over time (Fig. 5)", path)


def ekf(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 6: the extended Kalman filter's λ estimate over time against the truth."""
    _history(results, "ekf", "Extended Kalman filter: λ estimate over time (Fig. 6)", path)


def validation(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 7: each estimated model's position error against the true robot on the
    validation trajectory (the paper's figure overlays the trajectories, which agree
    to within a line width)."""
    val = results["validation"]
    t = np.asarray(val["t"])
    q_true = np.asarray(val["q_true"])
    fig, axes = drawing.figure(5, 1, panel=(8.0, 1.5), top=0.9, hspace=0.25, sharex=True)
    for j, ax in enumerate(axes[:, 0]):
        for m in val["methods"]:
            error = np.asarray(m["q"])[:, j] - q_true[:, j]
            label = paper.METHOD_LABELS.get(m["method"], m["method"])
            drawing.lines(ax, t, error, lw=1.0, label=label)
        ax.axhline(0.0, color="black", lw=0.8)
        ax.set_ylabel(f"{paper.JOINTS[j]} error ({paper.POSITION_UNITS[j]})", fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)", fontsize=8)
    fig.suptitle(
        "Validation: position of each model with estimated λ minus the true robot's (Fig. 7)",
        fontsize=10,
    )
    _legend_above(fig, axes[0, 0], ncol=len(val["methods"]))
    drawing.save(fig, path)


#: Decades of RMS a panel of Fig. 8 spans below its largest value.
FIG8_DECADES = 3


def _nullformatter() -> Any:
    from matplotlib.ticker import NullFormatter

    return NullFormatter()


def sensitivity(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 8: position RMS per joint against the variation of each λ_i (%), on a log
    scale; the unvaried model (RMS 0 exactly) is not drawn and variations that make the
    robot non-physical (M not positive definite: skipped by the study) are marked."""
    sens = results["sensitivity"]
    variation = 100.0 * (np.asarray(sens["factors"], dtype=float) - 1.0)
    fig, axes = drawing.figure(
        4,
        2,
        panel=(4.0, 1.6),
        top=1.05,
        hspace=0.55,
        left=1.0,
        wspace=1.1,
        label_offset=0.8,
        sharex=True,
    )
    skipped_any = floored_any = False
    for i, ax in enumerate(axes.flat):
        rms = np.array(
            [[np.nan if x is None else x for x in (row or [None] * 5)] for row in sens["rms"][i]],
            dtype=float,
        )
        positive = rms > 0
        # A log axis spans at most FIG8_DECADES below the panel's largest RMS; smaller
        # values (a joint the parameter does not move: rounding noise) sit on its floor.
        floor = 0.0
        if positive.any():
            floor = max(float(rms[positive].min()), np.nanmax(rms) * 10.0**-FIG8_DECADES)
        for j in range(rms.shape[1]):
            y = np.where(positive[:, j], np.maximum(rms[:, j], floor), np.nan)
            (line,) = ax.plot(variation, y, "-", lw=1.0, label=_joint_label(j))
            above = positive[:, j] & (rms[:, j] >= floor)
            below = positive[:, j] & (rms[:, j] < floor)
            ax.plot(variation[above], rms[above, j], "o", ms=3, color=line.get_color())
            if below.any():
                floored_any = True
                ax.plot(
                    variation[below],
                    np.full(below.sum(), floor),
                    "v",
                    ms=4,
                    color=line.get_color(),
                    label=f"below 1e-{FIG8_DECADES} × the panel's largest (≈ 0)",
                )
        if positive.any():
            ax.set_yscale("log")
            ax.set_ylim(bottom=floor / 1.5)
            ax.yaxis.set_minor_formatter(_nullformatter())
        skipped = np.isnan(rms).all(axis=1)
        if skipped.any():
            skipped_any = True
            # At the foot of the panel, in data x and axes y.
            ax.plot(
                variation[skipped],
                np.full(skipped.sum(), 0.04),
                "x",
                color="tab:red",
                ms=5,
                transform=ax.get_xaxis_transform(),
                clip_on=False,
                label="non-physical λ (skipped)",
            )
        ax.set_title(f"λ{i + 1} varied", fontsize=9)
        ax.set_ylabel("position RMS (m or rad)", fontsize=8)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("variation of λ_i (%)", fontsize=8)
    note = "; ×: non-physical, skipped" if skipped_any else ""
    note += "; ▼: ≈ 0" if floored_any else ""
    fig.suptitle(
        "Sensitivity: position RMS vs parameter variation, log scale (Fig. 8)" + note,
        fontsize=10,
    )
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab.startswith("below"):
                lab = "≈ 0 (below the floor)"
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(
        handles,
        labels,
        loc="upper center",
        ncol=6,
        fontsize=8,
        frameon=False,
        bbox_to_anchor=(0.5, 1.0 - 0.35 / fig.get_size_inches()[1]),
    )
    drawing.save(fig, path)


def lambda_bars(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """λ of each method (ours and the paper's) divided by the truth, per parameter."""
    truth = np.asarray(results["truth"], dtype=float)
    estimates = results["estimates"]
    n = len(estimates)
    x = np.arange(len(truth))
    width = 0.8 / max(n, 1)
    fig, axes = drawing.figure(1, 1, panel=(7.5, 3.6), right=1.7, top=0.5)
    ax = axes[0, 0]
    for k, e in enumerate(estimates):
        offset = (k - (n - 1) / 2) * width
        ratio = np.asarray(e["lambda"], dtype=float) / truth
        bars = ax.bar(
            x + offset, ratio, width, label=paper.METHOD_LABELS.get(e["method"], e["method"])
        )
        published = paper.TABLE4.get(e["method"])
        if published:
            ax.plot(
                x + offset,
                np.asarray(published) / truth,
                "_",
                ms=10,
                mew=2,
                color=bars.patches[0].get_facecolor(),
                markeredgecolor="black",
                label=None if k else "paper's value",
            )
    ax.axhline(1.0, color="black", lw=1.0, ls="--", label="truth")
    ax.set_xticks(x, [f"λ{i + 1}" for i in range(len(truth))])
    ax.set_xlabel("base parameter", fontsize=8)
    ax.set_ylabel("estimate / truth (dimensionless)", fontsize=8)
    ax.set_title("Estimated λ per method, normalised by the true value", fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    drawing.save(fig, path)


WRITERS: dict[str, Callable[[dict[str, Any], str | os.PathLike[str]], None]] = {
    "trajectories": trajectories,
    "hopfield": hopfield,
    "ekf": ekf,
    "validation": validation,
    "sensitivity": sensitivity,
    "lambda_bars": lambda_bars,
}


def write_all(results: dict[str, Any], directory: str | os.PathLike[str]) -> list[Path]:
    """Writes every figure of :data:`FIGURES` into ``directory``; returns their paths."""
    paths = []
    for name, (writer, _) in FIGURES.items():
        path = Path(directory) / name
        WRITERS[writer](results, path)
        paths.append(path)
    return paths
