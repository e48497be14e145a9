"""What every figure of prrrp shares: a figure of panels laid out once with fixed margins,
traces reduced to what the saved image can show, and the PNG writer.

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

import importlib
import os
import threading
from collections.abc import Sequence
from typing import Any

import numpy as np

#: Resolution of the saved PNGs, dots per inch.
DPI = 100

#: Distance of an x-axis label's centre below its panel, and of a y-axis label's centre
#: left of it, inches: clear of 8-point tick labels (up to 6 characters wide).
LABEL_X_DROP = 0.32
LABEL_Y_OFFSET = 0.55

_preload: threading.Thread | None = None


def _import() -> None:
    # Agg canvases directly: pyplot's backend (a notebook's, a user's) is left alone.
    for name in ("matplotlib.figure", "matplotlib.backends.backend_agg"):
        importlib.import_module(name)


def preload() -> None:
    """Starts importing matplotlib on a daemon thread (once), for a caller that will draw
    after a computation that releases the GIL; :func:`figure` waits for it."""
    global _preload
    if _preload is None:
        _preload = threading.Thread(target=_import, name="prrrp-import-matplotlib", daemon=True)
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
    panel: tuple[float, float] = (3.6, 1.9),
    left: float = 0.8,
    right: float = 0.2,
    top: float = 0.45,
    bottom: float = 0.55,
    wspace: float = 0.85,
    hspace: float = 0.85,
    sharex: bool = False,
    label_offset: float | None = None,
) -> tuple[Any, np.ndarray]:
    """A figure of ``rows`` × ``cols`` panels of ``panel`` = (width, height) inches each,
    with fixed margins in inches: ``left`` (y tick labels and label), ``bottom`` (x tick
    labels and label), ``top`` (titles), ``wspace`` and ``hspace`` between panels. Returns
    (figure, axes array of shape (rows, cols))."""
    wait_preload()
    _import()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pw, ph = panel
    width = left + right + cols * pw + (cols - 1) * wspace
    height = top + bottom + rows * ph + (rows - 1) * hspace
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
    for ax in axes.flat:
        ax.tick_params(which="both", labelsize=8)
        # Few ticks: each label is a text to lay out, and more crowd a small panel.
        ax.locator_params(nbins=4)
        # Titles and axis labels at fixed places in the margins: placed automatically,
        # each would be moved clear of the tick labels, measuring every one of them.
        ax.title.set_y(1.0)
        ax._autotitlepos = False
        ax.xaxis.set_label_coords(0.5, -LABEL_X_DROP / ph)
        offset = LABEL_Y_OFFSET if label_offset is None else label_offset
        ax.yaxis.set_label_coords(-offset / pw, 0.5)
    return fig, axes


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


def save(fig: Any, path: str | os.PathLike[str]) -> None:
    """Writes ``fig`` as a PNG at :data:`DPI` (format given: the caller may write to a
    temporary name without the .png suffix)."""
    # zlib level 6 (PIL's default) costs more than drawing for a few percent of size.
    fig.savefig(path, dpi=DPI, format="png", pil_kwargs={"compress_level": 2})
