"""The Markdown report of ``prrrp reproduce``: the paper's Tables 4, 5 and 6 side by side with
the study's values and the truth, torque-prediction errors, relative parameter errors and
stage timings. Input is the study result dict (``prrrp.run_study``, schema_version 1).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

from prrrp import paper


def _f(x: Any, digits: int = 4) -> str:
    if x is None:
        return "—"
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    if x != 0 and (abs(x) < 10 ** (-digits) or abs(x) >= 1e6):
        return f"{x:.{max(digits - 1, 1)}e}"
    return f"{x:.{digits}f}"


def _g(x: Any) -> str:
    return "—" if x is None else f"{float(x):.3g}"


def _table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out.extend("| " + " | ".join(row) + " |" for row in rows)
    return [*out, ""]


def _label(method: str) -> str:
    return paper.METHOD_LABELS.get(method, method)


def _rel(est: float, truth: float) -> float:
    return 100.0 * (est - truth) / truth


def table4(results: dict[str, Any]) -> list[str]:
    """λ per method: the paper's value and ours, with the truth."""
    truth = results["truth"]
    estimates = results["estimates"]
    header = ["λ", "unit", "truth"]
    for e in estimates:
        name = _label(e["method"])
        header += [f"{name} (paper)", f"{name} (ours)"]
    rows = []
    for i in range(len(truth)):
        row = [f"λ{i + 1}", paper.PARAMETER_UNITS[i], _f(truth[i])]
        for e in estimates:
            published = paper.TABLE4.get(e["method"])
            row += [_f(published[i]) if published else "—", _f(e["lambda"][i])]
        rows.append(row)
    return _table(header, rows)


def relative_errors(results: dict[str, Any]) -> list[str]:
    """Relative error of each λ_i against the truth, %, ours and the paper's."""
    truth = results["truth"]
    estimates = results["estimates"]
    header = ["λ"]
    for e in estimates:
        name = _label(e["method"])
        header += [f"{name} paper %", f"{name} ours %"]
    rows = []
    for i in range(len(truth)):
        row = [f"λ{i + 1}"]
        for e in estimates:
            published = paper.TABLE4.get(e["method"])
            ours = e.get("relative_error_percent")
            ours_i = ours[i] if ours else _rel(e["lambda"][i], truth[i])
            row += [_f(_rel(published[i], truth[i]), 2) if published else "—", _f(ours_i, 2)]
        rows.append(row)
    worst = ["max abs"]
    for e in estimates:
        published = paper.TABLE4.get(e["method"])
        ours = e.get("relative_error_percent") or [
            _rel(x, t) for x, t in zip(e["lambda"], truth, strict=True)
        ]
        pub = (
            max(abs(_rel(p, t)) for p, t in zip(published, truth, strict=True))
            if published
            else None
        )
        worst += [_f(pub, 2), _f(max(abs(x) for x in ours), 2)]
    rows.append(worst)
    return _table(header, rows)


def least_squares_statistics(results: dict[str, Any]) -> list[str]:
    """σ and %σ of the least-squares estimate, cond(W_b) and the residual variance: the
    estimate is of the chain's base parameters β (``base_names``), λ and σ its paper view."""
    ls = next((e for e in results["estimates"] if e["method"] == "least_squares"), None)
    if ls is None or ls.get("std") is None:
        return []
    rows = [
        [f"λ{i + 1}", _f(ls["lambda"][i]), _f(ls["std"][i], 6), _f(ls["rsd_percent"][i], 3)]
        for i in range(len(ls["lambda"]))
    ]
    lines = _table(["λ", "estimate", "σ", "%σ"], rows)
    names = results.get("base_names") or []
    of = f" (regressor of the {len(names)} base parameters {', '.join(names)})" if names else ""
    lines += [
        f"cond(W_b) = {_g(ls.get('cond'))}{of}, residual variance σ² = {_g(ls.get('sigma2'))}",
        "",
    ]
    return lines


def table5(results: dict[str, Any]) -> list[str]:
    """Validation indices per method and joint (RMS, RSD, AI) against the paper's bounds."""
    methods = results["validation"]["methods"]
    header = ["method", "index", *paper.JOINTS]
    rows = []
    for m in methods:
        for key, name in (("rms", "RMS"), ("rsd", "RSD"), ("ai", "AI")):
            rows.append([_label(m["method"]), name, *(_g(x) for x in m[key])])
    lines = _table(header, rows)
    lines += [
        f"Paper (Table 5): every RMS ≤ {paper.TABLE5_MAX_RMS}, every RSD ≤ "
        f"{paper.TABLE5_MAX_RSD}, every AI ≥ {paper.TABLE5_MIN_AI}. RMS is in the joint's "
        "position unit (m or rad).",
        "",
    ]
    return lines


