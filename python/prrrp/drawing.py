"""What every figure of prrrp shares: a figure of panels laid out once with fixed margins,
traces reduced to what the saved image can show, and the PNG writer.

The report figures of ``prrrp identify`` are :class:`prrrp.canvas.Figure` objects, drawn
natively without matplotlib (:func:`save` takes both kinds); the study figures of
:mod:`prrrp.plots` are matplotlib's, made here.

matplotlib is imported here only when a figure is made (it costs more than the rest of a
``prrrp identify`` run on a small log); :func:`preload` imports it on a background thread
while the caller computes. Figures are ``matplotlib.figure.Figure`` objects on their own
Agg canvas, never pyplot's global state, so nothing is left open between figures.

A line of S samples drawn into P pixel columns (S ≫ P) shows, per column, only the span
from its smallest to its largest value: :func:`envelope` keeps those two samples per
column (in time order), so every column spans the same pixels as with all the samples.
A cloud of points shows which pixels are covered: :func:`thin_points` keeps one point per
covered pixel cell.
Layout is fixed in inches (room for tick labels, axis labels and titles) instead of
measured by ``tight_layout``, which draws every text twice to find its size.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import os
import signal
import sys
import threading
import zlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, NoReturn

import numpy as np

#: Resolution of the saved PNGs, dots per inch.
DPI = 100

#: Distance of an x-axis label's centre below its panel, and of a y-axis label's centre
#: left of it, inches: clear of 8-point tick labels (up to 6 characters wide).
LABEL_X_DROP = 0.32
LABEL_Y_OFFSET = 0.55
#: The default panel (width, height) and margins of :func:`figure`, inches: left, right,
#: top, bottom and the space between panels. :func:`prrrp.canvas.figure` lays out the
#: native figures with the same defaults.
PANEL = (3.6, 1.9)
LEFT, RIGHT, TOP, BOTTOM = 0.8, 0.2, 0.45, 0.55
WSPACE = HSPACE = 0.85

_preload: threading.Thread | None = None


def _import() -> None:
    # Agg canvases directly: pyplot's backend (a notebook's, a user's) is left alone.
    for name in ("matplotlib.figure", "matplotlib.backends.backend_agg"):
        importlib.import_module(name)


def _warm() -> None:
    """Draws and encodes a small figure: what a process's first figure pays once (loading
    the font, the PNG writer's plugins, matplotlib's caches), paid here instead — and
    inherited by the workers of :func:`draw_all`, which would each pay it again."""
    import io

    with contextlib.suppress(Exception):  # only a head start: drawing proper says what fails
        fig, axes = figure(1, 1, panel=(1.0, 0.8), wait=False)
        ax = axes[0, 0]
        ax.plot([0.0, 1.0], [0.0, 1.0], ".-", label="a")
        ax.set_title("torque", fontsize=9)
        ax.set_xlabel("time (s)", fontsize=8)
        ax.legend(fontsize=7)
        save(fig, io.BytesIO())


def _preload_and_warm() -> None:
    _import()
    _warm()


def preload() -> None:
    """Starts importing matplotlib (and drawing a first figure, :func:`_warm`) on a daemon
    thread (once), for a caller that will draw after a computation that releases the GIL;
    :func:`figure` waits for it."""
    global _preload
    if _preload is None:
        _preload = threading.Thread(
            target=_preload_and_warm, name="prrrp-import-matplotlib", daemon=True
        )
        _preload.start()


def wait_preload() -> None:
    """Joins the :func:`preload` thread, if any: :func:`figure` does before drawing. A
    caller that stops early does not wait (the thread is a daemon)."""
    if _preload is not None:
        _preload.join()


def figure(
    rows: int,
    cols: int,
    *,
    panel: tuple[float, float] = PANEL,
    left: float = LEFT,
    right: float = RIGHT,
    top: float = TOP,
    bottom: float = BOTTOM,
    wspace: float = WSPACE,
    hspace: float = HSPACE,
    sharex: bool = False,
    label_offset: float | None = None,
    wait: bool = True,
) -> tuple[Any, np.ndarray]:
    """A figure of ``rows`` × ``cols`` panels of ``panel`` = (width, height) inches each,
    with fixed margins in inches: ``left`` (y tick labels and label), ``bottom`` (x tick
    labels and label), ``top`` (titles), ``wspace`` and ``hspace`` between panels. Returns
    (figure, axes array of shape (rows, cols)); ``wait=False``: without waiting for
    :func:`preload` (its own drawing)."""
    if wait:
        wait_preload()
    _import()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pw, ph = panel
    width, height = grid_size(rows, cols, panel, (left, right, top, bottom), (wspace, hspace))
    fig = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(fig)
    axes = fig.subplots(
        rows,
        cols,
        squeeze=False,
        sharex=sharex,
        gridspec_kw={
            "left": left / width,
            "right": 1 - right / width,
            "bottom": bottom / height,
            "top": 1 - top / height,
            "wspace": wspace / pw,
            "hspace": hspace / ph,
        },
    )
    locator = _in_view_locator()
    for ax in axes.flat:
        ax.tick_params(which="both", labelsize=8)
        # Few ticks: each label is a text to lay out, and more crowd a small panel.
        ax.xaxis.set_major_locator(locator(nbins=4, steps=[1, 2, 2.5, 5, 10]))
        ax.yaxis.set_major_locator(locator(nbins=4, steps=[1, 2, 2.5, 5, 10]))
        # Titles and axis labels at fixed places in the margins: placed automatically,
        # each would be moved clear of the tick labels, measuring every one of them.
        ax.title.set_y(1.0)
        ax._autotitlepos = False
        ax.xaxis.set_label_coords(0.5, -LABEL_X_DROP / ph)
        offset = LABEL_Y_OFFSET if label_offset is None else label_offset
        ax.yaxis.set_label_coords(-offset / pw, 0.5)
    return fig, axes


def grid_size(
    rows: int,
    cols: int,
    panel: tuple[float, float],
    margins: tuple[float, float, float, float],
    space: tuple[float, float],
) -> tuple[float, float]:
    """(width, height), inches, of a figure of ``rows`` × ``cols`` panels of ``panel`` =
    (width, height) with ``margins`` = (left, right, top, bottom) and ``space`` = (wspace,
    hspace) between panels: the layout of :func:`figure` and :func:`prrrp.canvas.figure`."""
    (pw, ph), (left, right, top, bottom), (wspace, hspace) = panel, margins, space
    return (
        left + right + cols * pw + (cols - 1) * wspace,
        top + bottom + rows * ph + (rows - 1) * hspace,
    )


_InView: Any = None


def _in_view_locator() -> Any:
    """matplotlib's default tick locator (``AutoLocator``'s steps) giving only the ticks
    inside the view: matplotlib makes a tick object (lines and texts, the larger part of
    drawing an axis) for each location, also the two it then leaves out."""
    global _InView
    if _InView is None:
        from matplotlib.ticker import MaxNLocator

        class InView(MaxNLocator):  # type: ignore[misc]
            def __call__(self) -> Any:
                lo, hi = sorted(self.axis.get_view_interval())
                locs = np.asarray(super().__call__())
                slack = 1e-10 * (hi - lo)
                return locs[(locs >= lo - slack) & (locs <= hi + slack)]

        _InView = InView
    return _InView


def pixels(ax: Any) -> tuple[int, int]:
    """Width and height of ``ax``'s plotting area in pixels of the saved image."""
    fig = ax.figure
    w, h = fig.get_size_inches()
    box = ax.get_position()
    return max(int(np.ceil(box.width * w * DPI)), 1), max(int(np.ceil(box.height * h * DPI)), 1)


