"""Monte-Carlo benchmark of the estimators: which method to trust for a robot, a sensor
noise and a sampling rate (the protocol of BIRDy: many noise realisations × methods,
parameter and torque errors, time).

``prrrp.benchmark(...)`` (:func:`benchmark`, re-exported at the top level) runs a grid of
cases, each seed × noise scale × sampling rate: excitation → closed-loop simulation →
sensor noise → preprocessing → ``prrrp.identify`` with each method → torque prediction on a
second trajectory. The cases run on every core by default, or on any
``concurrent.futures.Executor`` (a Dask cluster: ``pip install prrrp[cluster]``, then
``executor=distributed.Client(address)``).

>>> result = prrrp.benchmark(seeds=4, noise=[1, 3], rates=[50, 100])   # doctest: +SKIP
>>> result.save("bench-out")        # results.csv, results.json, report.md, figures
...                                                                     # doctest: +SKIP

Modules: :mod:`~prrrp.montecarlo.cases` (the grid, one case),
:mod:`~prrrp.montecarlo.runner` (executors, streaming, retries, timeouts),
:mod:`~prrrp.montecarlo.report` (CSV, JSON, report.md, figures).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from prrrp.montecarlo.cases import (
    COLUMNS,
    DEFAULT_METHODS,
    METHODS,
    Case,
    converged,
    grid,
    run_case,
)
from prrrp.montecarlo.runner import DEFAULT_TIMEOUT, RunStats, WorkerStartError, run_cases

__all__ = [
    "COLUMNS",
    "DEFAULT_METHODS",
    "METHODS",
    "BenchmarkResult",
    "Case",
    "WorkerStartError",
    "benchmark",
    "converged",
    "grid",
    "run_case",
    "run_cases",
]


@dataclasses.dataclass
class BenchmarkResult:
    """What :func:`benchmark` returns: one row per case × method (keys
    :data:`COLUMNS`, in grid order), the configuration and how the run went."""

    rows: list[dict[str, Any]]
    config: dict[str, Any]
    stats: RunStats
    #: Figures the last :meth:`save` could not draw (name → error); the results were
    #: written all the same.
    figure_errors: dict[str, str] = dataclasses.field(default_factory=dict)

    def summary(self) -> list[dict[str, Any]]:
        """Per method × noise × rate: medians and 90th percentiles of the errors."""
        from prrrp.montecarlo import report

        return report.summary(self.rows)

    def to_dict(self) -> dict[str, Any]:
        """The results.json document."""
        from prrrp.montecarlo import report

        stats = dataclasses.asdict(self.stats)
        stats["cases_per_second"] = self.stats.cases_per_second
        return {
            "schema": report.SCHEMA,
            "config": self.config,
            "stats": stats,
            "summary": self.summary(),
            "rows": self.rows,
        }

    def save(self, directory: str | os.PathLike[str]) -> list[Path]:
        """Writes results.csv, results.json, report.md and the figures into ``directory``,
        built aside and swapped in whole (an existing folder must be empty or an earlier
        prrrp output). Returns the written paths. A figure that cannot be drawn is named
        in report.md and in :attr:`figure_errors`; the rest is written all the same."""
        from prrrp import outdir
        from prrrp.montecarlo import report

        document = self.to_dict()
        target = outdir.resolve(directory)

        def build(tmp: Path) -> list[Path]:
            paths, self.figure_errors = report.write_all(document, tmp)
            return [target / p.relative_to(tmp) for p in paths]

        return outdir.write_dir(directory, build)

    def save_results(self, path: str | os.PathLike[str]) -> Path:
        """Writes results.json alone to ``path`` (atomically): the rescue when the output
        folder cannot be written."""
        from prrrp import csvio
        from prrrp.cli.common import json_default

        text = json.dumps(self.to_dict(), indent=1, default=json_default) + "\n"
        csvio.write_text_atomic(path, text)
        return Path(path)


def _robot(robot: Any, base: str | None, tip: str | None) -> tuple[str | None, str]:
    """(robot_json, name) of the simulated robot: None for the paper's arm."""
    import prrrp

    if robot is None or (isinstance(robot, str) and robot == "paper"):
        return None, "PRRRP (Urrea & Pascal 2017)"
    if isinstance(robot, prrrp.Robot):
        if robot != prrrp.Robot.paper():
            raise prrrp.InvalidInputError(
                "a benchmark of a modified paper arm is not supported; give a SerialChain"
            )
        return None, "PRRRP (Urrea & Pascal 2017)"
    if isinstance(robot, str | os.PathLike):
        robot = prrrp.load_robot(robot, base=base, tip=tip)
    elif base is not None or tip is not None:
        raise prrrp.InvalidInputError("base and tip apply to a robot file, not a SerialChain")
    if not isinstance(robot, prrrp.SerialChain):
        raise prrrp.InvalidInputError(
            f"robot must be None (the paper's arm), a robot file or a SerialChain, "
            f"got {type(robot).__name__}"
        )
    return robot.to_json(), f"{robot.name} ({robot.dof} joints)"


