"""The Monte-Carlo benchmark (issue 17): metrics against independent references, paired
noise scaling, determinism across worker counts, worker deaths and timeouts that lose
only their case, bad input, the output folder and the command line. The Dask engine is
tested in test_benchmark_dask.py."""

from __future__ import annotations

import concurrent.futures as cf
import csv
import dataclasses
import importlib.metadata
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import prrrp
from prrrp.cli import main
from prrrp.montecarlo import cases as bc
from prrrp.montecarlo import runner

URDF = str(
    importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots/panda_description/urdf/panda.urdf"
    )
)
NUMBERS = (
    *bc.ERROR_COLUMNS,
    "converged",
    "epochs",
    "samples",
    "status",
)


def numbers(rows):
    """Everything but the wall times (which differ run to run)."""
    return [(r["seed"], r["noise"], r["rate"], r["method"], *(r[k] for k in NUMBERS)) for r in rows]


# ---------------------------------------------------------------------------- metrics


def test_parameter_errors_by_hand() -> None:
    truth = np.array([4.0, -0.5, 0.0, 0.02])
    # Relative perturbations 1 %, -3 %, (zero truth: off by 0.1), 10 %.
    est = np.array([4.04, -0.485, 0.1, 0.022])
    e = bc.parameter_errors(est, truth)
    assert e["max_param_error_percent"] == pytest.approx(10.0)
    assert e["median_param_error_percent"] == pytest.approx(3.0)
    norm = np.sqrt(0.04**2 + 0.015**2 + 0.1**2 + 0.002**2) / np.sqrt(16 + 0.25 + 0.0004)
    assert e["param_error_norm_percent"] == pytest.approx(100 * norm)


def test_converged_reads_the_model_attribute() -> None:
    class Model:
        converged = False

    assert bc.converged(Model()) is False
    assert bc.converged(object()) is True


def test_noise_free_case_recovers_the_simulating_robot() -> None:
    """With no sensor noise the identification error is only the preprocessing's (filter,
    differences): least squares must land on the simulating robot's base parameters
    (a wrong truth would be off by far more) and predict the validation torques."""
    (row,) = bc.run_case(bc.Case(seed=5, noise=0.0, rate=200.0, methods=("ls",)))
    assert row["status"] == "ok", row
    assert row["param_error_norm_percent"] < 0.05
    assert row["torque_rms_relative_percent"] < 0.2
    assert row["converged"] is True


def test_paper_truth_is_the_chain_base_parameters() -> None:
    names, truth = bc._truth(None)
    # λ1 = m1 + m2 + m3 + m4 and λ8 = m5 of the paper (Table 3) are base parameters of
    # the chain form too (notes/paper.md).
    assert names[0] == "m1"
    assert names[-1] == "m5"
    assert truth[0] == pytest.approx(1.228 + 3 * 1.023)
    assert truth[-1] == pytest.approx(0.5114)


def test_error_grows_with_the_noise_on_paired_seeds() -> None:
    """The noise realisation of a seed is the same at every scale, so the least-squares
    error (linear in the noise, small bias) scales with it: about 3× from ×1 to ×3."""
    ratios = []
    for seed in range(4):
        low, high = (
            bc.run_case(bc.Case(seed=seed, noise=n, rate=100.0, methods=("ls",)))[0]
            for n in (1.0, 3.0)
        )
        ratios.append(high["param_error_norm_percent"] / low["param_error_norm_percent"])
    assert 2.5 < np.median(ratios) < 3.5, ratios


def test_panda_case() -> None:
    robot = prrrp.load_robot(URDF, tip="panda_link8")
    case = bc.Case(
        seed=0,
        noise=1.0,
        rate=100.0,
        methods=("ls", "rls"),
        robot_json=robot.to_json(),
        excitation_evaluations=50,
    )
    rows = bc.run_case(case)
    assert [r["status"] for r in rows] == ["ok", "ok"], rows
    # LS and one-pass RLS solve the same problem.
    assert rows[0]["param_error_norm_percent"] == pytest.approx(
        rows[1]["param_error_norm_percent"], rel=1e-3
    )
    assert rows[0]["torque_rms_relative_percent"] < 5


# ---------------------------------------------------------------------------- execution


