"""The ``prrrp`` command line end to end: reproduce, simulate → identify, bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import prrrp
from prrrp import cli, csvio, outdir, paper, plots, report

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SCHEMA_KEYS = {
    "schema_version",
    "seed",
    "truth",
    "initial_guess",
    "excitation",
    "estimation_data",
    "estimates",
    "validation",
    "sensitivity",
    "timings_s",
}


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(err: str, *needles: str) -> None:
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("prrrp: error: ")
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


# ------------------------------------------------------------------------- fake study result


def fake_results() -> dict:
    """A small dict following the study schema (version 1), built from the real robot."""
    rng = np.random.default_rng(1)
    truth = prrrp.Robot.paper().base_parameters()
    t = np.arange(50) * 0.02
    q = np.column_stack([0.1 * np.sin((k + 1) * t) for k in range(5)])

    def noisy(x: np.ndarray, s: float) -> list:
        return (x + s * rng.standard_normal(x.shape)).tolist()

    estimates = []
    for m in paper.METHODS:
        lam = truth * (1 + 0.01 * rng.standard_normal(8))
        ls = m == "least_squares"
        estimates.append(
            {
                "method": m,
                "lambda": lam.tolist(),
                "relative_error_percent": (100 * (lam - truth) / truth).tolist(),
                "std": (0.001 * truth).tolist() if ls else None,
                "rsd_percent": [0.1] * 8 if ls else None,
                "cond": 12.5 if ls else None,
                "sigma2": 0.01 if ls else None,
                "history": None
                if ls
                else {"t": t.tolist(), "lambda": np.tile(lam, (len(t), 1)).tolist()},
            }
        )
    factors = [0.5, 1.0, 1.5]
    return {
        "schema_version": 1,
        "seed": 0,
        "truth": truth.tolist(),
        "initial_guess": (0.5 * truth).tolist(),
        "excitation": {
            "cond_initial": 80.0,
            "cond_final": 20.0,
            "evaluations": 100,
            "limits_satisfied": True,
            "samples": 50,
            "duration": 1.0,
        },
        "estimation_data": {
            "t": t.tolist(),
            "q_ref": q.tolist(),
            "q": noisy(q, 1e-3),
            "q_measured": noisy(q, 2e-3),
            "tau_measured": noisy(q, 1.0),
        },
        "estimates": estimates,
        "validation": {
            "t": t.tolist(),
            "q_ref": q.tolist(),
            "q_true": q.tolist(),
            "methods": [
                {
                    "method": m,
                    "q": noisy(q, 1e-3),
                    "rms": [1e-4] * 5,
                    "rsd": [1e-3] * 5,
                    "ai": [0.9999] * 5,
                    "torque_rms": [0.1] * 5,
                    "torque_relative_percent": [1.0] * 5,
                }
                for m in paper.METHODS
            ],
        },
        "sensitivity": {
            "factors": factors,
            "ranges": [[0.5 * x, 1.5 * x] for x in truth],
            "rms": [[[0.01] * 5, [0.0] * 5, None if i == 7 else [0.02] * 5] for i in range(8)],
        },
        "timings_s": {"excitation": 1.0, "simulation": 0.5, "total": 1.5},
    }


def test_report_renders_every_table_from_a_schema_dict() -> None:
    text = report.render(fake_results())
    for title in (
        "Table 4",
        "Table 5",
        "Table 6",
        "Relative parameter errors",
        "Torque prediction",
    ):
        assert title in text
    # The paper's printed values are there next to ours.
    assert "4.2969" in text
    assert "0.0859" in text  # EKF λ7 in Table 4
    assert "6.4004" in text  # λ1 max in Table 6
    assert "slowest stage: excitation" in text


def test_figures_are_png_files(tmp_path: Path) -> None:
    paths = plots.write_all(fake_results(), tmp_path)
    assert sorted(p.name for p in paths) == sorted(plots.FIGURES)
    for p in paths:
        assert p.read_bytes()[:8] == PNG_MAGIC, p


# ----------------------------------------------------------------------------------- help


def test_python_m_prrrp_help() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "prrrp", "--help"], capture_output=True, text=True, check=False
    )
    assert proc.returncode == 0, proc.stderr
    for command in ("reproduce", "simulate", "identify"):
        assert command in proc.stdout


@pytest.mark.parametrize("command", ["reproduce", "simulate", "identify"])
def test_every_subcommand_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main([command, "--help"])
    assert exc.value.code == 0
    assert f"usage: prrrp {command}" in capsys.readouterr().out


def test_unknown_method_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main(["identify", "x.csv", "--method", "lsq"])
    assert exc.value.code == cli.EXIT_USAGE
    assert_one_line_error(capsys.readouterr().err, "invalid choice", "--help")


@pytest.mark.parametrize(
    "argv",
    [
        ["identify", "x.csv", "--out", ""],
        ["simulate", "--out", " "],
        ["reproduce", "--out", ""],
        ["identify"],
        ["identify", "x.csv", "--nope"],
    ],
)
def test_usage_errors_are_one_line(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == cli.EXIT_USAGE
    assert_one_line_error(capsys.readouterr().err)


# ------------------------------------------------------------------------------ bad input


def measurement_rows(n: int = 200) -> tuple[list[str], np.ndarray]:
    """Gravity-only data at rest (q̇ = q̈ = 0) with the exact torques of the paper robot."""
    robot = prrrp.Robot.paper()
    t = 0.02 * np.arange(n)
    q = np.tile([0.1, 0.2, 0.3, 0.4, 0.05], (n, 1))
    zeros = np.zeros_like(q)
    tau = robot.inverse_dynamics(q, zeros, zeros)
    header = list(csvio.ALL_COLUMNS)
    return header, np.hstack([t[:, None], q, tau, zeros, zeros])


def write_csv(path: Path, header: list[str], table: np.ndarray, edit=None) -> Path:
    lines = [",".join(header)] + [",".join(repr(float(x)) for x in row) for row in table]
    if edit is not None:
        lines = edit(lines)
    path.write_text("\n".join(lines) + "\n")
    return path


def test_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["identify", str(tmp_path / "nope.csv")], capsys)
    assert code == cli.EXIT_USAGE
    assert_one_line_error(err, "nope.csv", "no such file")


def test_endless_file_is_refused_at_once(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["identify", "/dev/zero"], capsys)
    assert code == cli.EXIT_USAGE
    assert_one_line_error(err, "not a regular file")


def test_byte_order_mark_is_accepted(tmp_path: Path) -> None:
    header, table = measurement_rows()
    path = write_csv(tmp_path / "bom.csv", header, table)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    data = csvio.read_measurements(path)
    np.testing.assert_array_equal(data["t"], table[:, 0])


def test_velocities_without_accelerations_are_an_error(tmp_path: Path) -> None:
    header, table = measurement_rows()
    keep = [i for i, h in enumerate(header) if not h.startswith("qdd")]
    path = write_csv(tmp_path / "qd.csv", [header[i] for i in keep], table[:, keep])
    with pytest.raises(csvio.InputError, match=r"qd1\.\.qd5 given without qdd1\.\.qdd5"):
        csvio.read_measurements(path)


def test_missing_column_is_named_with_the_expected_list(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    header, table = measurement_rows()
    keep = [k for k, h in enumerate(header) if h != "tau5"]
    path = write_csv(tmp_path / "d.csv", [header[k] for k in keep], table[:, keep])
    code, _, err = run(["identify", str(path)], capsys)
    assert code == cli.EXIT_USAGE
    assert_one_line_error(err, "missing column 'tau5'", "expected t, q1..q5, tau1..tau5")


def test_misspelt_column_suggests_the_closest(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    header, table = measurement_rows()
    header[header.index("tau3")] = "tua3"
    path = write_csv(tmp_path / "d.csv", header, table)
    code, _, err = run(["identify", str(path)], capsys)
    assert code == cli.EXIT_USAGE
    assert_one_line_error(err, "unknown column 'tua3'", "did you mean 'tau3'", "expected")


@pytest.mark.parametrize(
    ("cell", "needle"), [("abc", "'abc' is not a number"), ("nan", "nan is not finite")]
)
def test_bad_cell_names_line_and_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], cell: str, needle: str
) -> None:
    header, table = measurement_rows()
    col = header.index("q3")

    def edit(lines: list[str]) -> list[str]:
        cells = lines[10].split(",")
        cells[col] = cell
        lines[10] = ",".join(cells)
        return lines

    path = write_csv(tmp_path / "d.csv", header, table, edit)
    code, _, err = run(["identify", str(path)], capsys)
    assert code == cli.EXIT_USAGE
    assert_one_line_error(err, "line 11", "column 'q3'", needle)


def test_non_increasing_time(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    header, table = measurement_rows()
    table[50, 0] = table[49, 0]
    path = write_csv(tmp_path / "d.csv", header, table)
    code, _, err = run(["identify", str(path)], capsys)
    assert code == cli.EXIT_USAGE
    assert_one_line_error(err, "time is not strictly increasing", "data row 51")


def test_too_few_samples(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    header, table = measurement_rows(5)
    path = write_csv(tmp_path / "d.csv", header, table)
    code, _, err = run(["identify", str(path)], capsys)
    assert code == cli.EXIT_USAGE
    assert_one_line_error(err, "too few samples (5)")


@pytest.mark.skipif(not hasattr(prrrp, "least_squares"), reason="no least_squares binding")
def test_unexciting_data_is_rank_deficient_and_keeps_old_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    header, table = measurement_rows()
    path = write_csv(tmp_path / "d.csv", header, table)
    out = tmp_path / "results.json"
    out.write_text("previous results\n")
    code, _, err = run(["identify", str(path), "--out", str(out)], capsys)
    assert code == cli.EXIT_USAGE
    assert_one_line_error(err, "rank deficient", "cond(W) = ")
    assert out.read_text() == "previous results\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.csv", "results.json"]


# ------------------------------------------------------------------ simulate → identify


needs_simulation = pytest.mark.skipif(
    not all(
        hasattr(prrrp, f)
        for f in ("optimise_excitation", "simulate_closed_loop", "preprocess", "least_squares")
    ),
    reason="simulation bindings not available",
)


@needs_simulation
def test_simulate_identify_round_trip(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The previous release's closed-form spellings (deprecated, kept for one release)."""
    data, val, out = tmp_path / "data.csv", tmp_path / "val.csv", tmp_path / "lam.json"
    code, stdout, err = run(["simulate", "--out", str(data), "--seed", "3"], capsys)
    assert code == 0, err
    assert stdout.startswith(f"results in {data}")
    # The previous release's spelling (a CSV file, the closed form): kept, with a notice.
    assert err.startswith("prrrp: deprecated: "), err
    assert f"use `prrrp simulate --seed 3 --robot paper --out {tmp_path / 'data'}`" in err
    code, _, err = run(["simulate", "--out", str(val), "--seed", "4"], capsys)
    assert code == 0, err
    assert data.read_text().splitlines()[0] == ",".join(csvio.REQUIRED_COLUMNS)

    code, stdout, err = run(
        ["identify", str(data), "--method", "ls", "--validate", str(val), "--out", str(out)],
        capsys,
    )
    assert code == 0, err
    assert err.startswith("prrrp: deprecated: "), err
    assert "--robot paper --out" in err
    assert "cond(W)" in stdout
    result = json.loads(out.read_text())
    (ls,) = result["estimates"]
    truth = prrrp.Robot.paper().base_parameters()
    # The noise of the default sensor model leaves every λ_i within 2 % of the truth.
    np.testing.assert_allclose(ls["lambda"], truth, rtol=0.02)
    # Validation: the estimate predicts the other run's torques within its noise level.
    (v,) = result["validation"]["methods"]
    assert np.all(np.asarray(v["torque_rms"]) < 3 * np.asarray(cli.DEFAULT_TAU_NOISE))


