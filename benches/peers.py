"""Peer timings beside prrrp's own, measured in the same run, from Python.

- least squares on 5000 samples of the paper's arm: `prrrp.least_squares` (W built in
  Rust) against numpy's `lstsq` on the same, already built, W (`prrrp.observation_matrix`);
- batch inverse dynamics: `prrrp.Robot.paper().inverse_dynamics` on N states against a
  loop of `pin.rnea` on the same states (the Pinocchio model of python/tests);
- the EKF step at the chain7 size: filterpy's ExtendedKalmanFilter (benches/filterpy_ekf.py),
  if filterpy is installed (the `bench` extra), beside the median criterion recorded for
  `chain7_ekf_step` in target/criterion (the benches run just before this script).

- end to end on one log (`--e2e`, on by default): the `prrrp identify` command (model.json,
  report.md, figures) against a FIGAROH-style numpy + scipy + Pinocchio least-squares
  pipeline (benches/figaroh_style.py) on the same 40 s, 6-joint, 500 Hz log of a UR5-like
  arm (tests/data/ur5_like_friction.toml, made here with `prrrp excite` and `simulate`),
  each a fresh process, run alternately; without --short also `--method all` and a 5 kHz,
  25 000-row log (prrrp alone).

Medians of repeated timings. It reports and never fails on timing; it exits non-zero only on
an error (e.g. the results of prrrp and its peer disagree). numpy's BLAS honours
OPENBLAS_CORETYPE / OPENBLAS_L2_SIZE, which this machine sets for other software and which
slow a current numpy, so run it with those unset for a fair peer:

    env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE .venv/bin/python benches/peers.py [--short]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

import prrrp

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "python" / "tests"))
sys.path.insert(0, str(HERE))


def median_time(fn, number: int, repeat: int) -> float:
    """Median over `repeat` runs of the time per call (s), `number` calls per run."""
    fn()
    return statistics.median(t / number for t in timeit.repeat(fn, number=number, repeat=repeat))


def excitation(n: int, dt: float = 0.02) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A smooth multi-sine of the paper's arm (q, q̇, q̈ exact), n samples at dt."""
    t = np.arange(n)[:, None] * dt
    w = 2 * np.pi * 0.1 * np.arange(1, 4)
    amp = np.array([[0.05, 0.6, 0.8, 0.9, 0.04]]) / 3
    off = np.array([[0.5, 0.0, 0.3, -0.2, 0.1]])
    q, qd, qdd = off.repeat(n, 0), np.zeros((n, 5)), np.zeros((n, 5))
    for k, wk in enumerate(w):
        ph = 0.7 * k + np.arange(5)
        q = q + amp * np.sin(wk * t + ph)
        qd = qd + amp * wk * np.cos(wk * t + ph)
        qdd = qdd - amp * wk**2 * np.sin(wk * t + ph)
    return q, qd, qdd


