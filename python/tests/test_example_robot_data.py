"""Every robot description that the `example-robot-data` package ships, read by prrrp and
by Pinocchio: for up to four base-to-leaf chains of each file, prrrp's inverse dynamics
equals Pinocchio's (its model of the whole file, reduced to the chain with every other
joint locked at zero) on random states. Files prrrp has never been tuned on: humanoids,
quadrupeds, hands, mobile manipulators, with their geometry quirks (iCub's and Romeo's
`<texture />` without a file name, which urdf-rs alone refuses)."""

from __future__ import annotations

import importlib.metadata
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import pin_configuration

import prrrp

pin = pytest.importorskip("pinocchio")

ROBOTS_DIR = Path(
    importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
)
URDFS = sorted(ROBOTS_DIR.rglob("*.urdf"))
MOVABLE = {"revolute", "continuous", "prismatic"}
RTOL = 1e-9


def leaf_chains(urdf: Path, most: int = 4) -> list[tuple[str, list[str], bool]]:
    """(leaf link, movable joints from the root to it, whether one of them is a mimic
    joint) for the first ``most`` leaves with a movable joint on the way."""
    root = ET.parse(urdf).getroot()
    joints = root.findall("joint")
    parents = {j.find("parent").get("link") for j in joints}
    into = {j.find("child").get("link"): j for j in joints}
    chains = []
    for link in (el.get("name") for el in root.findall("link")):
        if link in parents or link not in into:
            continue
        path, mimic, at = [], False, link
        while at in into:
            joint = into[at]
            if joint.get("type") in MOVABLE:
                path.insert(0, joint.get("name"))
                mimic |= joint.find("mimic") is not None
            at = joint.find("parent").get("link")
        if path:
            chains.append((link, path, mimic))
        if len(chains) == most:
            break
    return chains


@pytest.mark.parametrize("urdf", URDFS, ids=lambda p: str(p.relative_to(ROBOTS_DIR)))
def test_every_chain_matches_pinocchio(urdf: Path) -> None:
    try:
        full = pin.buildModelFromUrdf(str(urdf))
    except Exception as e:  # Pinocchio's own limits (e.g. a robot without a name)
        pytest.skip(f"Pinocchio cannot read it: {e}")
    rng = np.random.default_rng(7)
    compared = 0
    for leaf, path, mimic in leaf_chains(urdf):
        if mimic:
            # Not an independent coordinate: a typed error that says so.
            with pytest.raises(prrrp.RobotFileError, match="mimic"):
                prrrp.SerialChain.from_urdf(str(urdf), tip=leaf)
            continue
        chain = prrrp.SerialChain.from_urdf(str(urdf), tip=leaf)
        assert list(chain.joint_names) == path, leaf
        locked = [full.getJointId(n) for n in list(full.names)[1:] if n not in path]
        try:
            model = pin.buildReducedModel(full, locked, pin.neutral(full)) if locked else full
        except Exception:  # Pinocchio refuses links and joints of the same name
            continue
        model.gravity.linear = np.asarray(chain.gravity)
        data = model.createData()
        n = chain.dof
        assert model.nv == n, leaf
        at = [list(model.names)[1:].index(name) for name in path]  # prrrp k -> Pinocchio
        for _ in range(5):
            q, qd, qdd = rng.uniform(-2, 2, n), rng.normal(0, 1, n), rng.normal(0, 2, n)
            qp, qdp, qddp = np.zeros(n), np.zeros(n), np.zeros(n)
            qp[at], qdp[at], qddp[at] = q, qd, qdd
            expected = pin.rnea(model, data, pin_configuration(model, qp), qdp, qddp)[at]
            tau = np.asarray(chain.inverse_dynamics(q, qd, qdd))
            scale = max(np.abs(expected).max(), 1e-9)
            assert np.abs(tau - expected).max() <= RTOL * scale, (leaf, tau, expected)
        compared += 1
    if compared == 0:
        pytest.skip("no chain Pinocchio can reduce to")
