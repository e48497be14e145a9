"""Results of a benchmark: ``results.csv`` (one row per case × method), ``results.json``
(the same rows, the configuration, the run's statistics and a summary per method, noise
and rate), ``report.md`` and its figures."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from prrrp.montecarlo.cases import COLUMNS, METHODS

#: Version of the results.json layout.
SCHEMA = "prrrp-benchmark/1"

#: Error columns summarised and plotted: column → label.
METRICS = {
    "max_param_error_percent": "largest relative parameter error (%)",
    "param_error_norm_percent": "parameter error ‖β̂ − β‖/‖β‖ (%)",
    "torque_rms_relative_percent": "validation torque RMS error, relative (%)",
}

FIGURES = {
    "errors_by_noise.png": "Error distributions per method (box: quartiles, whiskers: 5–95 %), "
    "one column per noise scale",
    "errors_vs_rate.png": "Median error against the sampling rate (band: quartiles), "
    "per method and noise scale",
    "time_per_method.png": "Identification wall time per method (one case)",
}


def _ordered_methods(rows: Sequence[dict[str, Any]]) -> list[str]:
    seen = {r["method"] for r in rows}
    return [m for m in METHODS if m in seen]


def _values(rows: Sequence[dict[str, Any]], column: str) -> np.ndarray:
    vals = [r[column] for r in rows if r["status"] == "ok" and r.get(column) is not None]
    return np.asarray(vals, dtype=float)


def _budget(row: dict[str, Any]) -> Any:
    return row.get("excitation_evaluations")


def summary(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per method × noise × rate × excitation budget: cases ok and failed, fraction
    converged, median and 90th percentile of each error column, median seconds and median
    cond(W) of the excitation."""
    out = []
    noises = sorted({r["noise"] for r in rows})
    rates = sorted({r["rate"] for r in rows})
    budgets = sorted({_budget(r) for r in rows}, key=lambda b: -1 if b is None else b)
    for method in _ordered_methods(rows):
        for noise in noises:
            for rate, budget in ((r, b) for r in rates for b in budgets):
                group = [
                    r
                    for r in rows
                    if r["method"] == method
                    and r["noise"] == noise
                    and r["rate"] == rate
                    and _budget(r) == budget
                ]
                if not group:
                    continue
                ok = [r for r in group if r["status"] == "ok"]
                conds = _values(group, "excitation_cond")
                entry: dict[str, Any] = {
                    "method": method,
                    "noise": noise,
                    "rate": rate,
                    "excitation_evaluations": budget,
                    "excitation_cond_median": float(np.median(conds)) if len(conds) else None,
                    "ok": len(ok),
                    "failed": len(group) - len(ok),
                    "converged_fraction": (
                        sum(bool(r["converged"]) for r in ok) / len(ok) if ok else None
                    ),
                }
                for column in (*METRICS, "seconds"):
                    v = _values(group, column)
                    entry[f"{column}_median"] = float(np.median(v)) if len(v) else None
                    if column != "seconds":
                        entry[f"{column}_p90"] = float(np.percentile(v, 90)) if len(v) else None
                out.append(entry)
    return out


