"""Cost of the Python boundary: prrrp's batched inverse dynamics vs one Pinocchio call per
sample, and prrrp called per sample. Not a test; prints medians.

    python python/bench/boundary.py [N]        (needs `pip install .[test]`)
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

import prrrp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from pinocchio_prrrp import from_robot


def measure(fns: dict, rounds: int) -> dict:
    """CPU time (process_time: robust to other processes on a loaded machine) of each
    function, interleaved over rounds; returns (median, min) per name."""
    times = {name: [] for name in fns}
    for _ in range(rounds):
        for name, fn in fns.items():
            t0 = time.process_time()
            fn()
            times[name].append(time.process_time() - t0)
    return {name: (statistics.median(t), min(t)) for name, t in times.items()}


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    rng = np.random.default_rng(1)
    q = rng.uniform(-3.0, 3.0, (n, 5))
    qd = rng.normal(0.0, 1.0, (n, 5))
    qdd = rng.normal(0.0, 2.0, (n, 5))
    robot = prrrp.Robot.paper()
    model = from_robot(robot)
    data = model.createData()
    lam = robot.base_parameters()

    def prrrp_batch():
        robot.inverse_dynamics(q, qd, qdd)

    def prrrp_batch_lam():
        robot.inverse_dynamics(q, qd, qdd, lam=lam)

    def prrrp_regressor_batch():
        prrrp.regressor(q, qd, qdd)

    # Rows as separate arrays, made outside the timed loops (as a user iterating over a
    # recorded trajectory would have them).
    rows = list(zip(q, qd, qdd, strict=True))

    def prrrp_loop():
        f = robot.inverse_dynamics
        for a, b, c in rows:
            f(a, b, c)

    def pin_loop():
        f = pin.rnea
        for a, b, c in rows:
            f(model, data, a, b, c)

    def numpy_copy():
        q.copy()

    def prrrp_gravity_batch():
        # G does not depend on q: this is the boundary alone (one (N,5) in, one out).
        robot.gravity(q)

    results = measure(
        {
            "prrrp batch inverse_dynamics (one call)": prrrp_batch,
            "prrrp batch inverse_dynamics, lam=": prrrp_batch_lam,
            "prrrp batch regressor (one call)": prrrp_regressor_batch,
            "prrrp batch gravity (boundary only)": prrrp_gravity_batch,
            "numpy q.copy() of the (N, 5) input, for scale": numpy_copy,
        },
        21,
    )
    results |= measure(
        {
            "prrrp inverse_dynamics, one call per sample": prrrp_loop,
            "pin.rnea, one call per sample": pin_loop,
        },
        5,
    )
    versions = f"prrrp {prrrp.__version__}, pinocchio {pin.__version__}, numpy {np.__version__}"
    print(f"N = {n}, {versions}")
    print(f"{'CPU time, median (min) over rounds':48s} {'ms':>9s}   {'ns/sample':>17s}")
    for name, (med, low) in results.items():
        print(f"{name:48s} {med * 1e3:9.2f}   {med / n * 1e9:8.1f} ({low / n * 1e9:6.1f})")


if __name__ == "__main__":
    main()
