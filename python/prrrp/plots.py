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

from prrrp import paper

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
        "Fig. 7: validation trajectories per joint, true robot vs each method's model",
    ),
    "fig8_sensitivity.png": (
        "sensitivity",
        "Fig. 8: position RMS vs variation of each λ_i, per joint",
    ),
    "lambda_bars.png": ("lambda_bars", "λ per method divided by the truth (1 = exact)"),
}


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _joint_label(j: int) -> str:
    return f"{paper.JOINTS[j]} ({paper.POSITION_UNITS[j]})"


def _save(fig: Any, path: str | os.PathLike[str]) -> None:
    fig.tight_layout()
    # format= because the caller may write to a temporary name without the .png suffix.
    fig.savefig(path, dpi=110, format="png")
    _pyplot().close(fig)


def trajectories(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 3: reference and output (true and measured) positions of each joint over time."""
    plt = _pyplot()
    data = results["estimation_data"]
    t = np.asarray(data["t"])
    q_ref, q = np.asarray(data["q_ref"]), np.asarray(data["q"])
    q_meas = np.asarray(data["q_measured"])
    fig, axes = plt.subplots(5, 1, figsize=(9, 11), sharex=True)
    for j, ax in enumerate(axes):
        ax.plot(t, q_ref[:, j], "--", color="black", lw=1.2, label="reference")
        ax.plot(t, q[:, j], color="tab:blue", lw=1.0, label="output")
        ax.plot(t, q_meas[:, j], ".", color="tab:orange", ms=1.5, alpha=0.5, label="measured")
        ax.set_ylabel(_joint_label(j))
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("Excitation trajectory: reference and output per joint (Fig. 3)")
    _save(fig, path)


def _history(
    results: dict[str, Any], method: str, title: str, path: str | os.PathLike[str]
) -> None:
    plt = _pyplot()
    truth = np.asarray(results["truth"])
    est = next((e for e in results["estimates"] if e["method"] == method), None)
    fig, axes = plt.subplots(4, 2, figsize=(10, 10), sharex=True)
    history = est.get("history") if est else None
    for i, ax in enumerate(axes.flat):
        if history:
            t = np.asarray(history["t"])
            lam = np.asarray(history["lambda"], dtype=float)
            ax.plot(t, lam[:, i], color="tab:blue", lw=1.2, label="estimate")
        ax.axhline(truth[i], color="black", ls="--", lw=1.0, label="truth")
        ax.set_ylabel(f"λ{i + 1} ({paper.PARAMETER_UNITS[i]})")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle(title if history else f"{title} — no history recorded")
    _save(fig, path)


def hopfield(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 5: the Hopfield network's λ estimate over time against the truth."""
    _history(results, "hopfield", "Hopfield network: λ estimate over time (Fig. 5)", path)


def ekf(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 6: the extended Kalman filter's λ estimate over time against the truth."""
    _history(results, "ekf", "Extended Kalman filter: λ estimate over time (Fig. 6)", path)


def validation(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 7: validation trajectories of the true robot and of each estimated model."""
    plt = _pyplot()
    val = results["validation"]
    t = np.asarray(val["t"])
    fig, axes = plt.subplots(5, 1, figsize=(9, 11), sharex=True)
    for j, ax in enumerate(axes):
        ax.plot(t, np.asarray(val["q_ref"])[:, j], ":", color="gray", lw=1.0, label="reference")
        ax.plot(t, np.asarray(val["q_true"])[:, j], color="black", lw=2.0, label="true robot")
        for m in val["methods"]:
            ax.plot(
                t,
                np.asarray(m["q"])[:, j],
                "--",
                lw=1.0,
                label=paper.METHOD_LABELS.get(m["method"], m["method"]),
            )
        ax.set_ylabel(_joint_label(j))
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("Validation: true robot vs models with estimated λ (Fig. 7)")
    _save(fig, path)


def sensitivity(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 8: position RMS per joint against the variation of each λ_i (%)."""
    plt = _pyplot()
    sens = results["sensitivity"]
    variation = 100.0 * (np.asarray(sens["factors"], dtype=float) - 1.0)
    fig, axes = plt.subplots(4, 2, figsize=(10, 11), sharex=True)
    for i, ax in enumerate(axes.flat):
        rms = np.array(
            [[np.nan if x is None else x for x in (row or [None] * 5)] for row in sens["rms"][i]],
            dtype=float,
        )
        for j in range(rms.shape[1]):
            ax.plot(variation, rms[:, j], "o-", ms=3, lw=1.0, label=_joint_label(j))
        ax.set_title(f"λ{i + 1}", fontsize=10)
        ax.set_ylabel("RMS (m or rad)")
        ax.grid(alpha=0.3)
        if np.any(rms > 0):
            ax.set_yscale("symlog", linthresh=1e-6)
    for ax in axes[-1]:
        ax.set_xlabel("variation of λ_i (%)")
    axes[0, 0].legend(loc="best", fontsize=7)
    fig.suptitle("Sensitivity: position RMS vs parameter variation (Fig. 8)")
    _save(fig, path)


def lambda_bars(results: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """λ of each method (ours and the paper's) divided by the truth, per parameter."""
    plt = _pyplot()
    truth = np.asarray(results["truth"], dtype=float)
    estimates = results["estimates"]
    n = len(estimates)
    x = np.arange(len(truth))
    width = 0.8 / max(n, 1)
    fig, ax = plt.subplots(figsize=(10, 5))
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
    ax.set_xlabel("base parameter")
    ax.set_ylabel("estimate / truth (dimensionless)")
    ax.set_title("Estimated λ per method, normalised by the true value")
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, ncol=3)
    _save(fig, path)


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
