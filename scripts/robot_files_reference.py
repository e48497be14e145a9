"""Pinocchio reference for crates/prrrp-core/tests/robot_files.rs.

Loads crates/prrrp-core/tests/data/three_joint.urdf with Pinocchio, locks the two finger
joints at zero with buildReducedModel (what DynChain::from_urdf_str with tip "link3"
promises to equal), and writes random states with their RNEA torques and CRBA mass
matrices to crates/prrrp-core/tests/data/three_joint_pinocchio.txt, one sample per line:
q(3) v(3) a(3) tau(3) M(3x3, row-major).

Run from the repository root with the project's venv: python scripts/robot_files_reference.py
"""

import numpy as np
import pinocchio as pin

URDF = "crates/prrrp-core/tests/data/three_joint.urdf"
OUT = "crates/prrrp-core/tests/data/three_joint_pinocchio.txt"

model = pin.buildModelFromUrdf(URDF)
locked = [model.getJointId(n) for n in ("finger_left_joint", "finger_right_joint")]
red = pin.buildReducedModel(model, locked, pin.neutral(model))
data = red.createData()
assert [red.names[i] for i in range(1, red.njoints)] == ["shoulder", "elbow", "slide"]

rng = np.random.default_rng(20261127)
lines = [f"# Pinocchio {pin.__version__} reference; see scripts/robot_files_reference.py"]
for _ in range(12):
    q = rng.uniform(-2.0, 2.0, 3)
    q[2] = rng.uniform(-0.1, 0.3)
    v = rng.uniform(-2.0, 2.0, 3)
    a = rng.uniform(-5.0, 5.0, 3)
    # Pinocchio stores a continuous joint's position as (cos q, sin q).
    qp = np.array([q[0], np.cos(q[1]), np.sin(q[1]), q[2]])
    tau = pin.rnea(red, data, qp, v, a)
    m = pin.crba(red, data, qp)
    m = np.triu(m) + np.triu(m, 1).T
    vals = np.concatenate([q, v, a, tau, m.reshape(-1)])
    lines.append(" ".join(repr(float(x)) for x in vals))
open(OUT, "w").write("\n".join(lines) + "\n")
print(f"wrote {OUT}")
