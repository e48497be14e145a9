"""One command per job (issue 30): `excite`, `simulate` and `identify` each take one `--out`
meaning, a folder; without `--robot` the robot is the built-in paper arm through the same
path as any robot; the previous release's spellings still work, and say what to write."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

import prrrp
from prrrp import cli, csvio


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def suggestion(err: str) -> list[str]:
    """The command a deprecation notice says to write instead: one line on stderr, the last,
    naming the command between backticks."""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("prrrp: deprecated: "), err
    match = re.search(r"use `prrrp ([^`]*)`", lines[0])
    assert match, lines[0]
    return shlex.split(match.group(1))


def test_the_default_robot_is_the_paper_arm_through_the_general_path(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without --robot: excite designs for the paper's 5 joints into DIR/trajectory.csv,
    simulate writes DIR/data.csv, identify writes DIR/model.json that `prrrp predict` uses
    (the model is the one `--robot paper` gives, bit for bit), track tracks the paper arm."""
    monkeypatch.chdir(tmp_path)
    code, _, err = run(["excite", "--seed", "2", "--out", "traj"], capsys)
    assert code == 0, err
    assert err == ""
    traj = csvio.read_table(tmp_path / "traj" / "trajectory.csv", 5, need_tau=False)
    assert traj["q"].shape[1] == 5

    code, stdout, err = run(["simulate", "--out", "sim", "--seed", "2"], capsys)
    assert code == 0, err
    assert err == ""
    assert stdout.startswith("results in sim/data.csv")
    files = sorted(p.name for p in (tmp_path / "sim").iterdir())
    assert files == [".prrrp-output", "data.csv", "trajectory.csv"]
    data = csvio.read_measurements(tmp_path / "sim" / "data.csv")
    assert data["q"].shape[1] == 5
    # The trajectory simulate designs is the one `prrrp excite` designs (same seed).
    designed = csvio.read_table(tmp_path / "sim" / "trajectory.csv", 5, need_tau=False)
    np.testing.assert_array_equal(designed["q"], traj["q"])

    code, _, err = run(["identify", "sim/data.csv", "--out", "id"], capsys)
    assert code == 0, err
    assert err == ""
    model = prrrp.IdentifiedModel.load(tmp_path / "id" / "model.json")
    paper = prrrp.load_robot("paper")
    assert model.robot.name == paper.name
    assert list(model.robot.joint_names) == list(paper.joint_names)

    code, _, err = run(["identify", "sim/data.csv", "--robot", "paper", "--out", "id2"], capsys)
    assert code == 0, err
    explicit = prrrp.IdentifiedModel.load(tmp_path / "id2" / "model.json")
    np.testing.assert_array_equal(np.asarray(model.beta), np.asarray(explicit.beta))

    code, _, err = run(["predict", "id/model.json", "sim/data.csv", "--out", "tau.csv"], capsys)
    assert code == 0, err
    tau = np.loadtxt(tmp_path / "tau.csv", delimiter=",", skiprows=1)
    assert len(tau) == len(data["t"])

    # The online identifier's command has the same default robot.
    code, stdout, err = run(["track", "sim/data.csv", "--out", "track"], capsys)
    assert code == 0, err
    assert stdout.startswith(f"{paper.name}: ")
    tracked = prrrp.IdentifiedModel.load(tmp_path / "track" / "model.json")
    assert list(tracked.robot.joint_names) == list(paper.joint_names)


def test_identify_without_robot_and_a_json_out_is_the_deprecated_closed_form(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The previous release's `simulate --out DATA.csv` and `identify DATA --out RESULTS.json`
    write what they wrote (one CSV; λ of the closed form as JSON), then one notice on stderr
    whose suggested command runs and writes a folder."""
    monkeypatch.chdir(tmp_path)
    code, stdout, err = run(["simulate", "--out", "d.csv", "--seed", "3"], capsys)
    assert code == 0, err
    assert stdout.startswith("results in d.csv")
    assert (tmp_path / "d.csv").is_file()
    assert suggestion(err) == ["simulate", "--seed", "3", "--robot", "paper", "--out", "d"]

    code, stdout, err = run(["identify", "d.csv", "--method", "ls", "--out", "lam.json"], capsys)
    assert code == 0, err
    assert "cond(W)" in stdout
    (ls,) = json.loads((tmp_path / "lam.json").read_text())["estimates"]
    assert ls["method"] == "least_squares"
    assert len(ls["lambda"]) == prrrp.NPARAM
    new = suggestion(err)
    assert new == ["identify", "d.csv", "--method", "ls", "--robot", "paper", "--out", "lam"]
    code, _, err = run(new, capsys)
    assert code == 0, err
    assert err == ""
    assert (tmp_path / "lam" / "model.json").is_file()

    # No --out at all: the closed form's print-only run, with the same notice.
    code, stdout, err = run(["identify", "d.csv"], capsys)
    assert code == 0, err
    assert "λ1" in stdout
    assert suggestion(err) == ["identify", "d.csv", "--robot", "paper", "--out", "DIR"]


def test_a_csv_out_of_excite_and_simulate_is_the_deprecated_one_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """`excite --out TRAJ.csv` and `simulate --robot R --trajectory T --out DATA.csv` write
    that one file, then say which folder spelling writes the same."""
    monkeypatch.chdir(tmp_path)
    argv = ["excite", "--robot", "paper", "--duration", "5", "--evaluations", "200"]
    code, _, err = run([*argv, "--out", "t.csv"], capsys)
    assert code == 0, err
    old = csvio.read_table(tmp_path / "t.csv", 5, need_tau=False)
    new = suggestion(err)
    assert new[-2:] == ["--out", "t"]
    code, _, err = run(new, capsys)
    assert code == 0, err
    same = csvio.read_table(tmp_path / "t" / "trajectory.csv", 5, need_tau=False)
    np.testing.assert_array_equal(old["q"], same["q"])

    argv = ["simulate", "--robot", "paper", "--trajectory", "t.csv", "--seed", "1"]
    code, _, err = run([*argv, "--out", "s.csv"], capsys)
    assert code == 0, err
    old = csvio.read_measurements(tmp_path / "s.csv")
    new = suggestion(err)
    assert new == [*argv[:-2], "--seed", "1", "--out", "s"]
    code, _, err = run(new, capsys)
    assert code == 0, err
    same = csvio.read_measurements(tmp_path / "s" / "data.csv")
    np.testing.assert_array_equal(old["tau"], same["tau"])


def test_a_failing_deprecated_spelling_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run(["identify", str(tmp_path / "none.csv"), "--out", "x.json"], capsys)
    assert code == cli.EXIT_USAGE
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("prrrp: error: ")


@pytest.mark.parametrize("command", ["identify", "simulate", "excite"])
def test_help_describes_one_behaviour(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    """No "without --robot: …, with --robot: …": one behaviour, `--out DIR`, the paper's
    arm named as the default robot; the deprecated spelling in the one closing paragraph."""
    with pytest.raises(SystemExit) as exc:
        cli.main([command, "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    paragraphs = [" ".join(p.split()) for p in text.split("\n\n") if p.strip()]
    body, last = paragraphs[:-1], paragraphs[-1]
    assert last.startswith("Deprecated"), last
    assert len(re.findall(r"[.!?](\s|$)", last)) == 1, last  # one sentence
    body_text = " ".join(body).lower()
    for phrase in ("without --robot", "with --robot", "closed form", "deprecated", "results.json"):
        assert phrase not in body_text, (command, phrase)
    assert "--out DIR" in " ".join(text.split())
    assert "(default: paper)" in body_text