def blas_kernel() -> str:
    try:
        from threadpoolctl import threadpool_info

        infos = [
            f"{i.get('internal_api')} {i.get('version')} {i.get('architecture')} "
            f"threads={i.get('num_threads')}"
            for i in threadpool_info()
            if i.get("user_api") == "blas"
        ]
        return "; ".join(infos) or "unknown"
    except ImportError:
        cfg = np.show_config(mode="dicts")
        blas = cfg.get("Build Dependencies", {}).get("blas", {})
        return f"{blas.get('name')} {blas.get('version')} (threadpoolctl not installed)"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--short", action="store_true", help="fewer repetitions (CI)")
    ap.add_argument("--no-e2e", action="store_true", help="skip the end-to-end comparison")
    args = ap.parse_args()
    rep = 5 if args.short else 15
    rows: list[tuple[str, str, float, str, float]] = []

    robot = prrrp.Robot.paper()
    lam = robot.base_parameters()

    # Least squares, 5000 samples.
    q, qd, qdd = excitation(5000)
    tau = robot.inverse_dynamics(q, qd, qdd)
    w = prrrp.observation_matrix(q, qd, qdd)
    y = tau.reshape(-1)
    ours = prrrp.least_squares(q, qd, qdd, tau).lam
    theirs = np.linalg.lstsq(w, y, rcond=None)[0]
    if not np.allclose(ours, theirs, rtol=1e-8, atol=1e-10 * np.abs(lam).max()):
        print(f"error: least squares disagree: {ours} vs {theirs}", file=sys.stderr)
        return 1
    t_ours = median_time(lambda: prrrp.least_squares(q, qd, qdd, tau), 5, rep)
    t_np = median_time(lambda: np.linalg.lstsq(w, y, rcond=None), 5, rep)
    rows.append(
        ("least squares, 5000 samples", "prrrp (W built)", t_ours, "numpy lstsq (W given)", t_np)
    )

    # Batch inverse dynamics against a loop of pin.rnea.
    try:
        import pinocchio as pin
        from pinocchio_prrrp import build
    except ImportError as e:
        print(f"pinocchio not available ({e}); skipping inverse dynamics", file=sys.stderr)
        pin = None
    if pin is not None:
        model = build(robot.mass, robot.length, robot.com, robot.inertia_zz)
        data = model.createData()
        for n in (10_000, 100_000):
            q, qd, qdd = excitation(n, dt=1e-3)
            ours = robot.inverse_dynamics(q, qd, qdd)
            ref = np.array(
                [pin.rnea(model, data, *s) for s in zip(q[:100], qd[:100], qdd[:100], strict=True)]
            )
            if not np.allclose(ours[:100], ref, rtol=1e-9, atol=1e-9):
                print("error: inverse dynamics disagree with pin.rnea", file=sys.stderr)
                return 1

            def pin_loop(q=q, qd=qd, qdd=qdd):
                for a, b, c in zip(q, qd, qdd, strict=True):
                    pin.rnea(model, data, a, b, c)

            t_ours = median_time(
                lambda q=q, qd=qd, qdd=qdd: robot.inverse_dynamics(q, qd, qdd), 3, rep
            )
            t_pin = median_time(pin_loop, 1, max(3, rep // 3))
            rows.append(
                (
                    f"inverse dynamics, N = {n}, per state",
                    "prrrp batch",
                    t_ours / n,
                    "pin.rnea loop",
                    t_pin / n,
                )
            )

    # filterpy's EKF step at the chain7 size.
    if importlib.util.find_spec("filterpy") is not None:
        import filterpy_ekf

        t_fp = filterpy_ekf.time_step(repeat=rep)
        rows.append(
            (
                "EKF step, 78 states, 7 measurements",
                "prrrp: criterion chain7_ekf_step",
                criterion_median("chain7_ekf_step"),
                "filterpy ExtendedKalmanFilter",
                t_fp,
            )
        )

    e2e = end_to_end(short=args.short) if not args.no_e2e else []

    print(f"numpy {np.__version__}, BLAS: {blas_kernel()}")
    print(f"{'case':40s} {'prrrp':>12s} {'peer':>12s} {'peer/prrrp':>11s}  (prrrp | peer)")
    for case, a, ta, b, tb in rows:
        ratio = tb / ta if ta == ta else float("nan")
        fa = "-" if ta != ta else fmt(ta)
        print(f"{case:40s} {fa:>12s} {fmt(tb):>12s} {ratio:>10.1f}×  ({a} | {b})")
    if e2e:
        print(f"end to end, wall time of a fresh process (median of runs); {machine()}")
        for case, ta, tb in e2e:
            peer = "-" if tb != tb else fmt(tb)
            ratio = "" if tb != tb else f"{tb / ta:10.2f}×"
            print(f"{case:58s} {fmt(ta):>9s} {peer:>9s} {ratio}")
        cpu = ", ".join(f"{k} {statistics.median(v):.3g} s" for k, v in CPU.items())
        print(f"CPU time (user + system) per process, medians: {cpu}")
    return 0


#: The robot of the end-to-end comparison.
UR5_LIKE = HERE.parent / "tests" / "data" / "ur5_like_friction.toml"


def machine() -> str:
    """CPU model, core count and load average: the numbers are only meaningful with them."""
    model = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return f"{model}, {os.cpu_count()} cores, load average {load}"


#: CPU seconds (user + system) of each process _run ran, by argv[1:3]: on a loaded machine
#: the wall time measures the load as much as the program.
CPU: dict[str, list[float]] = {}


def _run(argv: list[str], key: str | None = None) -> float:
    """Wall time of one fresh process running argv (s), its CPU time kept in CPU[key];
    raises if it fails."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(argv, capture_output=True, text=True, check=False)
    took = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} failed: {proc.stderr.strip()[-500:]}")
    if key is not None:
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        CPU.setdefault(key, []).append(cpu)
    return took


def _log(prrrp_cmd: list[str], folder: Path, name: str, seconds: float, rate: float) -> Path:
    """A simulated log of the UR5-like arm (excitation designed for it), seeded."""
    traj, log = folder / f"{name}-traj", folder / name
    robot = ["--robot", str(UR5_LIKE)]
    _run(
        [
            *prrrp_cmd,
            "excite",
            *robot,
            "--duration",
            f"{seconds:g}",
            "--rate",
            f"{rate:g}",
            "--out",
            str(traj),
            "--evaluations",
            "300",
        ]
    )
    trajectory = traj / "trajectory.csv"
    _run([*prrrp_cmd, "simulate", *robot, "--trajectory", str(trajectory), "--out", str(log)])
    return log / "data.csv"


def end_to_end(short: bool) -> list[tuple[str, float, float]]:
    """(case, prrrp median s, peer median s or NaN) for each end-to-end case."""
    try:
        import figaroh_style  # noqa: F401  (needs pinocchio and scipy)
    except ImportError as e:
        print(f"FIGAROH-style peer not available ({e}); skipping end to end", file=sys.stderr)
        return []
    exe = Path(sys.executable)
    prrrp_cmd = (
        [str(exe.with_name("prrrp"))]
        if exe.with_name("prrrp").exists()
        else [str(exe), "-m", "prrrp"]
    )
    peer_cmd = [str(exe), str(HERE / "figaroh_style.py")]
    rounds = 2 if short else 5
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        urdf = folder / "ur5_like.urdf"
        urdf.write_text(prrrp.SerialChain.from_file(str(UR5_LIKE)).to_urdf())
        log = _log(prrrp_cmd, folder, "ur5-40s-500hz", 40.0, 500.0)
        ident = [*prrrp_cmd, "identify", str(log), "--robot", str(UR5_LIKE)]
        ours, theirs = [], []
        for k in range(rounds):  # alternately, so that both see the same load
            ours.append(_run([*ident, "--out", str(folder / f"out{k}")], "prrrp"))
            theirs.append(_run([*peer_cmd, str(log), str(urdf)], "peer"))
        rows.append(
            (
                "identify, 40 s 6-joint 500 Hz log (report, figures)",
                statistics.median(ours),
                statistics.median(theirs),
            )
        )
        if not short:
            runs = [
                _run([*ident, "--method", "all", "--out", str(folder / f"all{k}")], "all")
                for k in range(3)
            ]
            rows.append(("identify --method all, same log", statistics.median(runs), math.nan))
            fast = _log(prrrp_cmd, folder, "ur5-5s-5khz", 5.0, 5000.0)
            cmd = [*prrrp_cmd, "identify", str(fast), "--robot", str(UR5_LIKE)]
            runs = [_run([*cmd, "--out", str(folder / f"fast{k}")], "5khz") for k in range(rounds)]
            rows.append(("identify, 5 kHz log, 25 000 rows", statistics.median(runs), math.nan))
    return rows


def criterion_median(bench: str) -> float:
    """The median (s) criterion recorded for `bench` in this checkout's target folder (the
    benches that `.ci/run` runs just before this script), or NaN when it has not run."""
    path = Path(__file__).resolve().parent.parent / "target" / "criterion" / bench / "new"
    try:
        estimates = json.loads((path / "estimates.json").read_text())
        return float(estimates["median"]["point_estimate"]) * 1e-9
    except (OSError, KeyError, TypeError, ValueError):
        return float("nan")


def fmt(t: float) -> str:
    for unit, f in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9)):
        if t >= f:
            return f"{t / f:.3g} {unit}"
    return f"{t / 1e-9:.3g} ns"


if __name__ == "__main__":
    sys.exit(main())