def torque_prediction(results: dict[str, Any]) -> list[str]:
    """Torque-prediction error on the validation trajectory, per method and joint."""
    methods = results["validation"]["methods"]
    header = [
        "method",
        *(f"{j} RMS ({u})" for j, u in zip(paper.FORCES, paper.FORCE_UNITS, strict=True)),
    ]
    rows = [[_label(m["method"]), *(_g(x) for x in m["torque_rms"])] for m in methods]
    lines = _table(header, rows)
    header = ["method", *(f"{j} %" for j in paper.FORCES)]
    rows = [
        [_label(m["method"]), *(_f(x, 2) for x in m["torque_relative_percent"])] for m in methods
    ]
    return lines + _table(header, rows)


def table6(results: dict[str, Any]) -> list[str]:
    """Sensitivity: the range swept per λ_i (ours and the paper's) and the worst position RMS."""
    sens = results["sensitivity"]
    factors = sens["factors"]
    header = ["λ", "paper min", "paper max", "ours min", "ours max", "worst RMS", "at factor"]
    rows = []
    for i, (lo, hi) in enumerate(sens["ranges"]):
        worst, at = None, None
        for k, per_joint in enumerate(sens["rms"][i]):
            if per_joint is None:
                continue
            vals = [x for x in per_joint if x is not None]
            if vals and (worst is None or max(vals) > worst):
                worst, at = max(vals), factors[k]
        plo, phi = paper.TABLE6_RANGES[i] if i < len(paper.TABLE6_RANGES) else (None, None)
        rows.append([f"λ{i + 1}", _f(plo), _f(phi), _f(lo), _f(hi), _g(worst), _g(at)])
    lines = _table(header, rows)
    lines += [
        f"Factors swept: {', '.join(_g(f) for f in factors)} × truth. Worst RMS: the largest "
        "position RMS over joints (m or rad) of the trajectory simulated with the varied λ_i "
        "against the true one; non-physical variations (M not positive definite) are skipped.",
        "",
    ]
    return lines


def timings(results: dict[str, Any]) -> list[str]:
    """Wall time of each stage of the study, s."""
    t = results.get("timings_s") or {}
    rows = [[stage, f"{float(s):.3f}"] for stage, s in t.items() if stage != "total"]
    lines = _table(["stage", "time (s)"], rows)
    if "total" in t:
        stages = {k: v for k, v in t.items() if k != "total"}
        slowest = max(stages, key=lambda k: stages[k]) if stages else "—"
        lines += [f"Total {float(t['total']):.2f} s; slowest stage: {slowest}.", ""]
    return lines


def render(results: dict[str, Any]) -> str:
    """The whole report as Markdown."""
    ex = results.get("excitation", {})
    lines = [
        "# prrrp: reproduction of Urrea & Pascal 2017",
        "",
        f"Seed {results.get('seed', '—')}, study schema version "
        f"{results.get('schema_version', '—')}. All values SI (kg, m, rad, s, N, N·m).",
        "",
        "## Excitation trajectory (eqs. 37–39)",
        "",
        f"cond(W) of the observation matrix: {_g(ex.get('cond_initial'))} before optimisation, "
        f"{_g(ex.get('cond_final'))} after ({ex.get('evaluations', '—')} evaluations; joint "
        f"limits {'satisfied' if ex.get('limits_satisfied') else 'NOT satisfied'}). "
        f"{ex.get('samples', '—')} samples over {_g(ex.get('duration'))} s.",
        "",
        "## Table 4: estimated parameters",
        "",
        *table4(results),
        "Initial guess of the iterative estimators: "
        + ", ".join(_f(x) for x in results.get("initial_guess", [])),
        "",
        "### Relative parameter errors against the truth",
        "",
        *relative_errors(results),
        "### Least squares: standard deviations",
        "",
        *least_squares_statistics(results),
        "## Table 5: validation (positions simulated with each estimate vs the true robot)",
        "",
        *table5(results),
        "### Torque prediction on the validation trajectory",
        "",
        "RMS error of the torques predicted with each estimate on the validation trajectory, "
        "per joint (`torque_rms`), and relative, % (`torque_relative_percent`).",
        "",
        *torque_prediction(results),
        "## Table 6: sensitivity",
        "",
        *table6(results),
        "## Stage timings",
        "",
        *timings(results),
    ]
    return "\n".join(lines).rstrip() + "\n"
