"""A Ctrl-C or SIGTERM that Python drops (its handler ran inside a weakref callback or a
finaliser, so the exception was printed as "Exception ignored" and lost) still ends the
command with 130 / 143 and writes nothing: seen once in CI, where `prrrp reproduce` went on
to finish with exit code 0 after Ctrl-C."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

CHILD = """
import gc, signal, sys, weakref
from prrrp import cli, signals

class Thing:
    pass

def callback(_ref):
    # Python runs the signal handler at the next bytecode, still inside this callback;
    # the exception it raises is printed and dropped.
    signal.raise_signal(SIG)
    sum(range(100))

installed = signals.install

def install():
    # The command installs its handlers, then the signal arrives and is dropped.
    installed()
    thing = Thing()
    ref = weakref.ref(thing, callback)
    del thing
    gc.collect()
    print("survived", flush=True)

signals.install = install
sys.exit(cli.main(ARGV))
"""


def run_child(argv: list[str], sig: int | None) -> subprocess.CompletedProcess[str]:
    """`prrrp ARGV` in a child where `sig` is raised and dropped right after the command
    installs its handlers (with None, nothing is raised)."""
    raised = "signal.raise_signal(SIG)"
    source = CHILD.replace(raised, "pass" if sig is None else f"signal.raise_signal({int(sig)})")
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(source.replace("ARGV", repr(argv)))],
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_dropped_signal_still_ends_the_run(tmp_path: Path, sig: int, code: int) -> None:
    out = tmp_path / "sim"
    argv = ["simulate", "--duration", "2", "--out", str(out)]
    child = run_child(argv, sig)
    # The premise: the exception was dropped, and the script went on.
    assert "Exception ignored" in child.stderr, child.stderr
    assert "survived" in child.stdout, (child.stdout, child.stderr)
    assert child.returncode == code, (child.stdout, child.stderr)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_an_error_after_a_dropped_signal_ends_for_the_signal(
    tmp_path: Path, sig: int, code: int
) -> None:
    """After a dropped signal, the command fails (here a bad --duration; in CI, matplotlib
    stopped halfway then raised "Invalid bounding box"): the exit code is the signal's,
    not the error's 2."""
    argv = ["simulate", "--duration", "0", "--out", str(tmp_path / "sim")]
    child = run_child(argv, sig)
    assert "survived" in child.stdout, (child.stdout, child.stderr)
    assert child.returncode == code, (child.stdout, child.stderr)
    # Without the signal, the same command is the usage error.
    plain = run_child(argv, None)
    assert plain.returncode == 2, (plain.stdout, plain.stderr)
    assert "--duration must be a positive number" in plain.stderr


def test_without_a_signal_the_run_writes_its_output(tmp_path: Path) -> None:
    # The same child with no signal: the check above fails for the signal, not the command.
    out = tmp_path / "sim"
    argv = ["simulate", "--duration", "2", "--out", str(out)]
    child = run_child(argv, None)
    assert child.returncode == 0, (child.stdout, child.stderr)
    assert out.exists()


@pytest.mark.parametrize("maker", ["mkstemp", "mkdtemp"])
def test_a_ctrl_c_while_a_temporary_is_created_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, maker: str
) -> None:
    """Ctrl-C arriving inside tempfile.mkstemp / mkdtemp, after the file or folder exists
    but before its name is returned: the interrupted writer still removes it (without
    `signals.deferred` the name was lost and the file stayed beside the output)."""
    import tempfile

    from prrrp import csvio, outdir

    real = getattr(tempfile, maker)

    def make_then_signal(*args, **kwargs):
        made = real(*args, **kwargs)
        signal.raise_signal(signal.SIGINT)  # default handler: KeyboardInterrupt
        return made

    monkeypatch.setattr(tempfile, maker, make_then_signal)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    restore = previous if previous is not None else signal.default_int_handler
    if maker == "mkstemp":
        write = lambda: csvio.write_text_atomic(tmp_path / "model.json", "{}")  # noqa: E731
    else:
        write = lambda: outdir.write_dir(tmp_path / "out", lambda folder: None)  # noqa: E731
    try:
        with pytest.raises(KeyboardInterrupt):
            write()
    finally:
        signal.signal(signal.SIGINT, restore)
    assert list(tmp_path.iterdir()) == []


def test_a_second_ctrl_c_while_exiting_prints_no_traceback() -> None:
    """A run ending for Ctrl-C whose exit handlers meet a second one (multiprocessing's
    joins under `prrrp benchmark`, or `timeout` signalling the process group): exit 130
    with the one error line, not "Exception ignored in atexit callback" and a traceback."""
    script = """
        import atexit, os, signal, time
        from prrrp import cli, signals

        def main(argv=None):
            signals.install()
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(5)
            except KeyboardInterrupt:
                cli.error("interrupted")
                return cli.EXIT_INTERRUPTED
            return 0

        def second_signal():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.2)
            print("exit handler done", flush=True)

        atexit.register(second_signal)
        cli.main = main
        cli.console()
    """
    child = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert child.returncode == 130, (child.stdout, child.stderr)
    assert "exit handler done" in child.stdout, child.stdout
    assert child.stderr.strip() == "prrrp: error: interrupted", child.stderr