def envelope(x: np.ndarray, y: np.ndarray, columns: int) -> tuple[np.ndarray, np.ndarray]:
    """The samples of the line (x, y) that an image of ``columns`` pixel columns across
    [x[0], x[-1]] can show (x non-decreasing, length S; y of shape (S,), or (S, k) for k
    lines on the same x): in each column the samples with its smallest and its largest
    value (of every line), in time order, plus the first and last sample. Returns (x, y)
    with at most 2·k·columns + 2 rows; each column's min/max envelope equals the input's
    (NaN samples, which break a line, are kept only where a column has nothing else)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = len(x)
    k = 1 if y.ndim == 1 else y.shape[1]
    if n <= 2 * k * columns + 2:
        return x, y
    span = x[-1] - x[0]
    if not span > 0:
        return x, y
    col = np.minimum(((x - x[0]) / span * columns).astype(np.int64), columns - 1)
    # Runs of equal column (x non-decreasing). Each run's extremes by one reduceat (fmin and
    # fmax skip NaN), then the first sample of the run equal to it: O(S), where sorting
    # each line by (column, value) cost 15× more. An all-NaN run keeps its first sample.
    change = col[1:] != col[:-1]
    starts = np.flatnonzero(np.r_[True, change])
    run = np.cumsum(np.r_[False, change])
    keep = [np.array([0, n - 1])]
    for v in y.T if y.ndim == 2 else (y,):
        for reduce in (np.fmin, np.fmax):
            extreme = reduce.reduceat(v, starts)
            hit = np.flatnonzero(v == extreme[run])
            keep.append(hit[np.r_[True, run[hit[1:]] != run[hit[:-1]]]])
            keep.append(starts[np.isnan(extreme)])
    idx = np.unique(np.concatenate(keep))
    return x[idx], y[idx]


def lines(
    ax: Any, x: np.ndarray, ys: Sequence[np.ndarray] | np.ndarray, *args: Any, **kwargs: Any
) -> Any:
    """``ax.plot`` of the line (x, y) reduced to ``ax``'s pixel columns by :func:`envelope`."""
    px, py = envelope(x, np.asarray(ys), pixels(ax)[0])
    return ax.plot(px, py, *args, **kwargs)