def _csv_value(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def to_csv(rows: Sequence[dict[str, Any]]) -> str:
    """The rows as CSV text with the header :data:`COLUMNS` (empty cells where a value does
    not apply; floats written exactly)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COLUMNS)
    for row in rows:
        writer.writerow([_csv_value(row.get(c)) for c in COLUMNS])
    return buffer.getvalue()


def _fmt(x: Any, digits: int = 3) -> str:
    if x is None:
        return "–"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return str(x)


def _budgets(config: dict[str, Any]) -> list[int]:
    b = config.get("excitation_evaluations", [])
    return list(b) if isinstance(b, list | tuple) else [b]


def render(
    document: dict[str, Any],
    figures: Sequence[str],
    failed_figures: dict[str, str] | None = None,
) -> str:
    """report.md from the results.json document (``failed_figures``: name → error of the
    figures that could not be drawn)."""
    config, stats = document["config"], document["stats"]
    budgets = _budgets(config)
    lines = [
        "# Monte-Carlo estimator benchmark",
        "",
        f"Robot: **{config['robot']}**. Methods: {', '.join(config['methods'])}. "
        f"Noise scales: {', '.join(_fmt(n) for n in config['noise'])} × the default sensor "
        f"noise. Sampling rates: {', '.join(_fmt(r) for r in config['rates'])} Hz. "
        f"Seeds: {len(config['seeds'])}. Excitation: {config['duration']:g} s, optimised "
        f"with a budget of {', '.join(str(b) for b in budgets)} cost evaluations per case "
        "(`--excitation-evaluations`).",
        "",
        f"{stats['cases']} cases on {stats['engine']} ({stats['parallelism']} in parallel): "
        f"{stats['elapsed_s']:.1f} s, {stats['cases_per_second']:.2f} cases/s; "
        f"{stats['failed_cases']} cases failed, {stats['retries']} retries, "
        f"{stats['restarts']} pool restarts.",
        "",
        "Each case: an excitation trajectory optimised for cond(W), the simulated robot "
        "tracking it in closed loop, sensor noise, preprocessing (zero-phase low-pass, "
        "differentiation), identification with each method, and torque prediction on a "
        "second, noise-free trajectory. Parameter errors are relative to the simulated "
        "robot's base parameters (the largest and the norm; structurally zero parameters "
        "are left out of the relative ones). Torque error: 100·‖τ − τ̂‖/‖τ‖ per joint, "
        "averaged over the joints. Values: median (90th percentile).",
        "",
        "| method | noise | rate (Hz) | excitation evals | ok | failed | converged | "
        "max param err % | param err norm % | torque err % | seconds |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in document["summary"]:

        def both(column: str, s: dict[str, Any] = s) -> str:
            return f"{_fmt(s[column + '_median'])} ({_fmt(s[column + '_p90'])})"

        conv = s["converged_fraction"]
        lines.append(
            f"| {s['method']} | {_fmt(s['noise'])} | {_fmt(s['rate'])} | "
            f"{_fmt(s.get('excitation_evaluations'))} | {s['ok']} | "
            f"{s['failed']} | {'–' if conv is None else f'{100 * conv:.0f} %'} | "
            f"{both('max_param_error_percent')} | {both('param_error_norm_percent')} | "
            f"{both('torque_rms_relative_percent')} | {_fmt(s['seconds_median'], 2)} |"
        )
    lines += ["", *excitation_section(document)]
    errors = sorted({r["error"] for r in document["rows"] if r["status"] == "failed"})
    if errors:
        lines += ["", "Failures (distinct errors):", ""]
        lines += [f"- {e}" for e in errors[:20]]
    if figures or failed_figures:
        lines += ["", "## Figures", ""]
        for name in figures:
            lines += [f"![{FIGURES[name]}]({name})", "", f"*{FIGURES[name]}.*", ""]
        for name, error in (failed_figures or {}).items():
            lines += [
                f"- `{name}` could not be drawn ({error}); the numbers above and in "
                "results.csv / results.json are complete.",
                "",
            ]
    return "\n".join(lines).rstrip() + "\n"


def excitation_section(document: dict[str, Any]) -> list[str]:
    """What the excitation optimiser's budget buys: cond(W) of the designed excitation and
    the median errors per budget (over every method, noise and rate, the cases paired by
    seed); with one budget, how the errors go with the cond(W) each case reached."""
    rows = [r for r in document["rows"] if r["status"] == "ok"]
    budgets = sorted({_budget(r) for r in rows if _budget(r) is not None})
    if not rows or not budgets:
        return []
    lines = ["## Excitation budget", ""]
    if len(budgets) > 1:
        lines += [
            "Medians over every method, noise and rate (each seed starts every budget's "
            "search from the same point, so the budgets are compared case for case):",
            "",
            "| excitation evals | cond(W) of the excitation | max param err % | torque err % |",
            "|---|---|---|---|",
        ]
        for b in budgets:
            group = [r for r in rows if _budget(r) == b]
            lines.append(
                f"| {b} | {_fmt(_median(group, 'excitation_cond'))} | "
                f"{_fmt(_median(group, 'max_param_error_percent'))} | "
                f"{_fmt(_median(group, 'torque_rms_relative_percent'))} |"
            )
        return [*lines, ""]
    conds = _values(rows, "excitation_cond")
    if len(conds) < 4:
        return []
    cut = float(np.median(conds))
    better = [
        r for r in rows if r.get("excitation_cond") is not None and r["excitation_cond"] <= cut
    ]
    worse = [r for r in rows if r.get("excitation_cond") is not None and r["excitation_cond"] > cut]
    lines += [
        f"One budget ({budgets[0]} evaluations) was run; its cases reached cond(W) "
        f"{_fmt(float(np.min(conds)))}..{_fmt(float(np.max(conds)))} (median {_fmt(cut)}). "
        "Median errors of the cases below and above that median show what a better "
        "excitation is worth here; to measure the budget itself, give several, e.g. "
        f"`--excitation-evaluations 50,{budgets[0]}`.",
        "",
        "| cases | cond(W) | max param err % | torque err % |",
        "|---|---|---|---|",
        f"| better-conditioned half | ≤ {_fmt(cut)} | "
        f"{_fmt(_median(better, 'max_param_error_percent'))} | "
        f"{_fmt(_median(better, 'torque_rms_relative_percent'))} |",
        f"| worse-conditioned half | > {_fmt(cut)} | "
        f"{_fmt(_median(worse, 'max_param_error_percent'))} | "
        f"{_fmt(_median(worse, 'torque_rms_relative_percent'))} |",
        "",
    ]
    return lines


def _median(rows: Sequence[dict[str, Any]], column: str) -> float | None:
    v = _values(rows, column)
    return float(np.median(v)) if len(v) else None


# ---------------------------------------------------------------------------------- figures


def _box(ax: Any, data: list[np.ndarray], labels: list[str]) -> None:
    positions = [k for k, d in enumerate(data) if len(d)]
    if positions:
        ax.boxplot(
            [data[k] for k in positions],
            positions=positions,
            whis=(5, 95),
            showfliers=False,
            widths=0.6,
        )
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, rotation=30)
    ax.set_yscale("log")
    ax.grid(True, axis="y", which="both", alpha=0.3)


def errors_by_noise(rows: Sequence[dict[str, Any]], path: str | os.PathLike[str]) -> None:
    from prrrp.plots import _pyplot, _save

    plt = _pyplot()
    methods = _ordered_methods(rows)
    noises = sorted({r["noise"] for r in rows})
    fig, axes = plt.subplots(
        len(METRICS),
        len(noises),
        figsize=(1.2 + 2.0 * len(noises) + 0.35 * len(methods), 2.6 * len(METRICS)),
        squeeze=False,
        sharey="row",
    )
    for i, (column, label) in enumerate(METRICS.items()):
        for j, noise in enumerate(noises):
            data = [
                _values([r for r in rows if r["method"] == m and r["noise"] == noise], column)
                for m in methods
            ]
            ax = axes[i][j]
            _box(ax, [d[d > 0] for d in data], methods)
            if i == 0:
                ax.set_title(f"noise × {noise:g}")
            if j == 0:
                ax.set_ylabel(label, fontsize=8)
    _save(fig, path)


def errors_vs_rate(rows: Sequence[dict[str, Any]], path: str | os.PathLike[str]) -> None:
    from prrrp.plots import _pyplot, _save

    plt = _pyplot()
    methods = _ordered_methods(rows)
    noises = sorted({r["noise"] for r in rows})
    rates = sorted({r["rate"] for r in rows})
    fig, axes = plt.subplots(
        len(METRICS),
        len(noises),
        figsize=(3.4 * len(noises) + 1, 2.6 * len(METRICS)),
        squeeze=False,
        sharey="row",
    )
    for i, (column, label) in enumerate(METRICS.items()):
        for j, noise in enumerate(noises):
            ax = axes[i][j]
            for k, m in enumerate(methods):
                stats = []
                for rate in rates:
                    v = _values(
                        [
                            r
                            for r in rows
                            if r["method"] == m and r["noise"] == noise and r["rate"] == rate
                        ],
                        column,
                    )
                    stats.append(np.percentile(v, [25, 50, 75]) if len(v) else [np.nan] * 3)
                s = np.asarray(stats)
                # Dashes tell apart methods that coincide (one-pass RLS is least squares).
                style = ("-", "--", ":", "-.")[k % 4]
                (line,) = ax.plot(rates, s[:, 1], marker="o", linestyle=style, label=m)
                ax.fill_between(rates, s[:, 0], s[:, 2], color=line.get_color(), alpha=0.15)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xticks(rates)
            ax.set_xticklabels([f"{r:g}" for r in rates])
            ax.minorticks_off()
            ax.grid(True, which="both", alpha=0.3)
            if i == 0:
                ax.set_title(f"noise × {noise:g}")
            if i == len(METRICS) - 1:
                ax.set_xlabel("sampling rate (Hz)")
            if j == 0:
                ax.set_ylabel(label, fontsize=8)
    axes[0][-1].legend(fontsize=7, loc="best")
    _save(fig, path)


def time_per_method(rows: Sequence[dict[str, Any]], path: str | os.PathLike[str]) -> None:
    from prrrp.plots import _pyplot, _save

    plt = _pyplot()
    methods = _ordered_methods(rows)
    fig, ax = plt.subplots(figsize=(1.5 + 0.8 * len(methods), 3.2))
    data = [
        np.asarray(
            [r["seconds"] for r in rows if r["method"] == m and r["seconds"] is not None], float
        )
        for m in methods
    ]
    _box(ax, [d[d > 0] for d in data], methods)
    ax.set_ylabel("identification time per case (s)")
    _save(fig, path)


def write(document: dict[str, Any], directory: str | os.PathLike[str]) -> list[Path]:
    """:func:`write_all` without the failed figures; returns the paths written."""
    return write_all(document, directory)[0]


def write_all(
    document: dict[str, Any], directory: str | os.PathLike[str]
) -> tuple[list[Path], dict[str, str]]:
    """Writes results.csv and results.json first, then the figures and report.md, into the
    existing folder ``directory``. Returns the paths written and the figures that could
    not be drawn (name → error): such a figure is reported in report.md and does not stop
    the rest, since the results are what the computation bought."""
    from prrrp.cli.common import json_default

    directory = Path(directory)
    rows = document["rows"]
    paths = [directory / "results.csv", directory / "results.json"]
    paths[0].write_text(to_csv(rows), encoding="utf-8")
    with paths[1].open("w", encoding="utf-8") as f:
        json.dump(document, f, indent=1, default=json_default)
        f.write("\n")
    figures = []
    failed: dict[str, str] = {}
    if any(r["status"] == "ok" for r in rows):
        for name, writer in (
            ("errors_by_noise.png", errors_by_noise),
            ("errors_vs_rate.png", errors_vs_rate),
            ("time_per_method.png", time_per_method),
        ):
            try:
                writer(rows, directory / name)
            except Exception as e:  # a figure is not worth the results
                text = str(e).strip().splitlines()
                failed[name] = f"{type(e).__name__}: {text[0]}" if text else type(e).__name__
                with contextlib.suppress(OSError):
                    (directory / name).unlink()
            else:
                figures.append(name)
    (directory / "report.md").write_text(render(document, figures, failed), encoding="utf-8")
    return [*paths, directory / "report.md", *(directory / f for f in figures)], failed
