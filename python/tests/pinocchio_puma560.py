"""The PUMA 560 built by hand in Pinocchio from its published data, independently of prrrp.

Source of the numbers: P. Corke and B. Armstrong-Hélouvry, "A search for consensus among
model parameters reported for the PUMA 560 robot", Proc. IEEE ICRA 1994, pp. 1608-1613, as
in Corke's Robotics Toolbox `mdl_puma560` (standard DH, SI units; links only: no motor
inertia, gearing or friction). Gravity (0, 0, -9.81) m/s².

Standard DH: joint i turns about z_{i-1}, and frame i = frame_{i-1}·Rz(q_i)·Tz(d_i)·Tx(a_i)·
Rx(alpha_i). In Pinocchio, joint i's frame is frame_{i-1} turned by q_i, so the next joint
and link i's own frame (where the toolbox gives its centre of mass and inertia) sit at
SE3(Rx(alpha_i), (a_i, 0, d_i)) in it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

GRAVITY = 9.81

# (d, a, alpha) per joint, theta offsets all zero; m, rad.
DH = [
    (0.0, 0.0, np.pi / 2),
    (0.0, 0.4318, 0.0),
    (0.15005, 0.0203, -np.pi / 2),
    (0.4318, 0.0, np.pi / 2),
    (0.0, 0.0, -np.pi / 2),
    (0.0, 0.0, 0.0),
]

# Per link: mass (kg), centre of mass in frame i (m), [Ixx, Iyy, Izz] about the centre of
# mass in the axes of frame i (kg·m², products zero). Link 1: only the inertia about its
# joint axis (y of frame 1) acts. As in prrrp's `puma560()`, the source's link-1 Ixx = Izz = 0
# and link-3 Izz = 0.0125 break the triangle inequality; they are raised to the smallest
# values a rigid body can have (Iyy/2, and Iyy − Ixx = 0.020).
LINKS = [
    (0.0, (0.0, 0.0, 0.0), (0.175, 0.35, 0.175)),
    (17.4, (-0.3638, 0.006, 0.2275), (0.13, 0.524, 0.539)),
    (4.8, (-0.0203, -0.0141, 0.070), (0.066, 0.086, 0.020)),
    (0.82, (0.0, 0.019, 0.0), (1.8e-3, 1.3e-3, 1.8e-3)),
    (0.34, (0.0, 0.0, 0.0), (0.3e-3, 0.4e-3, 0.3e-3)),
    (0.09, (0.0, 0.0, 0.032), (0.15e-3, 0.15e-3, 0.04e-3)),
]


def rot_x(alpha: float) -> np.ndarray:
    c, s = np.cos(alpha), np.sin(alpha)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def link_placement(i: int) -> pin.SE3:
    """Frame i in joint i's frame."""
    d, a, alpha = DH[i]
    return pin.SE3(rot_x(alpha), np.array([a, 0.0, d]))


def build() -> pin.Model:
    model = pin.Model()
    model.gravity.linear = np.array([0.0, 0.0, -GRAVITY])
    parent = 0
    placement = pin.SE3.Identity()
    for i, (m, c, inertia) in enumerate(LINKS):
        jid = model.addJoint(parent, pin.JointModelRZ(), placement, f"j{i + 1}")
        body = pin.Inertia(m, np.array(c), np.diag(inertia))
        model.appendBodyToJoint(jid, link_placement(i).act(body), pin.SE3.Identity())
        parent, placement = jid, link_placement(i)
    return model


def standard_parameters() -> np.ndarray:
    """The 60 link-frame parameters [m, m·c, I about the frame-i origin (Ixx, Ixy, Iyy, Ixz,
    Iyz, Izz)] per link, by the parallel-axis theorem."""
    out = []
    for m, c, inertia in LINKS:
        c = np.array(c)
        i_o = np.diag(inertia) + m * (c @ c * np.eye(3) - np.outer(c, c))
        out.append(np.concatenate([[m], m * c, pack(i_o)]))
    return np.concatenate(out)


def pack(i: np.ndarray) -> np.ndarray:
    return np.array([i[0, 0], i[0, 1], i[1, 1], i[0, 2], i[1, 2], i[2, 2]])


def unpack(v: np.ndarray) -> np.ndarray:
    return np.array([[v[0], v[1], v[3]], [v[1], v[2], v[4]], [v[3], v[4], v[5]]])


def change_frame(pi: np.ndarray, r: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The 10 parameters of a body given in frame B (about B's origin, B's axes) expressed in
    frame A, where B has orientation r and origin p in A. Linear in pi: for mass elements
    at s (from B's origin, A axes) the moment about A's origin sums |p+s|²·1 - (p+s)(p+s)ᵀ."""
    m, h_b, i_b = pi[0], pi[1:4], unpack(pi[4:])
    h1 = r @ h_b
    i1 = r @ i_b @ r.T
    i_a = (
        i1
        + m * (p @ p * np.eye(3) - np.outer(p, p))
        + 2.0 * (p @ h1) * np.eye(3)
        - np.outer(p, h1)
        - np.outer(h1, p)
    )
    return np.concatenate([[m], h1 + m * p, pack(i_a)])


def frame_map() -> np.ndarray:
    """T (60 x 60, block diagonal): Pinocchio's joint-frame parameters = T @ link-frame
    parameters, so that Y_link = Y_pinocchio @ T."""
    t = np.zeros((60, 60))
    for i in range(6):
        pl = link_placement(i)
        for k in range(10):
            e = np.zeros(10)
            e[k] = 1.0
            t[10 * i : 10 * i + 10, 10 * i + k] = change_frame(e, pl.rotation, pl.translation)
    return t
