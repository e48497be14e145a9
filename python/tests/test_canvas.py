"""The native figures (prrrp.canvas over prrrp._prrrp.Canvas): ticks where matplotlib's
locator puts them, labels that tell the ticks apart, shapes at the pixels their data map
to, text inside the image, typed errors for bad input."""

from __future__ import annotations

import io

import numpy as np
import pytest

import prrrp
from prrrp import canvas
from prrrp._prrrp import Canvas


def in_view_ticks(lo: float, hi: float) -> np.ndarray:
    """matplotlib's own MaxNLocator (the figures' settings of drawing.figure), in view."""
    from matplotlib.ticker import MaxNLocator

    locs = MaxNLocator(nbins=4, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)
    slack = 1e-10 * (hi - lo)
    return locs[(locs >= lo - slack) & (locs <= hi + slack)]


@pytest.mark.parametrize("seed", range(40))
def test_ticks_are_matplotlibs(seed):
    rng = np.random.default_rng(seed)
    lo = rng.normal() * 10.0 ** rng.integers(-4, 5)
    hi = lo + abs(rng.normal()) * 10.0 ** rng.integers(-4, 5) + 1e-12
    ours = canvas.ticks(lo, hi)
    assert np.allclose(ours, in_view_ticks(lo, hi), rtol=0, atol=1e-9 * (hi - lo)), (lo, hi)


@pytest.mark.parametrize(
    ("values", "texts", "scale"),
    [
        ([0.0, 10.0, 20.0, 30.0], ["0", "10", "20", "30"], ""),
        ([-2.5, 0.0, 2.5, 5.0], ["−2.5", "0.0", "2.5", "5.0"], ""),
        ([-0.02, 0.0, 0.02], ["−0.02", "0.00", "0.02"], ""),
        ([0.0, 2e-4, 4e-4], ["0", "2", "4"], "1e−4"),
        ([0.0, 5e5, 1e6], ["0.0", "0.5", "1.0"], "1e6"),
    ],
)
def test_tick_labels_tell_the_ticks_apart(values, texts, scale):
    assert canvas.tick_labels(np.array(values)) == (texts, scale)


def decode(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def test_a_line_lands_on_the_pixels_its_data_map_to():
    fig, axes = canvas.figure(1, 1, panel=(3.0, 2.0))
    ax = axes[0, 0]
    ax.plot(np.array([0.0, 10.0]), np.array([1.0, 1.0]), color="tab:red", lw=2.0)
    ax.plot(np.array([0.0, 10.0]), np.array([0.0, 0.0]), color="0.5", lw=2.0)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("torque (N·m)")
    ax.set_title("joint 1")
    img = decode(fig.png())
    assert img.shape == (fig.height, fig.width, 3)
    x0, y0, x1, y1 = ax.box
    # y limits: [0, 1] widened by 5 % each side; the red line at 1 sits 1/22 of the
    # panel's height below its top.
    row = round(y0 + (y1 - y0) / 22)
    col = round((x0 + x1) / 2)
    r, g, b = (int(v) for v in img[row, col])
    assert r > 180, (r, g, b)
    assert max(g, b) < 90, (r, g, b)
    grey = img[round(y1 - (y1 - y0) / 22), col]
    assert abs(int(grey[0]) - 128) < 30
    assert grey[0] == grey[1] == grey[2]
    # Between them: white; the frame: dark.
    assert (img[round((y0 + y1) / 2), col] == 255).all()
    assert img[round(y1), col].max() < 100
    # Ink in the title's band above the panel, none in the empty corner.
    assert (img[: int(y0), int(x0) : int(x1)] < 128).any()
    assert (img[: int(y0 * 0.3), -20:] == 255).all()


def test_every_text_is_inside_the_image():
    fig, axes = canvas.figure(2, 3)
    rng = np.random.default_rng(1)
    for ax in axes.flat:
        ax.lines(np.arange(500) * 0.01, rng.normal(size=500) * 1e3, color="tab:blue")
        ax.set_xlabel("joint velocity q̇ (rad/s)")
        ax.set_ylabel("friction torque (N·m)")
        ax.set_title("shoulder_lift_joint: RMS 0.123 N·m")
    assert fig.png()[:8] == b"\x89PNG\r\n\x1a\n"
    for _, kind, (a, b, c, d) in fig.layout():
        assert 0 <= a < c <= fig.width, (kind, (a, b, c, d))
        assert 0 <= b < d <= fig.height, (kind, (a, b, c, d))


def test_bad_canvas_input_is_a_typed_error():
    with pytest.raises(prrrp.InvalidInputError, match="pixels wide"):
        Canvas(0, 10)
    c = Canvas(10, 10)
    with pytest.raises(prrrp.InvalidInputError, match="differ in length"):
        c.polyline(np.zeros(3), np.zeros(2), (0, 0, 0, 255), 1.0)
    with pytest.raises(prrrp.InvalidInputError, match="line width"):
        c.polyline(np.zeros(3), np.zeros(3), (0, 0, 0, 255), float("nan"))
    with pytest.raises(prrrp.InvalidInputError, match="ha must be"):
        c.text("a", 1.0, 1.0, 8.0, "middle")
    assert c.text_extent("", 10.0)[0] == 0.0


def test_method_bars_keep_their_slanted_names_clear_of_the_axis_label(tmp_path, monkeypatch):
    from prrrp import drawing, model_report

    joints = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint"]
    runs = [
        {
            "method": m,
            "status": "ok",
            "converged": True,
            "validation": None,
            "identification": {"percent": np.arange(1.0, 5.0) * (k + 1)},
        }
        for k, m in enumerate(["ls", "wls", "ekf"])
    ]
    runs.append({"method": "rls", "status": "failed"})
    saved = []
    monkeypatch.setattr(drawing, "save", lambda fig, path: saved.append(fig))
    model_report.comparison_figure(runs, joints, tmp_path / "methods.png")
    (fig,) = saved
    ax = fig.panels[0]
    bars = [a for kind, a in ax.artists if kind == "bars"]
    assert [a["label"] for a in bars] == ["ls", "wls", "ekf"]
    assert np.array_equal(bars[2]["h"], np.arange(1.0, 5.0) * 3)
    texts = fig.layout()
    names = [b for _, kind, b in texts if kind == "xtick"]
    (label,) = [b for _, kind, b in texts if kind == "xlabel"]
    assert len(names) == len(joints)
    assert all(b[3] <= label[1] for b in names), (names, label)
    for _, kind, (a, b, c, d) in texts:
        assert 0 <= a < c <= fig.width, kind
        assert 0 <= b < d <= fig.height, kind
    assert fig.png()[:8] == b"\x89PNG\r\n\x1a\n"
