"""Runs the cases of a benchmark on any ``concurrent.futures.Executor``.

By default a process pool of ``os.cpu_count()`` workers (``forkserver`` start method: no
fork of a process that runs threads) that the runner owns; any other executor works the
same way: a ``ProcessPoolExecutor`` of your own, Dask's ``client.get_executor()`` (or the
``distributed.Client`` itself), Ray's or others.

What the runner guarantees:

- **Streaming**: at most one case per worker is in flight; results are collected as they
  finish (``concurrent.futures.wait``), with a progress bar on stderr.
- **Per-case timeout**, counted from the case's submission (a worker takes it at once,
  since no more cases than workers are in flight): a case over time is abandoned and
  counts as a failed attempt. In the runner's own pool the stuck worker is killed and the
  pool restarted; the other cases in flight are resubmitted without penalty.
- **A worker that dies loses only its case.** An engine that names the failed task (Dask:
  ``KilledWorker``; any exception) charges that case one attempt. A process pool that
  breaks cannot say which of its cases killed it: they are all rerun one at a time, so a
  second death is attributed to the case that caused it. A case is retried ``retries``
  times (default once) and then recorded as failed (``status="failed"`` and the error).
- **Never a hang**: every wait is bounded by the earliest deadline in flight.
- **Ctrl-C** (or any exception in the caller) cancels what is in flight, kills the owned
  pool's workers and re-raises.
"""

from __future__ import annotations

import collections
import concurrent.futures as cf
import contextlib
import dataclasses
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

from prrrp._prrrp import PrrrpError

# DEFAULT_TIMEOUT (per case, s) is defined beside prrrp.benchmark, which is imported without
# this module.
from prrrp.montecarlo import DEFAULT_TIMEOUT
from prrrp.montecarlo.cases import Case, failed_rows, ping, run_case

#: How long the executor may take to run its first task, s.
DEFAULT_START_TIMEOUT = 120.0


@dataclasses.dataclass
class RunStats:
    """How a run went: wall time (s), parallelism (cases in flight), the engine's name,
    the cases that failed for good, the retries made and the worker-pool restarts."""

    elapsed_s: float
    parallelism: int
    engine: str
    cases: int
    failed_cases: int
    retries: int
    restarts: int

    @property
    def cases_per_second(self) -> float:
        return self.cases / self.elapsed_s if self.elapsed_s > 0 else float("nan")


def _invalid(message: str) -> Exception:
    from prrrp import InvalidInputError

    return InvalidInputError(message)


class _Engine:
    """The executor, and for the runner's own pool the means to kill and restart it."""

    def __init__(self, executor: Any, workers: int | None, cases: int) -> None:
        self.owned = executor is None
        if self.owned:
            count = (os.cpu_count() or 1) if workers is None else workers
            if not (isinstance(count, int) and count >= 1):
                raise _invalid(f"workers must be a positive integer, got {workers!r}")
            # No more cases than workers are in flight: a larger pool would only be recorded
            # (100000 workers read in results.json for a 12-case grid).
            count = min(count, cases)
            self.workers = count
            self.executor: Any = self._new_pool()
            self.name = f"process pool ({count} workers)"
        else:
            if workers is not None:
                raise _invalid("give either an executor or a worker count, not both")
            if not isinstance(executor, cf.Executor) and hasattr(executor, "get_executor"):
                executor = executor.get_executor()  # a dask.distributed.Client
            if not callable(getattr(executor, "submit", None)):
                raise _invalid(
                    f"{type(executor).__name__} is not a concurrent.futures.Executor "
                    "(it has no submit method)"
                )
            self.executor = executor
            self.workers = _parallelism(executor)
            self.name = type(executor).__name__
        self.restarts = 0

    def _new_pool(self) -> cf.ProcessPoolExecutor:
        try:
            context = multiprocessing.get_context("forkserver")
        except ValueError:  # platforms without forkserver
            context = multiprocessing.get_context("spawn")
        return cf.ProcessPoolExecutor(self.workers, mp_context=context)

    def submit(self, case: Case) -> cf.Future:
        return self.executor.submit(run_case, case)

    def kill(self) -> None:
        """Stops the owned pool at once (its workers may be stuck in a case)."""
        if not self.owned:
            return
        processes = getattr(self.executor, "_processes", None) or {}
        for process in list(processes.values()):
            with contextlib.suppress(OSError, AttributeError):
                process.kill()
        self.executor.shutdown(wait=False, cancel_futures=True)

    def restart(self) -> None:
        self.kill()
        self.executor = self._new_pool()
        self.restarts += 1

    def close(self) -> None:
        if self.owned:
            self.executor.shutdown(wait=True)


