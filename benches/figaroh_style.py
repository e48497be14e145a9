"""A FIGAROH-style identification pipeline (numpy + scipy + Pinocchio), the peer of
`prrrp identify` in `benches/peers.py`: what FIGAROH 1.0's dynamic identification does
with a joint log, written out so that it runs from one command on the same CSV.

    python benches/figaroh_style.py LOG.csv ROBOT.urdf

1. read the log (t, q1..qN, tau1..tauN; SI units);
2. low-pass q and τ with a zero-phase 4th-order Butterworth (scipy.signal.filtfilt) at
   min(10 Hz, rate/10), differentiate q twice (np.gradient), drop 0.3 s at each end;
3. stack Pinocchio's joint-torque regressor (pin.computeJointTorqueRegressor, 10 inertial
   parameters per link) with viscous, Coulomb (sign) and offset friction columns per joint,
   joint-major as FIGAROH does;
4. drop the zero columns, choose base columns by QR with column pivoting (scipy.linalg.qr),
   solve least squares on them, σ of each base parameter from the residual;
5. print the torque RMS error per joint against the measured torque on the kept rows.

It writes no files and draws no figures (FIGAROH's identification returns arrays); it is
a peer for the work `prrrp identify` does before its report.
"""

from __future__ import annotations

import sys

import numpy as np
import pinocchio as pin
import scipy.linalg
import scipy.signal


def identify(log: str, urdf: str) -> dict[str, np.ndarray]:
    """β of the base parameters, their σ, and the per-joint torque RMS error (N·m)."""
    table = np.loadtxt(log, delimiter=",", skiprows=1)
    model = pin.buildModelFromUrdf(urdf)
    data = model.createData()
    n = model.nq
    t, q, tau = table[:, 0], table[:, 1 : 1 + n], table[:, 1 + n : 1 + 2 * n]
    dt = float(np.median(np.diff(t)))
    rate = 1.0 / dt
    b, a = scipy.signal.butter(4, min(10.0, rate / 10) / (rate / 2))
    q_f = scipy.signal.filtfilt(b, a, q, axis=0)
    tau_f = scipy.signal.filtfilt(b, a, tau, axis=0)
    qd = np.gradient(q_f, dt, axis=0)
    qdd = np.gradient(qd, dt, axis=0)
    trim = round(0.3 * rate)
    keep = slice(trim, len(t) - trim)
    q_f, qd, qdd, tau_f, tau_m = q_f[keep], qd[keep], qdd[keep], tau_f[keep], tau[keep]
    m = len(q_f)
    w = np.zeros((n * m, 10 * n + 3 * n))
    for i in range(m):
        y = pin.computeJointTorqueRegressor(model, data, q_f[i], qd[i], qdd[i])
        w[i::m, : 10 * n] = y  # joint-major: row j·m + i is joint j at sample i
    for j in range(n):
        rows = slice(j * m, (j + 1) * m)
        w[rows, 10 * n + 3 * j] = qd[:, j]
        w[rows, 10 * n + 3 * j + 1] = np.sign(qd[:, j])
        w[rows, 10 * n + 3 * j + 2] = 1.0
    nonzero = np.flatnonzero(np.linalg.norm(w, axis=0) > 1e-8 * np.sqrt(len(w)))
    w_e = w[:, nonzero]
    _, r, piv = scipy.linalg.qr(w_e, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r))
    rank = int(np.sum(diag > 1e-8 * diag[0]))
    w_b = w_e[:, piv[:rank]]
    y = tau_f.T.reshape(-1)
    beta, *_ = np.linalg.lstsq(w_b, y, rcond=None)
    resid = y - w_b @ beta
    sigma2 = resid @ resid / (len(y) - rank)
    cov = sigma2 * np.linalg.inv(w_b.T @ w_b)
    predicted = (w_b @ beta).reshape(n, m).T
    err = np.sqrt(np.mean((tau_m - predicted) ** 2, axis=0))
    ref = np.sqrt(np.mean(tau_m**2, axis=0))
    return {"beta": beta, "sigma": np.sqrt(np.diag(cov)), "rms": err, "percent": 100 * err / ref}


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__.splitlines()[0], "\nusage: figaroh_style.py LOG.csv ROBOT.urdf")
        return 2
    out = identify(sys.argv[1], sys.argv[2])
    print(f"{len(out['beta'])} base parameters")
    print(
        "torque RMS error per joint, % of measured:", " ".join(f"{p:.3g}" for p in out["percent"])
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