def test_callable_module_and_determinism_across_worker_counts() -> None:
    kwargs = {"seeds": [3, 1], "noise": [1, 2], "rates": [50], "methods": "ls,hopfield,ekf"}
    one = prrrp.benchmark(workers=1, progress=False, **kwargs)
    two = prrrp.benchmark(workers=2, progress=False, **kwargs)
    threads = prrrp.benchmark(executor=cf.ThreadPoolExecutor(2), progress=False, **kwargs)
    direct = [
        row for c in bc.grid(kwargs["methods"], [1, 2], [50], [3, 1]) for row in bc.run_case(c)
    ]
    assert numbers(one.rows) == numbers(two.rows) == numbers(threads.rows) == numbers(direct)
    assert [(r["seed"], r["noise"]) for r in one.rows[::3]] == [(3, 1), (3, 2), (1, 1), (1, 2)]
    assert all(r["status"] == "ok" for r in one.rows)
    assert two.stats.parallelism == 2
    assert two.stats.failed_cases == 0


def small_grid(**kwargs):
    return bc.grid("ls", [1.0], [50.0], 4, excitation_evaluations=100, **kwargs)


def test_the_pool_is_no_larger_than_the_grid() -> None:
    # `--workers 100000` on a 4-case grid was recorded as 100000 workers in results.json.
    cases = small_grid()
    _, stats = runner.run_cases(cases, workers=100_000, progress=False)
    assert stats.parallelism == len(cases) == 4


def test_a_killed_worker_loses_only_its_case() -> None:
    cases = small_grid()
    cases[1] = dataclasses.replace(cases[1], fault="exit")  # dies on every attempt
    cases[2] = dataclasses.replace(cases[2], fault="exit-once")  # dies, then succeeds
    rows, stats = runner.run_cases(cases, workers=2, progress=False, timeout=60)
    status = [(r["seed"], r["status"], r["attempts"]) for r in rows]
    assert status == [(0, "ok", 1), (1, "failed", 2), (2, "ok", 2), (3, "ok", 1)]
    assert "died" in rows[1]["error"]
    assert stats.failed_cases == 1
    assert stats.restarts >= 2
    # The surviving cases have the numbers of an undisturbed run.
    clean, _ = runner.run_cases(small_grid(), workers=1, progress=False)
    assert numbers([rows[0], rows[2], rows[3]]) == numbers([clean[0], clean[2], clean[3]])


def test_a_hanging_case_times_out_and_the_rest_completes() -> None:
    cases = small_grid()
    cases[0] = dataclasses.replace(cases[0], fault="hang")
    t0 = time.monotonic()
    rows, _stats = runner.run_cases(cases, workers=2, progress=False, timeout=4.0, retries=1)
    assert time.monotonic() - t0 < 40
    assert rows[0]["status"] == "failed"
    assert "timed out" in rows[0]["error"]
    assert rows[0]["attempts"] == 2
    assert all(r["status"] == "ok" for r in rows[1:])


def test_progress_callback_streams_every_case() -> None:
    seen = []
    runner.run_cases(small_grid(), workers=2, progress=lambda d, t, f: seen.append((d, t, f)))
    assert [d for d, _, _ in seen] == [1, 2, 3, 4]
    assert {t for _, t, _ in seen} == {4}


# ---------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"methods": "ls,lsq"}, "unknown method 'lsq'"),
        ({"methods": []}, "empty grid"),
        ({"seeds": []}, "empty grid"),
        ({"seeds": 0}, "empty grid"),
        ({"noise": []}, "empty grid"),
        ({"rates": []}, "empty grid"),
        ({"noise": [-1]}, "noise scale"),
        ({"noise": [float("nan")]}, "noise scale"),
        ({"rates": [0]}, "sampling rate"),
        ({"rates": [1e9]}, "samples per case"),
        ({"seeds": [-3]}, "seed"),
        ({"seeds": 10**8}, "more than"),
        ({"workers": 0}, "workers"),
        ({"timeout": 0}, "timeout"),
        ({"executor": object()}, "not a concurrent.futures.Executor"),
        ({"robot": 42}, "robot must be"),
    ],
)
def test_bad_input_is_a_typed_error(kwargs, message) -> None:
    with pytest.raises(prrrp.InvalidInputError, match=message):
        prrrp.benchmark(**{"seeds": 1, "progress": False, **kwargs})