def _parallelism(executor: Any) -> int:
    """How many tasks the executor runs at once, as far as it says."""
    count = getattr(executor, "_max_workers", None)
    client = getattr(executor, "_client", None)
    if count is None and client is not None and hasattr(client, "nthreads"):
        try:
            count = sum(client.nthreads().values())
        except Exception:
            count = None
    return int(count) if count else (os.cpu_count() or 1)


class _Bar:
    """A progress bar on stderr (tqdm), or a callback ``progress(done, total, failed)``."""

    def __init__(self, progress: bool | Callable[[int, int, int], object] | None, total: int):
        self.callback = progress if callable(progress) else None
        enabled = sys.stderr.isatty() if progress is None else progress is True
        self.bar: Any = None
        if enabled and self.callback is None:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="benchmark", unit="case", file=sys.stderr)
        self.total = total

    def update(self, done: int, failed: int) -> None:
        if self.callback is not None:
            self.callback(done, self.total, failed)
        if self.bar is not None:
            self.bar.n = done
            self.bar.set_postfix(failed=failed, refresh=False)
            self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


class WorkerStartError(PrrrpError, RuntimeError):
    """The benchmark's own process pool could not start its workers: not bad input but
    the environment (a script without the ``if __name__ == "__main__":`` guard, a sandbox
    that forbids processes, no memory). The message is whole."""


_MAIN_GUARD_HINT = (
    "Each worker process starts by importing the calling script (Python's forkserver and "
    "spawn start methods), so a script that calls prrrp.benchmark at its top level starts "
    'the benchmark again in every worker: put the call under `if __name__ == "__main__":`.'
)


def _check_started(engine: _Engine, start_timeout: float) -> None:
    try:
        engine.executor.submit(ping).result(timeout=start_timeout)
    except cf.TimeoutError:
        raise _invalid(
            f"the executor {engine.name} ran no task within {start_timeout:g} s "
            "(no workers? check the cluster)"
        ) from None
    except Exception as e:
        if not engine.owned:
            raise _invalid(f"the executor {engine.name} failed to start: {_describe(e)}") from e
        main = sys.modules.get("__main__")
        script = getattr(main, "__file__", None)
        hint = f" {_MAIN_GUARD_HINT}" if script else ""
        whole = f"{type(e).__name__}: {str(e).strip()}" if str(e).strip() else type(e).__name__
        raise WorkerStartError(
            f"the {engine.name} could not start its workers ({whole}).{hint} The workers' "
            "own error, if any, is printed above on stderr."
        ) from e


def _describe(e: BaseException) -> str:
    lines = str(e).strip().splitlines()
    name = type(e).__name__
    return f"{name}: {lines[0]}" if lines else name


