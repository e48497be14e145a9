"""The command line speaks command line: `--help` gives every option's default and every
method; errors are one line without Python tuples or the library's `code` quotes."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np
import pytest

from prrrp import cli, csvio, workflow

SWITCHES = (argparse._HelpAction, argparse._VersionAction, argparse._StoreTrueAction)


def subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


@pytest.mark.parametrize("command", sorted(subcommands()))
def test_help_gives_every_default(command):
    parser = subcommands()[command]
    for action in parser._actions:
        if not action.option_strings or action.required or isinstance(action, SWITCHES):
            continue
        assert "default" in (action.help or ""), (command, action.option_strings, action.help)


def test_identify_help_lists_every_method(capsys):
    with pytest.raises(SystemExit):
        cli.main(["identify", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for method in (*workflow.METHODS, "all"):
        assert re.search(rf"\b{method} =", text), method
    assert "(default: wls)" in text
    assert "--cutoff HZ" in text
    assert "(default: min(10 Hz, output rate/10))" in text


def test_errors_speak_cli(tmp_path: Path, capsys):
    data = tmp_path / "d.csv"
    data.write_text(
        csvio.format_measurements(np.arange(50) * 0.01, np.zeros((50, 5)), np.zeros((50, 5)))
    )
    out = str(tmp_path / "o")
    commands = [
        ["identify", str(data), "--robot", str(tmp_path / "none.urdf"), "--out", out],
        ["identify", str(data), "--method", "physical"],
        ["excite", "--robot", str(tmp_path / "none.toml"), "--out", str(tmp_path / "t.csv")],
        ["predict", str(tmp_path / "none.json"), str(data), "--out", str(tmp_path / "t.csv")],
        ["predict", str(tmp_path), str(data), "--out", str(tmp_path / "t.csv")],
    ]
    for argv in commands:
        assert cli.main(argv) == cli.EXIT_USAGE, argv
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1, err
        assert "`" not in err, err
        assert "('" not in err, err
        assert err.startswith("prrrp: error: "), err
    # The robot file's error names the file once, then what is wrong.
    cli.main(commands[0])
    err = capsys.readouterr().err
    assert err.startswith(f"prrrp: error: {tmp_path / 'none.urdf'}: cannot read"), err
    cli.main(commands[1])
    assert "wls, ls, adaline, hopfield, ekf or all" in capsys.readouterr().err