def benchmark(
    robot: Any = None,
    methods: Any = DEFAULT_METHODS,
    noise: Any = (1.0,),
    rates: Any = (50.0,),
    seeds: Any = 10,
    executor: Any = None,
    *,
    workers: int | None = None,
    timeout: float = DEFAULT_TIMEOUT,
    retries: int = 1,
    duration: float = 10.0,
    excitation_evaluations: Any = 300,
    base: str | None = None,
    tip: str | None = None,
    progress: bool | Callable[[int, int, int], object] | None = None,
) -> BenchmarkResult:
    """Monte-Carlo benchmark of identification methods on a simulated robot.

    ``robot``: None (the paper's arm), a ``.urdf``/``.toml`` path (``base``/``tip`` pick a
    URDF's chain) or a ``SerialChain`` (its inertials and friction are the truth).
    ``methods``: names of ``prrrp.identify`` methods (list or "ls,rls"). ``noise``: scales
    of the default sensor noise (paper's arm: 1e-5 m / 1e-4 rad on positions, 0.5 N, 0.03,
    0.015, 0.007 N·m, 0.05 N on the forces; other robots: 1e-4 rad or m, 0.05 N·m or N).
    ``rates``: sampling rates (Hz). ``seeds``: a count N (0..N−1) or a list of seeds.
    Each case simulates ``duration`` s of excitation, designed by an optimiser with a
    budget of ``excitation_evaluations`` cost evaluations (one number, or several to
    compare: the report then gives the errors per budget).

    Execution: ``executor`` None runs a process pool of ``workers`` (default every core);
    otherwise any ``concurrent.futures.Executor`` or a ``distributed.Client``. Results are
    the same whatever the engine and worker count (every random stream derives from the
    case's seed). ``timeout``: seconds per case; a case whose worker dies or times out is
    retried ``retries`` times, then recorded with ``status="failed"``. ``progress``: a bar
    on stderr (default when it is a terminal), False, or ``progress(done, total,
    failed)``.

    Raises InvalidInputError for unknown methods, an empty grid, bad values, or an
    executor given that cannot run a task; :class:`WorkerStartError` (a PrrrpError and
    RuntimeError, its message whole) when the own process pool cannot start. On a process
    pool the calling script needs the usual ``if __name__ == "__main__":`` guard."""
    robot_json, robot_name = _robot(robot, base, tip)
    cases = grid(
        methods,
        noise,
        rates,
        seeds,
        robot_json=robot_json,
        duration=duration,
        excitation_evaluations=excitation_evaluations,
    )
    rows, stats = run_cases(
        cases, executor, workers=workers, timeout=timeout, retries=retries, progress=progress
    )
    first = cases[0]
    config = {
        "robot": robot_name,
        "methods": list(first.methods),
        "noise": sorted({c.noise for c in cases}),
        "rates": sorted({c.rate for c in cases}),
        "seeds": sorted({c.seed for c in cases}),
        "duration": first.duration,
        "excitation_evaluations": sorted({c.excitation_evaluations for c in cases}),
        "timeout_s": timeout,
        "retries": retries,
    }
    return BenchmarkResult(rows, config, stats)