def thin_points(
    x: np.ndarray, y: np.ndarray, size: tuple[int, int], margin: float = 0.05
) -> np.ndarray:
    """Indices of the points (x, y) to draw in a plotting area of ``size`` = (width,
    height) pixels spanning the data's range widened by ``margin`` (matplotlib's default
    margins): the first point in each covered pixel cell, plus the extreme points of
    each coordinate (which set the axis limits)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
    if len(ok) <= size[0] * size[1] // 4 or len(ok) < 4:
        return ok
    xs, ys = x[ok], y[ok]
    cells = []
    for v, pixels_ in ((xs, size[0]), (ys, size[1])):
        lo, hi = float(v.min()), float(v.max())
        pad = margin * (hi - lo) if hi > lo else 1.0
        cells.append(((v - lo + pad) / (hi - lo + 2 * pad) * pixels_).astype(np.int64))
    key = cells[0] * (size[1] + 2) + cells[1]
    first = np.unique(key, return_index=True)[1]
    extremes = [xs.argmin(), xs.argmax(), ys.argmin(), ys.argmax()]
    return ok[np.unique(np.concatenate((first, extremes)))]


#: PIL's PNG settings: zlib level 6 (PIL's default) costs more than drawing for a few
#: percent of size; run-length matching suits flat plots (a tenth faster than level 2,
#: and smaller).
PNG_OPTIONS = {"compress_level": 1, "compress_type": zlib.Z_RLE}


def save(fig: Any, path: str | os.PathLike[str] | Any) -> None:
    """Writes ``fig`` as a PNG at :data:`DPI` to ``path``, through a temporary file beside
    it that is renamed to ``path`` once complete: a failed or interrupted drawing leaves
    no half-written PNG (and an existing one as it was). ``path`` may be a binary file
    object (written directly). ``fig`` is a matplotlib figure or a
    :class:`prrrp.canvas.Figure` (drawn natively: no matplotlib)."""
    native = hasattr(fig, "png")

    def write(f: Any) -> None:
        if not native:
            fig.savefig(f, dpi=DPI, format="png", pil_kwargs=PNG_OPTIONS)
        elif isinstance(f, str | os.PathLike):
            with open(f, "wb") as out:
                out.write(fig.png())
        else:
            f.write(fig.png())

    if not isinstance(path, str | os.PathLike):
        write(path)
        return
    from prrrp import csvio

    csvio.write_atomic(path, write)


def job(name: str, draw: Callable[..., object], *args: Any) -> Callable[[], object]:
    """``draw(*args)`` as a call for :func:`draw_all` named ``name`` (in its messages):
    a ``functools.partial``, which pickles (with its name) when ``draw`` is a module-level
    function and ``args`` pickle, so that a :func:`figure_server` can draw it."""
    call = functools.partial(draw, *args)
    call.__name__ = name  # type: ignore[attr-defined]
    return call


def draw_all(
    drawings: Sequence[Callable[[], object]], workers: int | None = None
) -> list[tuple[int, str]]:
    """Runs the calls ``drawings`` (each draws and saves figures with :func:`save`), in
    forked worker processes, at most ``workers`` at a time (default: twice the CPUs this
    process may use, none when it may use one or none is idle), the last one in this
    process beside them, and returns when all have ended.

    A call that fails stops neither the others nor the caller: its error is said on stderr
    and returned as (index of the call, message), in the order of the calls — the results
    the figures illustrate are already written and must not be lost to a figure. Ctrl-C and
    SIGTERM end every worker (SIGTERM, then SIGKILL after :data:`STOP_GRACE_S`) and reap it
    before the exception leaves: no worker outlives the call (nor its process: they die with
    it) or writes after it, and a figure lands only whole.

    With a :func:`figure_server` running (and calls that pickle, and no ``workers``
    given), the calls are handed to it: it draws them the same way in its process and its
    workers, with matplotlib imported while this process computed.

    Without ``os.fork`` (not Linux), while another thread runs (a fork copies the locks it
    holds), or with one worker or one call, the calls run here one after another, with the
    same handling of errors."""
    jobs = list(drawings)
    server = _take_server()
    payload = _pickled(jobs) if server is not None and workers is None else None
    if server is not None and payload is None:
        _end_server(server)
    if server is not None and payload is not None:
        failures = _draw_on_server(server, payload, len(jobs))
    else:
        failures = _draw_jobs(jobs, workers)
    # Workers end in any order; the caller (and its messages) get the calls' order.
    failures = sorted(failures)
    for i, message in failures:
        name = getattr(jobs[i], "__name__", "")
        what = f"figure {name!r}" if name.isidentifier() else "a figure"
        print(f"prrrp: {what} was not drawn: {message}", file=sys.stderr)
    return failures


def _draw_jobs(jobs: list[Callable[[], object]], workers: int | None) -> list[tuple[int, str]]:
    """:func:`draw_all` in this process and its workers, without reporting the failures."""
    wait_preload()  # also a thread that runs
    if workers is None:
        workers = _default_workers()
    if sys.platform != "linux" or workers < 2 or len(jobs) < 2 or threading.active_count() > 1:
        return [f for f in (_draw_here(i, job) for i, job in enumerate(jobs)) if f]
    return _draw_forked(jobs, workers)


class _Server:
    """A forked process of :func:`figure_server`: its pid, the write end of the pipe that
    takes the pickled calls, the read end of the one that returns the failures."""

    def __init__(self, pid: int, jobs: int, results: int) -> None:
        self.pid, self.jobs, self.results = pid, jobs, results


_server: _Server | None = None


@contextlib.contextmanager
def figure_server() -> Iterator[bool]:
    """Forks, now, a process that imports matplotlib and draws a first figure
    (:func:`_warm`) while this one computes, and then waits for the calls of the next
    :func:`draw_all`: in a process of its own the import does not compete with the
    computation for the GIL, and uses a second CPU. Yields whether the process was started:
    only on Linux, from a process without other threads, with a CPU to spare
    (:func:`_default_workers` ≥ 2). On leaving, a process that was not used is ended
    (SIGTERM) and reaped, also on Ctrl-C or an error before the figures."""
    global _server
    started = _server is None and _start_server()
    try:
        yield started
    finally:
        if started:
            server = _take_server()
            if server is not None:
                _end_server(server)


def _take_server() -> _Server | None:
    global _server
    server, _server = _server, None
    return server


def _start_server() -> bool:
    global _server
    if sys.platform != "linux" or threading.active_count() > 1 or _default_workers() < 2:
        return False
    import warnings

    sys.stdout.flush()
    sys.stderr.flush()
    parent = os.getpid()
    jobs_read, jobs_write = os.pipe()
    results_read, results_write = os.pipe()
    # Blocked across the fork, as for the workers of _draw_forked.
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DeprecationWarning)
                pid = os.fork()
        except OSError:
            pid = -1
        if pid == 0:
            os.close(jobs_write)
            os.close(results_read)
            # Its own failure (not a figure's) comes back on the results pipe, as text.
            job = functools.partial(_serve, jobs_read, results_write)
            _worker(job, results_write, mask, parent)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    os.close(jobs_read)
    os.close(results_write)
    if pid < 0:
        os.close(jobs_write)
        os.close(results_read)
        return False
    _server = _Server(pid, jobs_write, results_read)
    return True


def _serve(jobs: int, results: int) -> None:
    """The work of the process of :func:`figure_server` (run by :func:`_worker`): imports
    matplotlib, reads the pickled calls until the pipe ``jobs`` ends, draws them as
    :func:`draw_all` does here and writes the pickled failures to ``results``."""
    import pickle

    try:
        _preload_and_warm()
        broken = None
    except Exception as e:  # every figure fails with it, below
        broken = _describe(e)
    data = _read_all(jobs)
    calls = pickle.loads(data) if data else []
    if broken is not None:
        failures = [(i, broken) for i in range(len(calls))]
    else:
        failures = _draw_jobs(calls, None)
    _write_all(results, pickle.dumps(failures))


def _read_all(fd: int) -> bytes:
    chunks = []
    while chunk := os.read(fd, 1 << 20):
        chunks.append(chunk)
    return b"".join(chunks)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def _pickled(jobs: list[Callable[[], object]]) -> bytes | None:
    """The calls pickled for the figure server, or None when one does not pickle (a
    closure: drawn here instead)."""
    import pickle

    try:
        return pickle.dumps(jobs, protocol=pickle.HIGHEST_PROTOCOL)
    except (pickle.PicklingError, TypeError, AttributeError):
        return None


def _draw_on_server(server: _Server, payload: bytes, count: int) -> list[tuple[int, str]]:
    """Hands the pickled calls to the server and waits for its failures; on Ctrl-C (or any
    error here) the server, and with it its workers, is stopped and reaped."""
    import pickle

    from prrrp import signals

    done = False
    try:
        with contextlib.suppress(BrokenPipeError):  # it died: said below, from its exit
            _write_all(server.jobs, payload)
        os.close(server.jobs)
        server.jobs = -1
        # End of file once the server and its workers (which share the pipe) have exited.
        data = _read_all(server.results)
        code = _reap(server.pid)
        done = True
    finally:
        if done:
            os.close(server.results)
        else:
            _end_server(server)
    if code != 0:
        signals.checkpoint()  # the server's Ctrl-C is also this process's
    try:
        failures = pickle.loads(data) if data else None
    except Exception:
        failures = None
    if failures is None:
        why = data.decode("utf-8", "replace").strip() or (
            f"killed by signal {-code}" if code < 0 else f"exit code {code}"
        )
        failures = [(i, f"the figure process failed: {why}") for i in range(count)]
    return list(failures)


def _end_server(server: _Server) -> None:
    """Stops the server (its drawing workers with it) and reaps it."""
    if server.jobs >= 0:
        with contextlib.suppress(OSError):
            os.close(server.jobs)
        server.jobs = -1
    # Its own workers get STOP_GRACE_S from it: more for it, which reaps them (killed
    # first, they would be left to init).
    _stop({server.results: (server.pid, -1, bytearray())}, grace=3 * STOP_GRACE_S)


def _default_workers() -> int:
    """Two per CPU this process may use: figures take similar times, and a third beside
    two others ends with them where it would start after them (3 figures on 2 cores: 1.5
    figures' time). None (1) when no CPU is idle (1-minute load average, this process
    included, within half a CPU of the count): a worker then only adds its own cost (the
    pages it copies, ~40 ms of CPU a figure) and takes CPU from the others."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1
    try:
        idle = cpus - os.getloadavg()[0]
    except OSError:
        idle = cpus
    return 2 * cpus if cpus > 1 and idle >= 0.5 else 1


