"""``identify --method all`` runs its methods on threads (``workflow.identify_methods``):
the same models as one method after another, and a Ctrl-C while they run stops every
method at its next check, leaves no thread behind and lets the next computation run."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
from conftest import fourier_motion

import prrrp
from prrrp import workflow

UR5_LIKE = Path(__file__).resolve().parents[2] / "tests" / "data" / "ur5_like_friction.toml"


def _data(robot: prrrp.SerialChain, samples: int, rate: float = 200.0) -> prrrp.Dataset:
    """A seeded Fourier motion of the robot with RNEA torques and 0.05 N·m noise."""
    t = np.arange(samples) / rate
    q, qd, qdd = (x[:, : robot.dof] for x in fourier_motion(3, t))
    tau = robot.inverse_dynamics(q, qd, qdd)
    tau = tau + np.random.default_rng(4).normal(0.0, 0.05, tau.shape)
    return prrrp.Dataset(t, q, qd, qdd, tau)


def test_threads_give_the_models_of_one_method_after_another() -> None:
    robot = workflow.load_robot(str(UR5_LIKE))
    data = _data(robot, 2000)
    one = workflow.identify_methods(robot, data, workers=1)
    two = workflow.identify_methods(robot, data, workers=2)
    assert [r.method for r in one] == [r.method for r in two] == list(workflow.METHODS)
    for a, b in zip(one, two, strict=True):
        assert a.error == b.error, a.method
        if a.result is not None:
            assert b.result is not None
            np.testing.assert_array_equal(a.result.model.beta, b.result.model.beta)


def test_ctrl_c_stops_every_method_running_on_a_thread() -> None:
    """In a fresh interpreter: a SIGINT raised as the first method finishes (the second
    thread is then inside Adaline, 1.7 s of work alone on this machine; 1.4 s passed
    before the stop when the other threads were not told) ends the call within a second
    with KeyboardInterrupt (0.23 s measured), no method thread is left, and a new
    identification runs (the process-wide stop is lowered again)."""
    script = f"""
        import os, signal, threading, time
        import numpy as np
        import prrrp
        from prrrp import workflow
        from test_method_threads import _data
        robot = workflow.load_robot({str(UR5_LIKE)!r})
        data = _data(robot, 60000, rate=1000.0)
        fired = []
        def progress(done, total):
            if done == 1 and not fired:
                fired.append(time.perf_counter())
                os.kill(os.getpid(), signal.SIGINT)
        try:
            workflow.identify_methods(
                robot, data, ["ls", "adaline"], progress=progress, workers=2
            )
        except KeyboardInterrupt:
            took = time.perf_counter() - fired[0]
        else:
            raise SystemExit("not interrupted")
        left = [t.name for t in threading.enumerate() if t.name.startswith("prrrp-method")]
        assert not left, left
        model = prrrp.identify(robot, data, "ls")
        print(f"ok {{took:.3f}} {{len(model.beta)}}")
    """
    here = str(Path(__file__).resolve().parent)
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=here,
        env={**os.environ, "PYTHONPATH": here},
        check=False,
    )
    assert done.returncode == 0, done.stderr
    word, took, _ = done.stdout.split()
    assert word == "ok"
    assert float(took) < 1.0, f"took {took} s to stop"


def test_a_hosts_stop_request_is_honoured_and_kept() -> None:
    """A host's prrrp.request_stop() stops every method, also the one-pass ls and wls
    (which never polled and ran), and the threaded runner leaves the host's flag raised
    (it lowered it on the way out, so the host's next call ran); clear_stop() lowers it."""
    robot = workflow.load_robot(str(UR5_LIKE))
    data = _data(robot, 2000)
    prrrp.request_stop()
    try:
        assert prrrp.stop_requested()
        for method in ("ls", "wls"):
            try:
                prrrp.identify(robot, data, method)
            except KeyboardInterrupt:
                pass
            else:
                raise AssertionError(f"{method} ran with the stop flag raised")
        try:
            workflow.identify_methods(robot, data, ["ls", "wls"], coulomb_scale=0.03, workers=2)
        except KeyboardInterrupt:
            pass
        else:
            raise AssertionError("identify_methods ran with the stop flag raised")
        assert prrrp.stop_requested()
    finally:
        prrrp.clear_stop()
    assert not prrrp.stop_requested()
    assert len(prrrp.identify(robot, data, "ls").beta) > 0


def test_one_method_at_a_time_when_two_copies_of_the_regressors_would_not_fit(
    monkeypatch,
) -> None:
    """The threads are used only when each running method's stored regressors fit in the
    memory share twice over; otherwise the methods run one after another."""
    robot = workflow.load_robot(str(UR5_LIKE))
    data = _data(robot, 2000)
    concurrent = []

    def spy(run, methods, workers, progress):
        concurrent.append(workers)
        return [run(m) for m in methods]

    monkeypatch.setattr(workflow, "_run_concurrently", spy)
    monkeypatch.setattr(workflow, "usable_cpus", lambda: 2)
    stored = 2000 * robot.dof * robot.num_params * 8
    for available, threads in ((100 * stored, [2]), (2 * stored, [])):
        concurrent.clear()
        monkeypatch.setattr(workflow, "available_memory", lambda a=available: a)
        runs = workflow.identify_methods(robot, data, ["ls", "wls"])
        assert [r.error for r in runs] == [None, None]
        assert concurrent == threads, available
