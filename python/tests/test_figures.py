"""The report's figures: traces reduced to what the image shows keep every pixel column's
extremes (against the raw data), every panel has axis labels with quantity and unit,
report.md embeds the figures it is written before, numbers are rounded to what σ
supports, and matplotlib is imported only to draw."""

from __future__ import annotations

import itertools
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from conftest import paper_friction_log

import prrrp
from prrrp import drawing, model_report

# ------------------------------------------------------------------------- reduction


def column_extremes(x, y, columns):
    """Per pixel column of [x0, x1]: (min, max) of y over the samples in it (a loop over
    the columns, independent of drawing.envelope's sort)."""
    return column_extremes_at(x, x, y, columns)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_envelope_keeps_each_columns_min_and_max(seed):
    rng = np.random.default_rng(seed)
    n = 20_000
    # A jittery clock with repeated stamps, a random walk, spikes one sample wide.
    x = np.cumsum(rng.choice([0.0, 0.001, 0.002], n, p=[0.05, 0.9, 0.05]))
    y = np.cumsum(rng.normal(size=n))
    y[rng.integers(0, n, 30)] += rng.normal(0, 200, 30)
    columns = 300
    xs, ys = drawing.envelope(x, y, columns)
    assert len(xs) <= 2 * columns + 2 < n / 10
    assert np.all(np.diff(xs) >= 0)  # still in time order
    assert xs[0] == x[0]
    assert xs[-1] == x[-1]
    raw = column_extremes(x, y, columns)
    kept = column_extremes_at(x, xs, ys, columns)
    assert raw.keys() == kept.keys()
    for c, (lo, hi) in raw.items():
        assert kept[c] == (lo, hi), c
    # Every kept point is a sample of the input.
    pairs = set(zip(x.tolist(), y.tolist(), strict=True))
    assert all(p in pairs for p in zip(xs.tolist(), ys.tolist(), strict=True))


def column_extremes_at(x_full, xs, ys, columns):
    """column_extremes of the (reduced) points xs, ys, in the pixel columns of the full x
    range."""
    edges = x_full[0] + (x_full[-1] - x_full[0]) * np.arange(columns + 1) / columns
    out = {}
    for c in range(columns):
        last = c == columns - 1
        inside = (xs >= edges[c]) & ((xs <= edges[c + 1]) if last else (xs < edges[c + 1]))
        if inside.any():
            v = ys[inside]
            out[c] = (np.min(v), np.max(v)) if np.isnan(v).all() else (np.nanmin(v), np.nanmax(v))
    return out


def test_envelope_of_several_lines_and_nans():
    rng = np.random.default_rng(5)
    x = np.linspace(0, 10, 5001)
    y = rng.normal(size=(5001, 3))
    y[100:300, 1] = np.nan  # a gap in one line
    xs, ys = drawing.envelope(x, y, 100)
    for j in range(3):
        raw = column_extremes(x, y[:, j], 100)
        kept = column_extremes_at(x, xs, ys[:, j], 100)
        for c, extremes in raw.items():
            # An all-NaN column (the gap) stays NaN: the line stays broken there.
            assert np.array_equal(kept[c], extremes, equal_nan=True), (j, c)


def test_short_lines_are_drawn_as_they_are():
    x, y = np.arange(50.0), np.arange(50.0) ** 2
    xs, ys = drawing.envelope(x, y, 100)
    assert np.array_equal(xs, x)
    assert np.array_equal(ys, y)


def test_thin_points_cover_every_pixel_the_cloud_covers():
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=50_000), rng.normal(size=50_000) ** 3
    size = (200, 120)
    keep = drawing.thin_points(x, y, size)
    assert len(keep) < len(x) / 3

    def cells(i):
        """Pixel cells of points i in a plot of the data's range with 5 % margins."""
        out = []
        for v, n in ((x, size[0]), (y, size[1])):
            lo, hi = v.min() - 0.05 * np.ptp(v), v.max() + 0.05 * np.ptp(v)
            out.append(np.floor((v[i] - lo) / (hi - lo) * n).astype(int).tolist())
        return set(zip(*out, strict=True))

    # Every pixel the cloud covers still has a point.
    assert cells(np.arange(len(x))) == cells(keep)
    for v in (x, y):
        assert v[keep].min() == v.min()
        assert v[keep].max() == v.max()


# --------------------------------------------------------------------------- figures


@pytest.fixture(scope="module")
def run():
    """The paper's arm with friction, identified from a 6 s multi-sine log at 200 Hz with
    sensor noise."""
    robot, raw = paper_friction_log(7)
    return prrrp.identify_measurements(robot, raw, "wls", coulomb_scale=0.02)


