"""Reference dynamics of the PRRRP arm computed with Pinocchio (an independent rigid-body
library), for the Rust test `tests/pinocchio_reference.rs`.

The robot is built joint by joint from the DH table (paper Table 1) and the link data
(Table 2) with the conventions of `shared/notes/paper.md`:
joint 1 prismatic along +z, joints 2-4 revolute about z with links of length 0.2 m along x,
joint 5 prismatic along the z axis of a frame turned 180 deg about x (so d5 moves the tool
along world -z), centres of mass of links 2-4 on the link x axis at lc from the joint with
Izz about the centre of mass, link 5 a point mass. Gravity 9.81 m/s^2 along -z.

Usage:  python scripts/pinocchio_reference.py [OUT]   (needs `pip install pin`)
Writes one line per state: q(5) qd(5) qdd(5) tau(5) M(25, row-major) nle(5) tau_fd(5)
qdd_fd(5), where qdd_fd = ABA(q, qd, tau_fd).
"""

import sys

import numpy as np
import pinocchio as pin

MASS = [1.228, 1.023, 1.023, 1.023, 0.5114]
LENGTH = [0.524, 0.2, 0.2, 0.2, 0.14]
LC = 0.0229
IZZ = 0.0058


def build_model() -> pin.Model:
    model = pin.Model()
    model.gravity.linear = np.array([0.0, 0.0, -9.81])

    def add(parent, joint, placement, inertia, name):
        jid = model.addJoint(parent, joint, placement, name)
        model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        return jid

    # Link 1 only translates: its rotational inertia never enters the dynamics.
    j1 = add(0, pin.JointModelPZ(), pin.SE3.Identity(), pin.Inertia(MASS[0], np.zeros(3), np.eye(3) * 1e-3), "d1")
    # Links 2-4: inertia about the centre of mass; Ixx, Iyy do not enter planar motion but
    # are given positive values to keep the body physical.
    def link(m):
        return pin.Inertia(m, np.array([LC, 0.0, 0.0]), np.diag([1e-4, 1e-4, IZZ]))

    up = pin.SE3(np.eye(3), np.array([0.0, 0.0, LENGTH[0]]))
    j2 = add(j1, pin.JointModelRZ(), up, link(MASS[1]), "theta2")
    j3 = add(j2, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([LENGTH[1], 0.0, 0.0])), link(MASS[2]), "theta3")
    j4 = add(j3, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([LENGTH[2], 0.0, 0.0])), link(MASS[3]), "theta4")
    flip = pin.SE3(pin.utils.rotate("x", np.pi), np.array([LENGTH[3], 0.0, 0.0]))
    add(j4, pin.JointModelPZ(), flip, pin.Inertia(MASS[4], np.zeros(3), np.zeros((3, 3))), "d5")
    return model


def main() -> None:
    out = sys.argv[1] if len(sys.argv) > 1 else "tests/data/pinocchio_reference.txt"
    model = build_model()
    data = model.createData()
    rng = np.random.default_rng(20170320)
    rows = []
    for k in range(64):
        # Angles over several turns; velocities and accelerations from realistic to large.
        scale = 1.0 if k < 32 else 10.0
        q = np.concatenate([[rng.uniform(-0.5, 0.5)], rng.uniform(-3 * np.pi, 3 * np.pi, 3), [rng.uniform(-0.2, 0.2)]])
        qd = rng.normal(0.0, 1.0, 5) * scale
        qdd = rng.normal(0.0, 2.0, 5) * scale
        tau = pin.rnea(model, data, q, qd, qdd).copy()
        m = pin.crba(model, data, q).copy()
        m = np.triu(m) + np.triu(m, 1).T
        nle = pin.nonLinearEffects(model, data, q, qd).copy()
        tau_fd = rng.normal(0.0, 5.0, 5) * scale
        qdd_fd = pin.aba(model, data, q, qd, tau_fd).copy()
        rows.append(np.concatenate([q, qd, qdd, tau, m.ravel(), nle, tau_fd, qdd_fd]))
    with open(out, "w") as f:
        f.write(f"# Pinocchio {pin.__version__} reference for the PRRRP arm; see scripts/pinocchio_reference.py\n")
        for r in rows:
            f.write(" ".join(repr(float(x)) for x in r) + "\n")
    print(f"wrote {len(rows)} states to {out}")


if __name__ == "__main__":
    main()