def _describe(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}"


def _draw_here(index: int, job: Callable[[], object]) -> tuple[int, str] | None:
    """Runs ``job`` in this process: None, or (index, its error)."""
    try:
        job()
    except Exception as e:
        return index, _describe(e)
    return None


def _draw_forked(jobs: list[Callable[[], object]], workers: int) -> list[tuple[int, str]]:
    """:func:`draw_all` in forked workers, each reporting its error through a pipe whose
    end of file also says that it has exited."""
    import gc
    import select
    import warnings

    from prrrp import signals

    # The workers inherit matplotlib imported, and no output buffered twice.
    _import()
    sys.stdout.flush()
    sys.stderr.flush()
    stops = {signal.SIGINT, signal.SIGTERM}
    pending = list(enumerate(jobs))
    running: dict[int, tuple[int, int, bytearray]] = {}  # read end -> (pid, index, message)
    failures: list[tuple[int, str]] = []
    parent = os.getpid()
    try:
        while pending or running:
            while pending and len(running) < workers:
                index, job = pending.pop(0)
                if not pending and running:
                    # The last call is drawn here, beside the workers: this process would
                    # only wait, and a worker costs a fork and the pages it copies.
                    failure = _draw_here(index, job)
                    failures += [failure] if failure else []
                    break
                # Blocked across the fork: a signal arriving now reaches the parent once
                # the worker is in `running` (to be stopped), and the worker only inside
                # the handler that ends it (Python clears a child's pending signal flags).
                mask = signal.pthread_sigmask(signal.SIG_BLOCK, stops)
                try:
                    read, write = os.pipe()
                    # The worker's garbage collector leaves the inherited objects alone:
                    # scanning them would copy every page it touches.
                    gc.freeze()
                    try:
                        with warnings.catch_warnings():
                            # Python ≥ 3.12 warns of any thread, also OpenBLAS's pool,
                            # which readies itself for a fork (pthread_atfork); no Python
                            # thread runs (checked by draw_all).
                            warnings.simplefilter("ignore", DeprecationWarning)
                            pid = os.fork()
                    except OSError:
                        pid = -1  # no process to spare: drawn here, below
                    if pid != 0:
                        gc.unfreeze()
                    if pid == 0:
                        _worker(job, write, mask, parent)
                    if pid > 0:
                        running[read] = (pid, index, bytearray())
                        _children.add(pid)
                    os.close(write)
                finally:
                    signal.pthread_sigmask(signal.SIG_SETMASK, mask)
                if pid == -1:
                    os.close(read)
                    failure = _draw_here(index, job)
                    failures += [failure] if failure else []
            if not running:
                continue
            ready, _, _ = select.select(list(running), [], [])
            for fd in ready:
                chunk = os.read(fd, 4096)
                pid, index, message = running[fd]
                if chunk:
                    message.extend(chunk)
                    continue
                # End of file: the worker is exiting; reaped before it leaves `running`.
                code = _reap(pid)
                del running[fd]
                os.close(fd)
                if code != 0 or message:
                    signals.checkpoint()  # the worker's Ctrl-C is also the parent's
                    text = message.decode("utf-8", "replace").strip()
                    if not text:
                        text = f"killed by signal {-code}" if code < 0 else f"exit code {code}"
                    failures.append((index, text))
        signals.checkpoint()
    finally:
        _stop(running)  # only when interrupted (or failing) here
    return failures