def test_an_executor_that_cannot_start_is_a_typed_error() -> None:
    dead = cf.ThreadPoolExecutor(1)
    dead.shutdown()
    with pytest.raises(prrrp.InvalidInputError, match="failed to start"):
        prrrp.benchmark(seeds=1, executor=dead, progress=False)

    class NoWorkers(cf.Executor):
        def submit(self, fn, /, *args, **kwargs):
            return cf.Future()  # never runs

    with pytest.raises(prrrp.InvalidInputError, match="ran no task"):
        runner.run_cases(small_grid(), NoWorkers(), start_timeout=0.5, progress=False)


# ---------------------------------------------------------------------------- output


def test_save_writes_csv_json_report_and_figures(tmp_path: Path) -> None:
    result = prrrp.benchmark(
        seeds=2, noise=[1, 3], rates=[50, 100], methods="ls,adaline", workers=2, progress=False
    )
    out = tmp_path / "bench"
    result.save(out)
    with (out / "results.csv").open() as f:
        table = list(csv.DictReader(f))
    required = {
        "seed",
        "noise",
        "rate",
        "method",
        "max_param_error_percent",
        "torque_rms_relative_percent",
        "converged",
        "seconds",
    }
    assert required <= set(table[0])
    assert len(table) == 2 * 2 * 2 * 2
    for row, original in zip(table, result.rows, strict=True):
        assert float(row["max_param_error_percent"]) == original["max_param_error_percent"]
        assert row["converged"] == "true"
    doc = json.loads((out / "results.json").read_text())
    assert doc["rows"] == json.loads(json.dumps(result.rows))
    assert len(doc["summary"]) == 2 * 2 * 2
    report = (out / "report.md").read_text()
    for name in ("errors_by_noise.png", "errors_vs_rate.png", "time_per_method.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"
        assert f"]({name})" in report
    assert "| adaline | 3 | 100 |" in report


def test_cli_runs_and_reports(tmp_path: Path, capsys) -> None:
    out = tmp_path / "b"
    code = main(
        [
            "benchmark",
            "--methods",
            "ls,ekf",
            "--seeds",
            "2",
            "--noise",
            "1,2",
            "--rates",
            "50",
            "--workers",
            "2",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "results in" in text
    assert "ekf" in text
    assert (out / "results.csv").read_text().count("\n") == 1 + 2 * 2 * 2


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--methods", "ls,nope"], "unknown method 'nope'"),
        (["--noise", "a,b"], "not a comma-separated list"),
        (["--seeds", "0"], "must be at least 1"),
        (["--workers", "2", "--dask", "x"], "not allowed with"),
        (["--robot", "/nonexistent.urdf"], "nonexistent"),
    ],
)
def test_cli_bad_input_is_one_line_and_exit_2(tmp_path: Path, capsys, argv, message) -> None:
    try:
        code = main(["benchmark", *argv, "--out", str(tmp_path / "x")])
    except SystemExit as e:  # argparse's own checks
        code = e.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_cli_ctrl_c_exits_130_without_output(tmp_path: Path) -> None:
    out = tmp_path / "b"
    child = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "prrrp",
            "benchmark",
            "--seeds",
            "400",
            "--workers",
            "2",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        time.sleep(6.0)
        assert child.poll() is None, child.communicate()
        child.send_signal(signal.SIGINT)
        _, err = child.communicate(timeout=30)
    finally:
        child.kill()
    assert child.returncode == 130, err
    assert "interrupted" in err
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".b.")]


# ----------------------------------------------------------------- results before figures


def _tiny(**kwargs):
    return prrrp.benchmark(
        seeds=2, methods="ls", workers=1, progress=False, excitation_evaluations=60, **kwargs
    )


def test_a_failing_figure_keeps_the_results(tmp_path: Path, monkeypatch) -> None:
    """Issue 25: a benchmark ended after 258 s with nothing written because one figure
    failed. The results are written first; the figure's failure is reported."""
    from prrrp.montecarlo import report

    result = _tiny()

    def broken(rows, path):
        raise FileNotFoundError(2, "No such file or directory", str(path))

    monkeypatch.setattr(report, "errors_by_noise", broken)
    out = tmp_path / "bench"
    result.save(out)
    assert set(result.figure_errors) == {"errors_by_noise.png"}
    table = list(csv.DictReader((out / "results.csv").open()))
    assert len(table) == 2
    assert json.loads((out / "results.json").read_text())["rows"] == json.loads(
        json.dumps(result.rows)
    )
    text = (out / "report.md").read_text()
    assert "`errors_by_noise.png` could not be drawn (FileNotFoundError" in text
    assert not (out / "errors_by_noise.png").exists()
    assert (out / "errors_vs_rate.png").is_file()


