"""The report figures of ``prrrp identify`` without matplotlib: panels laid out in pixels
here, drawn by the native canvas (``prrrp._prrrp.Canvas``: the ``prrrp-figures`` crate,
antialiased shapes and a bundled DejaVu Sans, PNG out).

matplotlib's import and its fixed cost per panel (tick objects, text layout) were most of
the command's time; this module draws the same panels — frame, ticks inside the view,
tick labels, title, axis labels with units, legends — at matplotlib's sizes (points at
:data:`prrrp.drawing.DPI`), so that the images look as before, in a few milliseconds each.
It covers what the report's figures use (lines, shaded spans, point clouds, filled step
histograms, bars), not a plotting library: the study figures of :mod:`prrrp.plots` stay
on matplotlib.

A :class:`Figure` keeps what was asked for and draws only in :meth:`Figure.png`, so that
its texts and limits can be inspected (tests) and :meth:`Figure.layout` says where every
text lands.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from prrrp import drawing

#: Pixels per typographic point at the figures' resolution.
PT = drawing.DPI / 72.0

#: matplotlib's default sizes (rcParams), points: tick length and pad, line widths.
TICK_LENGTH = 3.5
TICK_PAD = 3.5
TICK_WIDTH = 0.8
SPINE_WIDTH = 0.8
TITLE_PAD = 6.0
#: Axis margins around the data (matplotlib's ``axes.xmargin`` / ``ymargin``).
MARGIN = 0.05
#: matplotlib's dash pattern of "--", in line widths.
DASHED = (3.7, 1.6)

#: matplotlib's named colours the report uses, in matplotlib's own hex notation.
COLORS = {
    "tab:blue": "#1f77b4",
    "tab:orange": "#ff7f0e",
    "tab:green": "#2ca02c",
    "tab:red": "#d62728",
    "tab:purple": "#9467bd",
    "tab:brown": "#8c564b",
    "tab:pink": "#e377c2",
    "tab:gray": "#7f7f7f",
    "tab:olive": "#bcbd22",
    "tab:cyan": "#17becf",
    "r": "#ff0000",
    "k": "#000000",
    "w": "#ffffff",
}
#: matplotlib's default colour cycle.
CYCLE = [
    "tab:blue",
    "tab:orange",
    "tab:green",
    "tab:red",
    "tab:purple",
    "tab:brown",
    "tab:pink",
    "tab:gray",
    "tab:olive",
    "tab:cyan",
]


def rgba(color: str, alpha: float = 1.0) -> tuple[int, int, int, int]:
    """A colour name of :data:`COLORS`, or a grey level "0.0".."1.0", as 0..255 RGBA."""
    if color in COLORS:
        code = COLORS[color]
        r, g, b = (int(code[k : k + 2], 16) for k in (1, 3, 5))
    else:
        level = round(255 * float(color))
        r = g = b = level
    return r, g, b, round(255 * alpha)


def px(points: float) -> float:
    return points * PT


class Axes:
    """One panel: a box in pixels (x0, y0, x1, y1; y down) and what it shows."""

    def __init__(self, figure: Figure, box: tuple[float, float, float, float]) -> None:
        self.figure = figure
        self.box = box
        self.axison = True
        self.title = ("", 9.0)
        self.xlabel = ("", 8.0)
        self.ylabel = ("", 8.0)
        self.label_offset = drawing.LABEL_Y_OFFSET
        #: Drawn in order: (kind, dict of its data and style).
        self.artists: list[tuple[str, dict[str, Any]]] = []
        self.legend_spec: dict[str, Any] | None = None
        self.xticks: tuple[np.ndarray, list[str], float, float] | None = None
        self.grid_y = False
        self._cycle = 0

    # What the tests ask of a panel (as of a matplotlib Axes).
    def get_xlabel(self) -> str:
        return self.xlabel[0]

    def get_ylabel(self) -> str:
        return self.ylabel[0]

    def get_title(self) -> str:
        return self.title[0]

    def set_title(self, text: str, fontsize: float = 9.0) -> None:
        self.title = (text, fontsize)

    def set_xlabel(self, text: str, fontsize: float = 8.0) -> None:
        self.xlabel = (text, fontsize)

    def set_ylabel(self, text: str, fontsize: float = 8.0) -> None:
        self.ylabel = (text, fontsize)

    def axis(self, what: str) -> None:
        if what == "off":
            self.axison = False

    def pixels(self) -> tuple[int, int]:
        """Width and height of the plotting area, whole pixels (as
        :func:`prrrp.drawing.pixels`)."""
        x0, y0, x1, y1 = self.box
        return max(math.ceil(x1 - x0), 1), max(math.ceil(y1 - y0), 1)

    def _next_color(self) -> str:
        c = CYCLE[self._cycle % len(CYCLE)]
        self._cycle += 1
        return c

    def _add(self, kind: str, data: dict[str, Any], **style: Any) -> None:
        """Appends an artist of ``kind``: its ``data`` as float arrays, then its ``style``
        (an empty ``color`` takes the next colour of the cycle)."""
        if "color" in style and not style["color"]:
            style["color"] = self._next_color()
        arrays = {k: np.asarray(v, dtype=float) for k, v in data.items()}
        self.artists.append((kind, {**arrays, **style}))

    def plot(
        self,
        x: np.ndarray,
        y: np.ndarray,
        *,
        color: str | None = None,
        lw: float = 1.5,
        ls: str = "-",
        label: str | None = None,
        alpha: float = 1.0,
    ) -> None:
        """A line through (x, y) as given (``lines`` reduces it to the pixel columns)."""
        self._add("line", {"x": x, "y": y}, color=color, lw=lw, ls=ls, label=label, alpha=alpha)

    def lines(self, x: np.ndarray, y: np.ndarray, **style: Any) -> None:
        """:meth:`plot` of the line reduced to this panel's pixel columns
        (:func:`prrrp.drawing.envelope`: the same pixels)."""
        px_, py_ = drawing.envelope(x, np.asarray(y), self.pixels()[0])
        self.plot(px_, py_, **style)

    def points(
        self,
        x: np.ndarray,
        y: np.ndarray,
        *,
        ms: float = 1.5,
        color: str | None = None,
        alpha: float = 1.0,
        label: str | None = None,
    ) -> None:
        """A cloud of round dots (matplotlib's "." marker of size ``ms`` points)."""
        self._add("points", {"x": x, "y": y}, ms=ms, color=color, alpha=alpha, label=label)

    def axvspan(self, a: float, b: float, color: str = "0.85") -> None:
        """A shaded span of x from a to b over the panel's height."""
        self.artists.append(("span", {"a": float(a), "b": float(b), "color": color}))

    def stairs(self, counts: np.ndarray, edges: np.ndarray, *, color: str = "tab:blue") -> None:
        """A filled step histogram (counts per bin between edges), from 0."""
        self._add("stairs", {"counts": counts, "edges": edges}, color=color)

    def bar(
        self,
        x: np.ndarray,
        heights: np.ndarray,
        width: float,
        *,
        label: str | None = None,
        color: str | None = None,
    ) -> None:
        """Bars centred on x, ``width`` wide (data units), from 0."""
        self._add("bars", {"x": x, "h": heights}, width=float(width), color=color, label=label)

    def set_xticks(
        self,
        x: Sequence[float],
        labels: Sequence[str],
        rotation: float = 0.0,
        fontsize: float = 8.0,
    ) -> None:
        """Fixed ticks at x with these labels (rotated, anchored at their right end)."""
        self.xticks = (np.asarray(x, dtype=float), list(labels), rotation, fontsize)

    def legend(
        self,
        *,
        fontsize: float = 7.0,
        loc: str = "upper left",
        markerscale: float = 1.0,
        outside: bool = False,
        frameon: bool = True,
    ) -> None:
        """A legend of the labelled artists: in the upper-left corner (``outside``:
        right of the panel, its top at the panel's)."""
        self.legend_spec = {
            "fontsize": fontsize,
            "loc": loc,
            "markerscale": markerscale,
            "outside": outside,
            "frameon": frameon,
        }

    def get_legend_handles_labels(self) -> tuple[list[tuple[str, dict[str, Any]]], list[str]]:
        handles = [(k, a) for k, a in self.artists if a.get("label")]
        return handles, [a["label"] for _, a in handles]

    # ------------------------------------------------------------------ limits, ticks

    def limits(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """(x, y) view limits: the data's range widened by :data:`MARGIN` each side,
        except past a histogram's or bar's baseline and a histogram's outer edges
        (matplotlib's sticky edges)."""
        xs: list[np.ndarray] = []
        ys: list[np.ndarray] = []
        sticky_y: list[float] = []
        for kind, a in self.artists:
            if kind in ("line", "points"):
                ok = np.isfinite(a["x"]) & np.isfinite(a["y"])
                xs.append(a["x"][ok])
                ys.append(a["y"][ok])
            elif kind == "span":
                xs.append(np.array([a["a"], a["b"]]))
            elif kind == "stairs":
                e, c = a["edges"], a["counts"]
                xs.append(e[[0, -1]])
                ys.append(np.array([0.0, float(np.max(c)) if len(c) else 0.0]))
                sticky_y.append(0.0)
            elif kind == "bars":
                h = a["h"][np.isfinite(a["h"])]
                xs.append(np.concatenate((a["x"] - a["width"] / 2, a["x"] + a["width"] / 2)))
                ys.append(np.concatenate(([0.0], h)))
                sticky_y.append(0.0)
        if self.xticks is not None:
            xs.append(self.xticks[0])
        return _view(xs, []), _view(ys, sticky_y)

    def transform(self) -> tuple[Any, Any]:
        """Functions from data x and y to pixels."""
        (xa, xb), (ya, yb) = self.limits()
        x0, y0, x1, y1 = self.box

        def fx(v: Any) -> Any:
            return x0 + (np.asarray(v, dtype=float) - xa) / (xb - xa) * (x1 - x0)

        def fy(v: Any) -> Any:
            return y1 - (np.asarray(v, dtype=float) - ya) / (yb - ya) * (y1 - y0)

        return fx, fy


def _view(values: list[np.ndarray], sticky: list[float]) -> tuple[float, float]:
    v = np.concatenate(values) if values else np.array([])
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return 0.0, 1.0
    lo, hi = float(v.min()), float(v.max())
    if hi <= lo:  # constant: a band around it (matplotlib's nonsingular)
        d = 0.05 * abs(lo) if lo != 0 else 0.05
        return lo - d, hi + d
    pad = MARGIN * (hi - lo)
    a, b = lo - pad, hi + pad
    for s in sticky:
        if a < s <= lo:
            a = s
        if hi <= s < b:
            b = s
    return a, b


#: Tick steps (times a power of ten), as the figures' MaxNLocator(nbins=4).
TICK_STEPS = (1.0, 2.0, 2.5, 5.0, 10.0)
TICK_BINS = 4


def ticks(lo: float, hi: float, nbins: int = TICK_BINS) -> np.ndarray:
    """matplotlib's MaxNLocator (``steps`` = :data:`TICK_STEPS`) over [lo, hi], only the
    ticks inside it: the smallest step at least (hi − lo)/nbins that leaves two ticks in
    view."""
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
        return np.array([])
    raw = (hi - lo) / nbins
    scale = 10.0 ** math.floor(math.log10(raw))
    steps = np.array([0.1, 0.2, 0.25, 0.5, *TICK_STEPS, 20.0]) * scale
    first = int(np.flatnonzero(steps >= raw * (1 - 1e-10))[0])
    out = np.array([])
    for step in steps[: first + 1][::-1]:
        start = math.floor(lo / step + 1e-10) * step
        k = np.arange(0, math.ceil((hi - start) / step - 1e-10) + 1)
        cand = start + k * step
        slack = 1e-10 * (hi - lo)
        out = cand[(cand >= lo - slack) & (cand <= hi + slack)]
        if len(out) >= 2:
            break
    return out


MINUS = "\u2212"


def tick_labels(values: np.ndarray) -> tuple[list[str], str]:
    """Labels of the ticks ``values`` (as few decimals as tell them apart, matplotlib's
    minus sign) and the axis's scale ("1e−5" when the labels are in units of it, else
    "")."""
    if len(values) == 0:
        return [], ""
    big = float(np.max(np.abs(values)))
    exp = 0
    if big >= 1e5 or 0 < big < 1e-3:
        exp = math.floor(math.log10(big))
    v = values / 10.0**exp
    step = float(np.min(np.diff(v))) if len(v) > 1 else abs(float(v[0])) or 1.0
    decimals = 0
    while decimals < 10 and abs(round(step, decimals) - step) > 1e-6 * step:
        decimals += 1
    texts = []
    for x in v:
        s = f"{x:.{decimals}f}"
        if float(s) == 0:
            s = s.lstrip("-")
        texts.append(s.replace("-", MINUS))
    scale = f"1e{exp}".replace("-", MINUS) if exp else ""
    return texts, scale


# ------------------------------------------------------------------------------ figure


class Figure:
    """A figure of panels (see :func:`figure`), drawn by :meth:`png`."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.panels: list[Axes] = []
        self.legend_spec: dict[str, Any] | None = None

    @property
    def axes(self) -> list[Axes]:
        return list(self.panels)

    def legend(
        self,
        handles: list[tuple[str, dict[str, Any]]],
        labels: list[str],
        *,
        ncol: int = 3,
        fontsize: float = 8.0,
    ) -> None:
        """A legend centred above the panels, ``ncol`` entries a row, no frame."""
        self.legend_spec = {
            "handles": handles,
            "labels": labels,
            "ncol": ncol,
            "fontsize": fontsize,
        }

    def png(self) -> bytes:
        """The figure drawn, as PNG bytes."""
        from prrrp._prrrp import Canvas

        c = Canvas(self.width, self.height)
        for ax in self.panels:
            if ax.axison:
                _draw_axes(c, ax)
            elif ax.title[0]:
                _draw_title(c, ax)
        if self.legend_spec is not None:
            _figure_legend(c, self, self.legend_spec)
        return c.png()

    def layout(self) -> list[tuple[int, str, tuple[float, float, float, float]]]:
        """Where every text of every shown panel lands: (panel index, "xtick", "ytick",
        "title", "xlabel" or "ylabel", its box (x0, y0, x1, y1) in pixels, y down)."""
        from prrrp._prrrp import Canvas

        c = Canvas(1, 1)  # measures only
        out = []
        for i, ax in enumerate(self.panels):
            if ax.axison:
                out += [(i, kind, box) for kind, box in _texts(c, ax)]
        return out


def figure(
    rows: int,
    cols: int,
    *,
    panel: tuple[float, float] = drawing.PANEL,
    left: float = drawing.LEFT,
    right: float = drawing.RIGHT,
    top: float = drawing.TOP,
    bottom: float = drawing.BOTTOM,
    wspace: float = drawing.WSPACE,
    hspace: float = drawing.HSPACE,
    label_offset: float | None = None,
) -> tuple[Figure, np.ndarray]:
    """A figure of ``rows`` × ``cols`` panels of ``panel`` = (width, height) inches, with
    the margins of :func:`prrrp.drawing.figure` (inches); returns (figure, axes array of
    shape (rows, cols))."""
    d = drawing.DPI
    pw, ph = panel
    width, height = drawing.grid_size(
        rows, cols, panel, (left, right, top, bottom), (wspace, hspace)
    )
    fig = Figure(round(width * d), round(height * d))
    axes = np.empty((rows, cols), dtype=object)
    for r in range(rows):
        for k in range(cols):
            x0 = (left + k * (pw + wspace)) * d
            y0 = (top + r * (ph + hspace)) * d
            ax = Axes(fig, (x0, y0, x0 + pw * d, y0 + ph * d))
            if label_offset is not None:
                ax.label_offset = label_offset
            fig.panels.append(ax)
            axes[r, k] = ax
    return fig, axes


# ----------------------------------------------------------------------------- drawing

BLACK = (0, 0, 0, 255)


def _axis_ticks(ax: Axes) -> tuple[Any, Any]:
    """((positions px, labels, scale, rotation, fontsize) of x, the same of y)."""
    (xa, xb), (ya, yb) = ax.limits()
    fx, fy = ax.transform()
    if ax.xticks is not None:
        xv, xl, rot, fs = ax.xticks
        xs = (fx(xv), xl, "", rot, fs)
    else:
        xv = ticks(xa, xb)
        xl, xscale = tick_labels(xv)
        xs = (fx(xv), xl, xscale, 0.0, 8.0)
    yv = ticks(ya, yb)
    yl, yscale = tick_labels(yv)
    return xs, (fy(yv), yl, yscale, 0.0, 8.0)


def _texts(c: Any, ax: Axes) -> list[tuple[str, tuple[float, float, float, float]]]:
    """The boxes of a panel's texts (see :meth:`Figure.layout`), and how they are placed
    (the same arithmetic as :func:`_draw_axes`)."""
    x0, y0, x1, y1 = ax.box
    (xp, xl, _, rot, xfs), (yp, yl, _, _, yfs) = _axis_ticks(ax)
    out = []
    below = y1 + px(TICK_LENGTH + TICK_PAD)
    for p, s in zip(xp, xl, strict=True):
        w, a, d = c.text_extent(s, px(xfs))
        if rot:
            # Rotated about its top-right end: its box spans left and down from there.
            t = math.radians(rot)
            bw, bh = w * math.cos(t) + (a + d) * math.sin(t), w * math.sin(t) + (a + d)
            out.append(("xtick", (p - bw, below, p, below + bh)))
        else:
            out.append(("xtick", (p - w / 2, below, p + w / 2, below + a + d)))
    right = x0 - px(TICK_LENGTH + TICK_PAD)
    for p, s in zip(yp, yl, strict=True):
        w, a, d = c.text_extent(s, px(yfs))
        out.append(("ytick", (right - w, p - (a + d) / 2, right, p + (a + d) / 2)))
    if ax.title[0]:
        w, a, d = c.text_extent(ax.title[0], px(ax.title[1]))
        base = y0 - px(TITLE_PAD)
        cx = (x0 + x1) / 2
        out.append(("title", (cx - w / 2, base - a, cx + w / 2, base + d)))
    if ax.xlabel[0]:
        w, a, d = c.text_extent(ax.xlabel[0], px(ax.xlabel[1]))
        top = _xlabel_top(ax, [b for k, b in out if k == "xtick"])
        cx = (x0 + x1) / 2
        out.append(("xlabel", (cx - w / 2, top, cx + w / 2, top + a + d)))
    if ax.ylabel[0]:
        w, a, d = c.text_extent(ax.ylabel[0], px(ax.ylabel[1]))
        edge = x0 - ax.label_offset * drawing.DPI
        cy = (y0 + y1) / 2
        out.append(("ylabel", (edge - a - d, cy - w / 2, edge, cy + w / 2)))
    return out


def _xlabel_top(ax: Axes, rotated: list[tuple[float, float, float, float]]) -> float:
    """Top of the x-axis label: :data:`prrrp.drawing.LABEL_X_DROP` below the panel, or
    below slanted tick labels that reach further."""
    top = ax.box[3] + drawing.LABEL_X_DROP * drawing.DPI
    if ax.xticks is not None and ax.xticks[2]:
        top = max([top, *(b[3] + px(2.0) for b in rotated)])
    return top


def _draw_title(c: Any, ax: Axes) -> None:
    x0, y0, x1, _ = ax.box
    c.text(ax.title[0], (x0 + x1) / 2, y0 - px(TITLE_PAD), px(ax.title[1]), "center", "baseline")


def _draw_axes(c: Any, ax: Axes) -> None:
    x0, y0, x1, y1 = ax.box
    fx, fy = ax.transform()
    c.set_clip((x0, y0, x1, y1))
    (xp, xl, xscale, rot, xfs), (yp, yl, yscale, _, yfs) = _axis_ticks(ax)
    if ax.grid_y:
        for p in yp:
            c.polyline(np.array([x0, x1]), np.array([p, p]), (176, 176, 176, 77), px(0.8))
    for kind, a in ax.artists:
        if kind == "span":
            c.fill_rect(float(fx(a["a"])), y0, float(fx(a["b"])), y1, rgba(a["color"]))
        elif kind == "line":
            dash = [px(d * a["lw"]) for d in DASHED] if a["ls"] == "--" else []
            c.polyline(fx(a["x"]), fy(a["y"]), rgba(a["color"], a["alpha"]), px(a["lw"]), dash)
        elif kind == "points":
            c.markers(fx(a["x"]), fy(a["y"]), _dot_radius(a["ms"]), rgba(a["color"], a["alpha"]))
        elif kind == "stairs":
            e, n = a["edges"], a["counts"]
            xs = np.concatenate(([e[0]], np.repeat(e[1:-1], 2), [e[-1]]))
            ys = np.repeat(n, 2)
            xs = np.concatenate((xs, [e[-1], e[0]]))
            ys = np.concatenate((ys, [0.0, 0.0]))
            c.fill_polygon(fx(xs), fy(ys), rgba(a["color"]))
        elif kind == "bars":
            color = rgba(a["color"])
            for xc, h in zip(a["x"], a["h"], strict=True):
                if np.isfinite(h):
                    c.fill_rect(
                        float(fx(xc - a["width"] / 2)),
                        float(fy(0.0)),
                        float(fx(xc + a["width"] / 2)),
                        float(fy(h)),
                        color,
                    )
    c.set_clip(None)
    # Frame and ticks, over the data as matplotlib's spines are, on pixel centres (as
    # matplotlib snaps them): a 1.1-pixel line between two pixels would be a grey 2.
    f0, g0, f1, g1 = (_snap(v) for v in (x0, y0, x1, y1))
    c.stroke_rect(f0, g0, f1, g1, BLACK, px(SPINE_WIDTH))
    tick = px(TICK_LENGTH)
    for p in xp:
        p = _snap(p)
        c.polyline(np.array([p, p]), np.array([g1, g1 + tick]), BLACK, px(TICK_WIDTH))
    for p in yp:
        p = _snap(p)
        c.polyline(np.array([f0 - tick, f0]), np.array([p, p]), BLACK, px(TICK_WIDTH))
    below = y1 + tick + px(TICK_PAD)
    for p, s in zip(xp, xl, strict=True):
        if rot:
            c.text(s, float(p), below, px(xfs), "right", "top", rot)
        else:
            c.text(s, float(p), below, px(xfs), "center", "top")
    right = x0 - tick - px(TICK_PAD)
    for p, s in zip(yp, yl, strict=True):
        c.text(s, right, float(p), px(yfs), "right", "center")
    if yscale:
        c.text(yscale, x0, y0 - px(2.0), px(yfs), "left", "bottom")
    if xscale:
        c.text(xscale, x1, below + px(xfs * 1.2), px(xfs), "right", "top")
    if ax.xlabel[0]:
        boxes = [b for k, b in _texts(c, ax) if k == "xtick"] if rot else []
        top = _xlabel_top(ax, boxes)
        c.text(ax.xlabel[0], (x0 + x1) / 2, top, px(ax.xlabel[1]), "center", "top")
    if ax.ylabel[0]:
        edge = x0 - ax.label_offset * drawing.DPI
        c.text(ax.ylabel[0], edge, (y0 + y1) / 2, px(ax.ylabel[1]), "center", "bottom", 90.0)
    if ax.title[0]:
        _draw_title(c, ax)
    if ax.legend_spec is not None:
        _axes_legend(c, ax, ax.legend_spec)


def _snap(v: float) -> float:
    """The centre of the pixel ``v`` falls in."""
    return math.floor(float(v)) + 0.5


def _dot_radius(ms: float) -> float:
    """Radius (pixels) of matplotlib's "." marker of size ``ms``: a disc of half that
    diameter with a 1-point edge of the same colour."""
    return px(ms * 0.25 + 0.5)


def _handle(
    c: Any, kind: str, a: dict[str, Any], x: float, y: float, length: float, markerscale: float
) -> None:
    """A legend entry's sample, ``length`` pixels wide, centred vertically on y."""
    if kind == "line":
        dash = [px(d * a["lw"]) for d in DASHED] if a["ls"] == "--" else []
        c.polyline(
            np.array([x, x + length]),
            np.array([y, y]),
            rgba(a["color"], a["alpha"]),
            px(a["lw"]),
            dash,
        )
    elif kind == "points":
        c.markers(
            np.array([x + length / 2]),
            np.array([y]),
            _dot_radius(a["ms"] * markerscale),
            rgba(a["color"], a["alpha"]),
        )
    else:
        h = 0.7 * length / 2
        c.fill_rect(x + length * 0.1, y - h / 2, x + length * 0.9, y + h / 2, rgba(a["color"]))


def _entries(
    c: Any, labels: list[str], spec: dict[str, Any]
) -> tuple[float, float, float, list[float]]:
    """(font size px, sample length, row height, text widths) of a legend of ``spec``."""
    size = px(spec["fontsize"])
    widths = [c.text_extent(s, size)[0] for s in labels]
    _, a, d = c.text_extent("Ag", size)
    return size, 2.0 * size, max(a + d, size) + 0.5 * size, widths


def _axes_legend(c: Any, ax: Axes, spec: dict[str, Any]) -> None:
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    size, length, row, widths = _entries(c, labels, spec)
    pad, gap = 0.4 * size, 0.8 * size
    w = pad * 2 + length + gap + max(widths)
    h = pad * 2 + row * len(labels) - 0.5 * size
    x0, y0, x1, _ = ax.box
    if spec["outside"]:
        bx, by = x1 + 0.02 * (x1 - x0), y0
    else:
        bx, by = x0 + 0.5 * size, y0 + 0.5 * size
    if spec["frameon"]:
        c.fill_rect(bx, by, bx + w, by + h, (255, 255, 255, 204))
        c.stroke_rect(bx, by, bx + w, by + h, rgba("0.8"), px(1.0))
    for k, ((kind, a), s) in enumerate(zip(handles, labels, strict=True)):
        cy = by + pad + row * k + (row - 0.5 * size) / 2
        _handle(c, kind, a, bx + pad, cy, length, spec["markerscale"])
        c.text(s, bx + pad + length + gap, cy, size, "left", "center")


def _figure_legend(c: Any, fig: Figure, spec: dict[str, Any]) -> None:
    handles, labels, ncol = spec["handles"], spec["labels"], spec["ncol"]
    if not handles:
        return
    size, length, row, widths = _entries(c, labels, spec)
    gap, between = 0.8 * size, 2.0 * size
    rows = [list(range(k, min(k + ncol, len(labels)))) for k in range(0, len(labels), ncol)]
    y = 0.9 * size + row / 2
    for r in rows:
        total = sum(length + gap + widths[i] for i in r) + between * (len(r) - 1)
        x = (fig.width - total) / 2
        for i in r:
            kind, a = handles[i]
            _handle(c, kind, a, x, y, length, 1.0)
            c.text(labels[i], x + length + gap, y, size, "left", "center")
            x += length + gap + widths[i] + between
        y += row
