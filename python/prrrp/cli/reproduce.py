"""``prrrp reproduce``: the paper's whole study into a folder of results, report and figures."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import prrrp
from prrrp.cli import common

#: ``prrrp reproduce --help``.
HELP = "run the paper's whole study: tables, figures, results.json"
DESCRIPTION = (
    "Runs the paper's study (excitation optimisation, closed-loop simulation, "
    "least squares, Adaline, Hopfield, EKF, validation, sensitivity) and writes "
    "results.json, report.md and PNG figures into DIR. DIR is built aside and swapped "
    "in whole when the run succeeds; a failed or interrupted run leaves it as it was. "
    "An existing DIR must be empty or an earlier prrrp output."
)


def add_parser(sub: Any) -> None:
    p = common.add_command(sub, "reproduce", run, help=HELP, description=DESCRIPTION)
    common.add_out_argument(p, help="output directory (default: ./prrrp-out)", default="prrrp-out")
    p.add_argument("--seed", type=common.seed, default=0, help="random seed (default: 0)")


def run(args: argparse.Namespace) -> int:
    from prrrp import drawing, outdir, plots, report

    if not hasattr(prrrp, "run_study"):
        raise common.CliError(
            "this build of prrrp has no run_study (reinstall the package)", common.EXIT_FAILED
        )
    out = Path(args.out)
    progress = common.Progress()

    # The folder is built aside and swapped in whole (outdir.write_dir): a failed or
    # interrupted run leaves the previous results exactly as they were.
    def build(tmp: Path) -> tuple[dict[str, Any], list[Path]]:
        try:
            results = prrrp.run_study(seed=args.seed, progress=progress)
        finally:
            progress.close()
        common.dump_json(results, tmp / "results.json")
        (tmp / "report.md").write_text(report.render(results), encoding="utf-8")
        return results, plots.write_all(results, tmp)

    # matplotlib's import runs while the study (which releases the GIL) computes; the
    # figures wait for it, an interrupted or failed run does not.
    drawing.preload()
    results, figures = outdir.write_dir(out, build)
    total = (results.get("timings_s") or {}).get("total")
    took = f" ({total:.1f} s)" if isinstance(total, int | float) else ""
    print(f"results in {out}/report.md, {out}/results.json and {len(figures)} figures{took}")
    return common.EXIT_OK
