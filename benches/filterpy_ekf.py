"""Reference timing: filterpy's ExtendedKalmanFilter at the size of the chain7 EKF bench.

78 states (7 positions, 7 velocities, 64 base parameters), 7 position measurements, with
the Jacobians precomputed (F dense in the dynamics rows, H a selection), so that only the
filter's own predict/update is timed, as the Rust `chain7_ekf_step` times one sample
(update + predict + the model's derivatives). Not a dependency of the project:

    .venv/bin/pip install filterpy && .venv/bin/python benches/filterpy_ekf.py
"""

import statistics
import timeit

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

N, B = 7, 64
S = 2 * N + B
DT = 0.01


def time_step(repeat: int = 30) -> float:
    """Median time (s) of one filterpy update + predict at the chain7 size."""
    rng = np.random.default_rng(0)
    ekf = ExtendedKalmanFilter(dim_x=S, dim_z=N)
    a = rng.normal(size=(N, S))  # ∂q̈/∂x of the model, dense as for the chain
    f = np.eye(S)
    f[:N, N : 2 * N] += DT * np.eye(N)
    f[N : 2 * N, :] += DT * a
    ekf.F = f
    ekf.Q = np.diag(np.r_[np.full(N, 1e-12), np.full(N, 1e-6), np.full(B, 1e-10)])
    ekf.R = np.eye(N) * 1e-6
    ekf.P = np.diag(np.r_[np.full(N, 1e-6), np.full(N, 1.0), np.full(B, 1e-2)])
    ekf.x = rng.normal(size=(S, 1))
    h = np.zeros((N, S))
    h[:, :N] = np.eye(N)
    z = rng.normal(size=(N, 1)) * 1e-3

    def step() -> None:
        ekf.update(z, lambda _x: h, lambda x: h @ x)
        ekf.predict()

    for _ in range(200):
        step()
    reps = 200
    times = timeit.repeat(step, number=reps, repeat=repeat)
    return statistics.median(t / reps for t in times)


def main() -> None:
    per = [time_step(repeat=1) * 1e6 for _ in range(30)]
    print(
        f"filterpy ExtendedKalmanFilter, {S} states, {N} measurements: "
        f"median {statistics.median(per):.1f} µs, min {min(per):.1f} µs per update+predict"
    )


if __name__ == "__main__":
    main()