#: Seconds the workers of an interrupted :func:`draw_all` have to remove their temporary
#: files (their Python code runs between two calls into matplotlib's C code, each well
#: under this) before they are killed.
STOP_GRACE_S = 1.0

#: Seconds between the SIGTERMs :func:`_stop` repeats during the grace: Python drops an
#: exception raised inside a finaliser or while it prints an ignored one, so a worker can
#: lose both a Ctrl-C and a first SIGTERM and draw on; one that is already unwinding
#: ignores the repeats (:func:`_stop_unless_stopping`).
STOP_RESEND_S = 0.05


def _stop(running: dict[int, tuple[int, int, bytearray]], grace: float = STOP_GRACE_S) -> None:
    """Ends the workers ``running`` (read end -> (pid, ...)): SIGTERM (repeated every
    :data:`STOP_RESEND_S`), up to ``grace`` seconds for them to exit, then SIGKILL; reaps
    every one. Ctrl-C and SIGTERM wait
    until it is done (at most ``grace``): a second one (a terminal's Ctrl-C reaches the
    whole group, a figure server's parent adds a SIGTERM) must not leave a worker
    unreaped."""
    import select
    import time

    def kill(sig: int, fds: Iterable[int]) -> None:
        for fd in fds:
            # Also harmless on a worker that has exited, until it is reaped.
            with contextlib.suppress(ProcessLookupError):
                os.kill(running[fd][0], sig)

    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    deferred: BaseException | None = None
    try:
        left = set(running)
        kill(signal.SIGTERM, left)
        deadline = time.monotonic() + grace
        while left and (timeout := deadline - time.monotonic()) > 0:
            ready, _, _ = select.select(list(left), [], [], min(timeout, STOP_RESEND_S))
            left -= {fd for fd in ready if not os.read(fd, 4096)}  # end of file: exited
            if not ready:
                kill(signal.SIGTERM, left)
    except (KeyboardInterrupt, SystemExit) as e:  # a signal that arrived before the mask
        deferred = e
    finally:
        kill(signal.SIGKILL, running)
        for fd, (pid, _, _) in running.items():
            while True:
                try:
                    _reap(pid)
                    break
                except (KeyboardInterrupt, SystemExit) as e:
                    deferred = deferred or e
            os.close(fd)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    if deferred is not None:
        raise deferred