UNIT = re.compile(r"\((N·m|N|rad/s|m/s|s)\)$")


def test_every_panel_has_labels_with_units(run, tmp_path, monkeypatch):
    saved = {}
    real_save = drawing.save

    def keep(fig, path):
        saved[Path(path).name] = fig
        real_save(fig, path)

    monkeypatch.setattr(drawing, "save", keep)
    figures = model_report.write_figures(run.model, run.raw, tmp_path)
    assert [name for name, _ in figures] == ["torque.png", "residual.png", "friction.png"]
    assert set(saved) == {name for name, _ in figures}
    types = run.model.robot.joint_types
    for name, fig in saved.items():
        panels = [ax for ax in fig.axes if ax.axison]
        assert len(panels) == 5, name
        for ax, kind in zip(panels, types, strict=True):
            x, y = ax.get_xlabel(), ax.get_ylabel()
            assert UNIT.search(x), (name, x)
            assert UNIT.search(y) or y == "rows per bin", (name, y)
            force = "N" if kind == "P" else "N·m"
            assert f"({force})" in (y if name != "residual.png" else x), (name, kind, x, y)
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def rigid_points(model, grid):
    """The friction figure's points by their definition: the measured torque minus the
    prediction of the model with its friction base parameters zeroed (a second model)."""
    from prrrp._prrrp import identified_model_from_parts

    _, mask = model_report.friction_split(model)
    rigid = identified_model_from_parts(model.robot, np.where(mask, 0.0, model.beta))
    k = grid.scored
    points = grid.measured[k] - grid.predict(rigid)[k]
    qd = prrrp.prediction._at_rows(
        np.asarray(grid.processed.t), np.asarray(grid.processed.qd), grid.t
    )[k]
    c = model.robot.actuators["coupling"]
    if c is not None:
        c = np.asarray(c)
        qd = qd @ c.T
        points = np.linalg.solve(c.T, points.T).T
    return qd, points


def test_friction_points_are_the_torque_less_the_rigid_model(run):
    grid = model_report.as_grid(run.raw, run.model)
    qd, points = model_report.friction_points(run.model, grid)
    want_qd, want = rigid_points(run.model, grid)
    assert np.array_equal(qd, want_qd)
    scale = np.abs(grid.measured).max()
    assert np.abs(points - want).max() < 1e-10 * scale
    # Not the measured torque itself: the rigid part was taken out.
    assert np.abs(points - grid.measured[grid.scored]).max() > 1e-3 * scale