def run_cases(
    cases: Sequence[Case],
    executor: Any = None,
    *,
    workers: int | None = None,
    timeout: float = DEFAULT_TIMEOUT,
    retries: int = 1,
    progress: bool | Callable[[int, int, int], object] | None = None,
    start_timeout: float = DEFAULT_START_TIMEOUT,
) -> tuple[list[dict[str, Any]], RunStats]:
    """Runs ``cases`` on ``executor`` (default: an own process pool of ``workers``, default
    every core) and returns their rows, in the order of ``cases`` whatever the order of
    completion, and the run's statistics. ``timeout``: seconds per case; ``retries``:
    reruns of a case whose worker died or that timed out; ``progress``: None (a bar when
    stderr is a terminal), True, False or ``progress(done, total, failed)``. Raises
    InvalidInputError if the executor cannot run a first task within ``start_timeout``
    s."""
    if not cases:
        raise _invalid("empty grid: no cases to run")
    if len({case.key for case in cases}) != len(cases):
        raise _invalid("the grid repeats a case (same seed, noise, rate and excitation budget)")
    if not (timeout > 0):
        raise _invalid(f"timeout must be a positive number of seconds, got {timeout}")
    if not (isinstance(retries, int) and retries >= 0):
        raise _invalid(f"retries must be an integer >= 0, got {retries!r}")
    t0 = time.perf_counter()
    engine = _Engine(executor, workers, len(cases))
    bar: _Bar | None = None
    inflight: dict[cf.Future, tuple[Case, float]] = {}
    try:
        _check_started(engine, start_timeout)
        bar = _Bar(progress, len(cases))
        results: dict[tuple[int, float, float, int], list[dict[str, Any]]] = {}
        fresh = collections.deque(cases)
        isolated: collections.deque[Case] = collections.deque()  # run one at a time
        retried = 0
        failed = 0

        def finish(case: Case, rows: list[dict[str, Any]]) -> None:
            nonlocal failed
            results[case.key] = rows
            failed += all(r["status"] == "failed" for r in rows)
            bar.update(len(results), failed)

        def attempt_failed(case: Case, error: str) -> None:
            nonlocal retried
            if case.attempt < retries:
                retried += 1
                isolated.append(dataclasses.replace(case, attempt=case.attempt + 1))
            else:
                finish(case, failed_rows(case, error))

        def submit(case: Case) -> None:
            try:
                inflight[engine.submit(case)] = (case, time.monotonic() + timeout)
            except Exception as e:  # a broken or shut-down executor
                attempt_failed(case, f"the executor refused the case: {_describe(e)}")

        while fresh or isolated or inflight:
            if isolated:
                if not inflight:
                    submit(isolated.popleft())
            else:
                while fresh and len(inflight) < engine.workers:
                    submit(fresh.popleft())
            if not inflight:
                continue
            wait = max(0.0, min(d for _, d in inflight.values()) - time.monotonic())
            done, _ = cf.wait(list(inflight), timeout=min(wait, 1.0), return_when="FIRST_COMPLETED")
            broken = []
            for future in done:
                case, _ = inflight.pop(future)
                try:
                    rows = future.result()
                except cf.process.BrokenProcessPool:
                    broken.append(case)
                except cf.CancelledError:
                    attempt_failed(case, "cancelled by the executor")
                except Exception as e:  # KilledWorker, a worker-side error, ...
                    attempt_failed(case, f"worker failed: {_describe(e)}")
                else:
                    finish(case, rows)
            now = time.monotonic()
            late = [f for f, (_, deadline) in inflight.items() if now >= deadline]
            for future in late:
                case, _ = inflight.pop(future)
                future.cancel()
                attempt_failed(case, f"timed out after {timeout:g} s")
            if broken:
                # The pool broke: every case in it got the same error, and which one
                # killed its worker is unknown unless it ran alone.
                broken += [case for case, _ in inflight.values()]
                inflight.clear()
                if len(broken) == 1:
                    attempt_failed(broken[0], "worker process died (BrokenProcessPool)")
                else:
                    isolated.extend(broken)
                if engine.owned:
                    engine.restart()
            elif late and engine.owned:
                # A stuck worker holds its process: restart the pool; the other cases in
                # flight lose nothing.
                fresh.extendleft(reversed([case for case, _ in inflight.values()]))
                inflight.clear()
                engine.restart()
        rows = [row for case in cases for row in results[case.key]]
        stats = RunStats(
            elapsed_s=time.perf_counter() - t0,
            parallelism=engine.workers,
            engine=engine.name,
            cases=len(cases),
            failed_cases=failed,
            retries=retried,
            restarts=engine.restarts,
        )
        engine.close()
        return rows, stats
    except BaseException:
        for future in inflight:
            future.cancel()
        engine.kill()
        raise
    finally:
        if bar is not None:
            bar.close()
