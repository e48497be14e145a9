"""The PRRRP arm built by hand in Pinocchio, an independent rigid-body library.

Conventions of shared/notes/paper.md: joint 1 prismatic along world +z; joints 2-4 revolute
about vertical axes, each next joint l_i along the previous link's x axis; joint 5 prismatic
along world -z at the end of link 4. Links 2-4 have their centre of mass on the link x axis
at lc from the joint and I_zz about the centre of mass; link 5 is a point mass. Gravity along
-z. Nothing here comes from prrrp except the robot's physical parameters.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

# Ixx, Iyy of links 1-4 never enter motions about vertical axes; they only have to make the
# bodies physical.
_SMALL = 1e-4


def build(mass, length, com, inertia_zz, gravity: float = 9.81) -> pin.Model:
    model = pin.Model()
    model.gravity.linear = np.array([0.0, 0.0, -gravity])

    def body(parent, joint, placement, inertia, name):
        jid = model.addJoint(parent, joint, placement, name)
        model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        return jid

    def link(m, lc, izz):
        return pin.Inertia(m, np.array([lc, 0.0, 0.0]), np.diag([_SMALL, _SMALL, izz]))

    def along_x(a):
        return pin.SE3(np.eye(3), np.array([a, 0.0, 0.0]))

    j1 = body(
        0,
        pin.JointModelPZ(),
        pin.SE3.Identity(),
        pin.Inertia(mass[0], np.zeros(3), np.eye(3) * _SMALL),
        "d1",
    )
    up = pin.SE3(np.eye(3), np.array([0.0, 0.0, length[0]]))
    j2 = body(j1, pin.JointModelRZ(), up, link(mass[1], com[0], inertia_zz[0]), "theta2")
    j3 = body(
        j2, pin.JointModelRZ(), along_x(length[1]), link(mass[2], com[1], inertia_zz[1]), "theta3"
    )
    j4 = body(
        j3, pin.JointModelRZ(), along_x(length[2]), link(mass[3], com[2], inertia_zz[2]), "theta4"
    )
    # Joint 5 slides along -z: a prismatic joint on an axis pointing down. Link 5 is a
    # point mass, with no rotational inertia at all.
    body(
        j4,
        pin.JointModelPrismaticUnaligned(np.array([0.0, 0.0, -1.0])),
        along_x(length[3]),
        pin.Inertia(mass[4], np.zeros(3), np.zeros((3, 3))),
        "d5",
    )
    return model


def from_robot(robot) -> pin.Model:
    return build(robot.mass, robot.length, robot.com, robot.inertia_zz, robot.g)
