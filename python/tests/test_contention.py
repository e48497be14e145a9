"""The main job never hangs: progress callbacks meeting worker threads under CPU contention,
and Ctrl-C / SIGTERM on ``prrrp reproduce`` mid-run.

A deadlock showed only under load (2 of 20 runs beside two busy processes): a worker thread
held a Rust lock while it waited for the GIL, the thread holding the GIL waited for that lock.
These tests run the study, the sensitivity sweep and the benchmark with progress callbacks
beside CPU hogs, with a tiny GIL switch interval so that threads trade the GIL as often as
possible, in a child process that must finish within a deadline. CI runs a few rounds
(``PRRRP_STRESS_ROUNDS``, default 2); a longer soak: ``PRRRP_STRESS_ROUNDS=30``.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

ROUNDS = int(os.environ.get("PRRRP_STRESS_ROUNDS", "2"))


@pytest.fixture
def cpu_hogs() -> Iterator[None]:
    """Two processes spinning on the CPU (the machine has two cores in CI)."""
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        yield
    finally:
        for h in hogs:
            h.kill()
            h.wait()


def run_child(source: str, deadline: float) -> str:
    """Runs `source` in a fresh interpreter; a child still running after `deadline` s is a
    hang: killed, and the test fails with what it printed."""
    child = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(source)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        out, err = child.communicate(timeout=deadline)
    except subprocess.TimeoutExpired:
        child.kill()
        out, err = child.communicate()
        pytest.fail(f"hung for {deadline} s (deadlock?)\nstdout: {out}\nstderr: {err}")
    assert child.returncode == 0, (out, err)
    return out


@pytest.mark.usefixtures("cpu_hogs")
def test_progress_callbacks_never_deadlock_under_contention() -> None:
    out = run_child(
        f"""
        import sys, threading
        import prrrp

        sys.setswitchinterval(1e-6)   # hand the GIL over as often as possible
        calls = []

        def staged(stage, done, total):
            calls.append((stage, done, total))
            sum(range(500))            # Python work: the interpreter may switch threads here

        def counts(done, total):
            sum(range(500))

        def sweeps():
            for _ in range(3):
                prrrp.sensitivity(points=3, duration=2.0, threads=4, progress=counts)

        for _ in range({ROUNDS}):
            other = threading.Thread(target=sweeps)
            other.start()
            result = prrrp.run_study(seed=0, progress=staged)
            other.join()
            assert result["schema_version"] == 1
        stages = [c[0] for c in calls]
        # Every stage reported, each ending at its total, in the study's order.
        for stage in ("excitation", "simulation", "estimators", "validation", "sensitivity"):
            last = [c for c in calls if c[0] == stage][-1]
            assert last[1] == last[2], last
        print("ok", len(calls))
        """,
        deadline=60.0 + 40.0 * ROUNDS,
    )
    assert out.startswith("ok")


@pytest.mark.usefixtures("cpu_hogs")
def test_benchmark_with_progress_in_threads_never_deadlocks() -> None:
    # Cases in threads of this process: Rust calls from several threads at once, and a
    # progress callback.
    out = run_child(
        f"""
        import sys
        from concurrent.futures import ThreadPoolExecutor
        import prrrp

        sys.setswitchinterval(1e-6)
        seen = []
        with ThreadPoolExecutor(4) as pool:
            for _ in range({ROUNDS}):
                r = prrrp.benchmark(methods="ls,rls", seeds=4, duration=3.0,
                                    excitation_evaluations=40, executor=pool,
                                    progress=lambda d, t, f: seen.append((d, t, f)))
                assert not r.failed if hasattr(r, "failed") else True
        assert seen[-1][0] == seen[-1][1]
        print("ok")
        """,
        deadline=60.0 + 60.0 * ROUNDS,
    )
    assert out.startswith("ok")


def _reproduce(out: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "prrrp", "reproduce", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.usefixtures("cpu_hogs")
@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_reproduce_ends_within_half_a_second_of_a_signal(tmp_path: Path, sig, code) -> None:
    out = tmp_path / "out"
    child = _reproduce(out)
    try:
        time.sleep(2.5)  # mid-run: the excitation optimisation or later
        assert child.poll() is None, child.communicate()
        child.send_signal(sig)
        t0 = time.monotonic()
        _, err = child.communicate(timeout=10)
        took = time.monotonic() - t0
    finally:
        child.kill()
    assert child.returncode == code, err
    # 0.06–0.09 s measured beside the hogs; 0.7–1.1 s when the exit waited for the
    # interpreter's teardown (the matplotlib import thread, every module freed).
    assert took < 0.5, f"took {took:.2f} s to stop"
    # Nothing half-written: no output folder, no staging folder left behind.
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_ctrl_c_stops_only_the_call_of_the_thread_it_reaches() -> None:
    # Ctrl-C reaches the main thread's call; a call running in another thread finishes.
    script = textwrap.dedent(
        """
        import threading
        import prrrp

        other = {}
        def background():
            other["result"] = prrrp.sensitivity(points=5, duration=20.0, threads=1)
        thread = threading.Thread(target=background)
        thread.start()
        print("started", flush=True)
        try:
            prrrp.sensitivity(points=11, duration=60.0, threads=1)
            print("main finished", flush=True)
        except KeyboardInterrupt:
            print("main interrupted", flush=True)
        thread.join()
        print("other", "finished" if "result" in other else "lost", flush=True)
        """
    )
    child = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout.readline().strip() == "started"
        time.sleep(1.0)
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=120)
    finally:
        child.kill()
    assert child.returncode == 0, (out, err)
    assert "main interrupted" in out, (out, err)
    assert "other finished" in out, (out, err)