@needs_simulation
def test_identify_defaults_to_joint_weighted_least_squares(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Without --method the paper's arm gets least squares weighted by each joint's
    residual noise; `all` runs it first, then the paper's four. With F1's noise in N and the
    wrist's in N·m (the default sensor model at 3×), weighting is the best linear unbiased
    estimate: each σ_i is at most the ordinary fit's (Gauss–Markov), both estimates cover
    the truth within 4σ, and the weighted one is within 2 %."""
    data, out, out_all = tmp_path / "d.csv", tmp_path / "w.json", tmp_path / "all.json"
    code, _, err = run(["simulate", "--out", str(data), "--seed", "5", "--noise", "3"], capsys)
    assert code == 0, err
    code, stdout, err = run(["identify", str(data), "--out", str(out)], capsys)
    assert code == 0, err
    assert "Weighted LS" in stdout
    (wls,) = json.loads(out.read_text())["estimates"]
    assert wls["method"] == "weighted_least_squares"
    code, _, err = run(["identify", str(data), "--method", "all", "--out", str(out_all)], capsys)
    assert code == 0, err
    estimates = json.loads(out_all.read_text())["estimates"]
    assert [e["method"] for e in estimates] == ["weighted_least_squares", *paper.METHODS]
    ols = estimates[1]
    truth = prrrp.Robot.paper().base_parameters()
    for e in (wls, ols):
        assert np.all(np.abs(np.asarray(e["lambda"]) - truth) <= 4 * np.asarray(e["std"]))
    np.testing.assert_allclose(wls["lambda"], truth, rtol=0.02)
    # 5 % slack: both σ are themselves estimated from the residuals.
    assert np.all(np.asarray(wls["std"]) <= 1.05 * np.asarray(ols["std"]))


def test_simulate_longer_than_the_excitation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--duration 30` with the 10 s excitation: 30 s of the excitation played forward and
    backward (1501 rows at 50 Hz), from which least squares is within 2 % of the truth as
    on the 10 s recording (the reflection is C², so preprocessing sees no jump)."""
    data = tmp_path / "long.csv"
    code, _, err = run(["simulate", "--out", str(data), "--duration", "30"], capsys)
    assert code == 0, err
    table = csvio.read_measurements(data)
    assert len(table["t"]) == 1501
    assert table["t"][-1] == pytest.approx(30.0)
    truth = prrrp.Robot.paper().base_parameters()
    d = prrrp.preprocess(table["t"], table["q"], table["tau"])
    ls = prrrp.least_squares(d["q"], d["qd"], d["qdd"], d["tau"])
    assert np.abs(ls.lam / truth - 1).max() < 0.02


# ----------------------------------------------------------------------------- reproduce


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not hasattr(prrrp, "run_study"):
        pytest.skip("prrrp.run_study not available")
    out = tmp_path_factory.mktemp("reproduce") / "out"
    # The study takes ~10-30 s: run once for all the checks below.
    assert cli.main(["reproduce", "--out", str(out)]) == 0
    return out


def test_reproduce_writes_the_schema(reproduced: Path) -> None:
    results = json.loads((reproduced / "results.json").read_text())
    assert set(results) >= SCHEMA_KEYS
    assert [e["method"] for e in results["estimates"]] == list(paper.METHODS)


def test_reproduce_writes_the_report_and_figures(reproduced: Path) -> None:
    text = (reproduced / "report.md").read_text()
    for title in ("Table 4", "Table 5", "Table 6", "Stage timings", "4.2969"):
        assert title in text
    for name in plots.FIGURES:
        assert (reproduced / name).read_bytes()[:8] == PNG_MAGIC, name
    assert [p.name for p in reproduced.iterdir() if p.name.startswith(".")] == [outdir.MARKER]
    assert not [p for p in reproduced.parent.iterdir() if ".prrrp-" in p.name]