def overlaps(a, b) -> bool:
    """Whether the boxes (x0, y0, x1, y1) share more than an edge."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def test_no_tick_labels_overlap(run, tmp_path, monkeypatch):
    """Within each axis the tick labels do not overlap, nor do a panel's labels and title
    reach into another panel or out of the image."""
    saved = []
    monkeypatch.setattr(drawing, "save", lambda fig, path: saved.append(fig))
    model_report.write_figures(run.model, run.raw, tmp_path)
    assert len(saved) == 3
    for fig in saved:
        texts = fig.layout()
        shown = [i for i, ax in enumerate(fig.panels) if ax.axison]
        tight = {i: fig.panels[i].box for i in shown}
        for i in shown:
            for kind in ("xtick", "ytick"):
                ext = sorted(b for j, k, b in texts if j == i and k == kind)
                assert len(ext) >= 2, (i, kind)
                for a, b in itertools.pairwise(ext):
                    assert not overlaps(a, b), (a, b)
        for i, _, b in texts:
            a = tight[i]
            tight[i] = (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))
        for i in shown:
            x0, y0, x1, y1 = tight[i]
            assert 0 <= x0 < x1 <= fig.width, (i, tight[i])
            assert 0 <= y0 < y1 <= fig.height, (i, tight[i])
            for j in shown:
                if j > i:
                    assert not overlaps(tight[i], tight[j]), (i, j, tight[i], tight[j])


def test_report_is_written_first_and_embeds_its_figures(run, tmp_path, monkeypatch):
    seen = []
    real_save = drawing.save

    def check(fig, path):
        # report.md is on disk before any figure is drawn.
        seen.append((Path(path).name, (tmp_path / "report.md").is_file()))
        real_save(fig, path)

    monkeypatch.setattr(drawing, "save", check)
    written = run.report(tmp_path)
    assert seen
    assert all(first for _, first in seen)
    text = (tmp_path / "report.md").read_text()
    linked = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert linked == ["torque.png", "residual.png", "friction.png"]
    for name in linked:
        assert (tmp_path / name).is_file()
    assert {p.name for p in written} == {"report.md", *linked}


def deferred_report(run, folder: Path) -> list:
    """``write_report`` of ``run`` into ``folder`` with the figures deferred: their calls."""
    drawings: list = []
    model_report.write_report(run.model, folder, run.raw, drawings=drawings)
    return drawings


def pngs(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.glob("*.png"))


def test_report_defers_figures_to_the_caller(run, tmp_path):
    drawings = deferred_report(run, tmp_path)
    assert (tmp_path / "report.md").is_file()
    assert not pngs(tmp_path)
    for draw in drawings:
        draw()
    assert pngs(tmp_path) == ["friction.png", "residual.png", "torque.png"]


def test_deferred_figures_pickle_and_draw_from_the_copy(run, tmp_path):
    """The calls write_report defers carry their data, not closures: a figure server
    forked before the model existed draws them from a pickled copy (drawing.draw_all)."""
    import pickle

    copies = pickle.loads(pickle.dumps(deferred_report(run, tmp_path)))
    assert [d.__name__ for d in copies] == ["torque", "residual", "friction_curves"]
    for draw in copies:
        draw()
    assert pngs(tmp_path) == ["friction.png", "residual.png", "torque.png"]


# -------------------------------------------------------------------------- rounding


@pytest.mark.parametrize(
    ("x", "sigma", "text"),
    [
        (1.99388, 0.00509, "1.9939"),
        (-2.41194, 0.00439, "-2.4119"),
        (-0.000215232, 0.000591, "-0.00022"),
        (1234.56, 12.0, "1235"),
        (1234.56, 120.0, "1230"),
        (0.5, float("nan"), "0.5"),
        (3.14159265, None, "3.14159"),
        (-8.6e-06, 0.00136, "-9e-06"),
    ],
)
def test_values_are_rounded_to_their_sigma(x, sigma, text):
    assert model_report._with_sigma(x, sigma) == text


def test_report_rounds_what_the_log_record_measured(run):
    text = model_report.render(run.model, run.raw, log_report={"median_rate_hz": 100.0000000002})
    assert "- median_rate_hz: 100\n" in text
    # Every base parameter value has no more decimals than its σ's second digit.
    rows = [ln.split(" | ") for ln in text.splitlines() if ln.startswith("| ") and "`" in ln]
    assert rows
    for r in rows:
        value, sigma = r[2], r[3]
        if sigma == "–" or "e" in value or "e" in sigma:
            continue
        decimals = len(value.split(".")[1]) if "." in value else 0
        sd = float(sigma)
        assert decimals <= max(1 - int(np.floor(np.log10(sd))), 0), (value, sigma)


# ------------------------------------------------------------------------ laziness


def modules_after(code: str) -> set[str]:
    """Top-level modules imported by a fresh interpreter running ``code``."""
    script = textwrap.dedent(code) + textwrap.dedent(
        """
        import sys
        print(" ".join(sorted({m.split(".")[0] for m in sys.modules})))
        """
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    )
    return set(proc.stdout.split())


HEAVY = {"matplotlib", "PIL", "tqdm", "rosbags", "multiprocessing", "concurrent"}


def test_help_imports_nothing_heavy():
    loaded = modules_after(
        """
        import contextlib, io
        from prrrp.cli import main
        with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
            main(["--help"])
        with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
            main(["identify", "--help"])
        """
    )
    assert "prrrp" in loaded
    assert not loaded & HEAVY, loaded & HEAVY


def test_identifying_in_python_does_not_import_matplotlib():
    loaded = modules_after(
        """
        import numpy as np, prrrp
        robot = prrrp.SerialChain.paper()
        t = np.arange(0, 4, 0.01)
        q = 0.3 + 0.2 * np.sin(np.outer(t, np.arange(1, 6)))
        tau = robot.inverse_dynamics(q, np.gradient(q, t, axis=0),
                                     np.gradient(np.gradient(q, t, axis=0), t, axis=0))
        prrrp.identify_measurements(robot, {"t": t, "q": q, "tau": tau}, "ls")
        """
    )
    assert "matplotlib" not in loaded


def test_identify_draws_its_figures_without_matplotlib(tmp_path):
    """`prrrp identify` writes its three figures natively (prrrp.canvas): matplotlib (and
    PIL, its image writer) is never imported, nor a process forked to import it."""
    robot_file = Path(__file__).resolve().parents[2] / "tests" / "data" / "ur5_like_friction.toml"
    out = tmp_path / "out"
    loaded = modules_after(
        f"""
        import contextlib, io, os
        import numpy as np, prrrp
        from prrrp.cli import main
        robot = prrrp.SerialChain.from_file({str(robot_file)!r})
        t = np.arange(0.0, 6.0, 0.004)
        w = 2 * np.pi * 0.3 * np.arange(1, 4)
        a = np.random.default_rng(3).normal(0, 0.4, (robot.dof, 3)) / np.arange(1, 4)
        s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
        q, qd, qdd = s @ a.T, (c * w) @ a.T, -(s * w**2) @ a.T
        tau = robot.inverse_dynamics(q, qd, qdd)
        n = robot.dof
        names = [*(f"q{{j + 1}}" for j in range(n)), *(f"tau{{j + 1}}" for j in range(n))]
        head = ",".join(["t", *names])
        np.savetxt({str(tmp_path / "log.csv")!r}, np.column_stack([t, q, tau]), delimiter=",",
                   header=head, comments="")
        forks = []
        real_fork = os.fork
        os.fork = lambda: forks.append(1) or real_fork()
        argv = ["identify", {str(tmp_path / "log.csv")!r}, "--robot", {str(robot_file)!r},
                "--out", {str(out)!r}, "--coulomb-scale", "0"]
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(argv) == 0
        assert not forks, forks
        """
    )
    assert sorted(p.name for p in out.glob("*.png")) == [
        "friction.png",
        "residual.png",
        "torque.png",
    ]
    for name in ("friction.png", "residual.png", "torque.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not loaded & {"matplotlib", "PIL"}, loaded & {"matplotlib", "PIL"}


# ------------------------------------------------------------------- paper's study


def test_study_figures_labelled_and_showing_what_they_say(tmp_path, monkeypatch):
    from test_cli import fake_results

    from prrrp import paper, plots

    saved = {}
    monkeypatch.setattr(drawing, "save", lambda fig, path: saved.setdefault(Path(path).name, fig))
    results = fake_results()
    plots.write_all(results, tmp_path)
    assert set(saved) == set(plots.FIGURES)
    for name, fig in saved.items():
        for ax in (a for a in fig.axes if a.axison):
            assert UNIT.search(ax.get_ylabel()) or "(" in ax.get_ylabel(), (name, ax)
        # Legends sit in the figure's margin, never on a panel.
        assert all(ax.get_legend() is None for ax in fig.axes) or name == "lambda_bars.png"
    # Fig. 7: each method's position error against the truth, per joint.
    val = results["validation"]
    q_true = np.asarray(val["q_true"])
    fig7 = saved["fig7_validation.png"]
    for j, ax in enumerate(fig7.axes):
        drawn = {ln.get_label(): ln.get_ydata() for ln in ax.get_lines()}
        for m in val["methods"]:
            error = np.asarray(m["q"])[:, j] - q_true[:, j]
            assert np.allclose(drawn[paper.METHOD_LABELS[m["method"]]], error), (j, m)
    # Fig. 8: λ8's +50 % variation is non-physical (None): marked, not dropped silently;
    # the unvaried model's RMS of exactly 0 is not put on the log axis.
    fig8 = saved["fig8_sensitivity.png"]
    panel8 = fig8.axes[7]
    marks = [ln for ln in panel8.get_lines() if ln.get_label() == "non-physical λ (skipped)"]
    assert len(marks) == 1
    assert np.allclose(marks[0].get_xdata(), [50.0])
    fig8.canvas.draw()
    for ax in fig8.axes:
        assert ax.get_yscale() == "log"
        labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
        assert labels
        assert not any(re.fullmatch(r"\$?(\\mathdefault\{)?0\}?\$?", s) for s in labels), labels
    # Fig. 5's time axis says it is the estimator's time over passes of the data.
    assert "estimation time (s)" in saved["fig5_hopfield.png"]._supxlabel.get_text()


def test_drawing_leaves_the_users_pyplot_backend_alone():
    """A notebook's backend stays what it was after a report (figures on Agg canvases)."""
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            textwrap.dedent(
                """
                import tempfile
                from pathlib import Path
                import matplotlib
                matplotlib.use("svg")
                from prrrp import drawing
                fig, axes = drawing.figure(1, 2)
                axes[0, 0].plot([0, 1], [0, 1])
                with tempfile.TemporaryDirectory() as d:
                    drawing.save(fig, Path(d) / "a.png")
                    assert (Path(d) / "a.png").read_bytes()[:4] == b"\\x89PNG"
                print(matplotlib.get_backend())
                """
            ),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    assert proc.stdout.strip() == "svg"