def test_cli_reports_a_failing_figure_and_exits_0(tmp_path: Path, monkeypatch, capsys) -> None:
    from prrrp.montecarlo import report

    def broken(rows, path):
        raise RuntimeError("the backend broke")

    monkeypatch.setattr(report, "time_per_method", broken)
    out = tmp_path / "b"
    argv = ["benchmark", "--methods", "ls", "--seeds", "1", "--workers", "1"]
    code = main([*argv, "--excitation-evaluations", "60", "--out", str(out)])
    assert code == 0
    assert "figure time_per_method.png could not be drawn (RuntimeError: the backend broke)" in (
        capsys.readouterr().err
    )
    assert (out / "results.csv").is_file()


def test_cli_rescues_the_results_when_out_cannot_be_written(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    from prrrp import outdir

    def refuse(out, build):
        raise PermissionError(13, "Permission denied", str(out))

    monkeypatch.setattr(outdir, "write_dir", refuse)
    monkeypatch.chdir(tmp_path)
    argv = ["benchmark", "--methods", "ls", "--seeds", "1", "--workers", "1"]
    code = main([*argv, "--excitation-evaluations", "60", "--out", "b"])
    assert code == 1
    err = capsys.readouterr().err
    assert "could not be written there (Permission denied" in err
    rescued = list(tmp_path.glob("b-results-*.json"))
    assert len(rescued) == 1
    assert str(rescued[0].name) in err
    assert len(json.loads(rescued[0].read_text())["rows"]) == 1


def test_cli_exits_1_when_every_case_failed(tmp_path: Path, monkeypatch, capsys) -> None:
    """Every case's worker dies (the test hook): the results (all failed) are written, the
    exit code says the run failed."""
    import prrrp.montecarlo as mc

    real_grid = mc.grid

    def dying(*args, **kwargs):
        return [dataclasses.replace(c, fault="exit") for c in real_grid(*args, **kwargs)]

    monkeypatch.setattr(mc, "grid", dying)
    out = tmp_path / "b"
    argv = ["benchmark", "--methods", "ls", "--seeds", "1", "--workers", "1", "--out", str(out)]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "every case failed (1)" in err
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert [r["status"] for r in rows] == ["failed"]


def test_excitation_budget_is_a_grid_axis_with_its_effect_reported(tmp_path: Path) -> None:
    result = prrrp.benchmark(
        seeds=3,
        methods="ls",
        workers=2,
        progress=False,
        excitation_evaluations=[60, 300],
    )
    assert result.config["excitation_evaluations"] == [60, 300]
    assert [r["excitation_evaluations"] for r in result.rows] == [60, 300] * 3
    assert all(r["status"] == "ok" and r["excitation_cond"] >= 1 for r in result.rows)
    result.save(tmp_path / "b")
    text = (tmp_path / "b" / "report.md").read_text()
    section = text[text.index("## Excitation budget") :]
    for budget in (60, 300):
        rows = [r for r in result.rows if r["excitation_evaluations"] == budget]
        cond = np.median([r["excitation_cond"] for r in rows])
        err = np.median([r["max_param_error_percent"] for r in rows])
        assert f"| {budget} | {cond:.3g} | {err:.3g} |" in section
    header = (tmp_path / "b" / "results.csv").read_text().splitlines()[0].split(",")
    assert "excitation_evaluations" in header
    assert "excitation_cond" in header


def test_cli_excitation_evaluations_flag(tmp_path: Path, capsys) -> None:
    """Too small a budget finds no feasible excitation: every case fails, the run says so
    (exit 1) and the results name the error."""
    out = tmp_path / "b"
    argv = ["benchmark", "--methods", "ls", "--seeds", "1", "--workers", "1", "--out", str(out)]
    assert main([*argv, "--excitation-evaluations", "5"]) == 1
    assert "InfeasibleError" in capsys.readouterr().err
    assert "| 5 |" in (out / "report.md").read_text()
    with pytest.raises(SystemExit) as exit_info:  # argparse's own check
        main([*argv, "--excitation-evaluations", "0"])
    assert exit_info.value.code == 2
    assert "must be at least 1" in capsys.readouterr().err