#: The workers forked by :func:`_draw_forked` and not yet reaped.
_children: set[int] = set()


def _reap(pid: int) -> int:
    """Waits for the worker ``pid``: its exit code (−n for signal n; 0 when it was reaped
    elsewhere, e.g. with SIGCHLD ignored)."""
    try:
        code = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
    except ChildProcessError:
        code = 0
    _children.discard(pid)
    return code


def _kill_children() -> None:
    """SIGKILLs and reaps the workers still in :data:`_children`, whatever signal arrives
    meanwhile (blocked; one that had arrived before runs once and is retried past): the
    last act of a figure server, whose workers would otherwise be left to init."""
    while True:
        try:
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
            for pid in list(_children):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
                _reap(pid)
            return
        except (KeyboardInterrupt, SystemExit):
            continue


def _worker(job: Callable[[], object], write: int, mask: Any, parent: int) -> NoReturn:
    """A forked worker of :func:`draw_all` (or the figure server): runs ``job`` and exits
    (0, or with its error on ``write``), its own workers, if any, killed and reaped first;
    never returns into the parent's code."""
    code = 1
    _children.clear()  # the parent's, not this process's
    try:
        _die_with(parent)
        # Whatever this process's handlers were: stopped by an exception, which removes
        # the temporary file of a figure being saved.
        signal.signal(signal.SIGINT, _stop_unless_stopping)
        signal.signal(signal.SIGTERM, _stop_unless_stopping)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        job()
        code = 0
    except KeyboardInterrupt:
        code = 130
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else 1
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.write(write, _describe(e).encode("utf-8", "replace")[:4000])
    finally:
        _kill_children()  # none when its job ended normally
        os._exit(code)


def _stop_unless_stopping(signum: int, _frame: Any) -> None:
    """A worker's handler of SIGINT and SIGTERM: raises KeyboardInterrupt (SIGINT) or
    SystemExit(128 + n), unless such an exception is already being handled. A terminal's
    Ctrl-C and the SIGTERM of a stopping parent often arrive together, and a second
    exception inside the first one's cleanup would skip the removal of the temporary file.
    A first exception that Python dropped (raised inside a finaliser) is not being handled,
    so the parent's SIGTERM still stops the worker."""
    if isinstance(sys.exc_info()[1], KeyboardInterrupt | SystemExit):
        return
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise SystemExit(128 + signum)


def _die_with(parent: int) -> None:
    """Asks Linux to SIGKILL this process when its parent dies (PR_SET_PDEATHSIG), so that a
    parent killed outright leaves no worker drawing into its output; exits at once if
    the parent is already gone."""
    import ctypes

    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:
        os._exit(1)
