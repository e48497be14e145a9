"""Peer timings beside prrrp's own, measured in the same run, from Python.

- least squares on 5000 samples of the paper's arm: `prrrp.least_squares` (W built in
  Rust) against numpy's `lstsq` on the same, already built, W (`prrrp.observation_matrix`);
- batch inverse dynamics: `prrrp.Robot.paper().inverse_dynamics` on N states against a
  loop of `pin.rnea` on the same states (the Pinocchio model of python/tests);
- the EKF step at the chain7 size: filterpy's ExtendedKalmanFilter (benches/filterpy_ekf.py),
  if filterpy is installed (the `bench` extra), beside the median criterion recorded for
  `chain7_ekf_step` in target/criterion (the benches run just before this script).

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
import statistics
import sys
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

    print(f"numpy {np.__version__}, BLAS: {blas_kernel()}")
    print(f"{'case':40s} {'prrrp':>12s} {'peer':>12s} {'peer/prrrp':>11s}  (prrrp | peer)")
    for case, a, ta, b, tb in rows:
        ratio = tb / ta if ta == ta else float("nan")
        fa = "-" if ta != ta else fmt(ta)
        print(f"{case:40s} {fa:>12s} {fmt(tb):>12s} {ratio:>10.1f}×  ({a} | {b})")
    return 0


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
