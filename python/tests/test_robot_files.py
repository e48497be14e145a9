"""Robots from URDF and TOML files, checked against Pinocchio on the real descriptions that
the `example-robot-data` package ships (Panda with its fingers locked, UR5, Kinova Gen2).

Pinocchio builds its own model from the same file (`pin.buildModelFromUrdf`, reduced with
`pin.buildReducedModel` where joints are locked): inverse dynamics, mass matrix, regressor,
forward dynamics and the rank of its stacked joint-torque regressor are compared with
prrrp's on random states.
"""

import importlib.metadata
import math

import numpy as np
import pytest
from conftest import pin_configuration

import prrrp

pin = pytest.importorskip("pinocchio")

ROBOTS_DIR = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)

# name: (URDF path under ROBOTS_DIR, tip link or None, joints that must be locked)
ROBOTS = {
    "panda": (
        "panda_description/urdf/panda.urdf",
        "panda_link8",
        {"panda_finger_joint1", "panda_finger_joint2"},
    ),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", None, set()),
    "kinova": ("kinova_description/robots/kinova.urdf", None, set()),
}

RTOL = 1e-9


def urdf_path(name):
    return str(ROBOTS_DIR / ROBOTS[name][0])


def load_prrrp(name):
    _, tip, _ = ROBOTS[name]
    return prrrp.SerialChain.from_urdf(urdf_path(name), tip=tip)


def load_pinocchio(name):
    """Pinocchio's model of the same file, with the off-path joints locked at zero."""
    model = pin.buildModelFromUrdf(urdf_path(name))
    _, _, locked = ROBOTS[name]
    if locked:
        ids = [model.getJointId(j) for j in sorted(locked)]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    return model


def rel(a, b):
    return np.abs(np.asarray(a) - np.asarray(b)).max() / max(np.abs(b).max(), 1e-300)


def random_states(n, count, seed):
    rng = np.random.default_rng(seed)
    return (
        rng.uniform(-math.pi, math.pi, (count, n)),
        rng.uniform(-2.0, 2.0, (count, n)),
        rng.uniform(-5.0, 5.0, (count, n)),
    )


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def robot(request):
    name = request.param
    return name, load_prrrp(name), load_pinocchio(name)


def test_joints_match_pinocchio(robot):
    name, chain, model = robot
    assert chain.dof == model.nv
    assert chain.joint_names == [model.names[j] for j in range(1, model.njoints)]
    assert set(chain.locked_joints) == ROBOTS[name][2]


def test_dynamics_match_pinocchio(robot):
    _, chain, model = robot
    data = model.createData()
    q, qd, qdd = random_states(chain.dof, 20, seed=1)
    tau = chain.inverse_dynamics(q, qd, qdd)
    mass = chain.mass_matrix(q)
    y = chain.regressor(q, qd, qdd)
    fwd = chain.forward_dynamics(q, qd, tau)
    for k in range(len(q)):
        qp = pin_configuration(model, q[k])
        tau_pin = pin.rnea(model, data, qp, qd[k], qdd[k])
        assert rel(tau[k], tau_pin) < RTOL
        m_pin = pin.crba(model, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        assert rel(mass[k], m_pin) < RTOL
        y_pin = pin.computeJointTorqueRegressor(model, data, qp, qd[k], qdd[k])
        # Same frames (URDF joint frames), same parameter order: the regressors agree entry
        # by entry, and Y·π reproduces Pinocchio's torques.
        assert rel(y[k], y_pin) < RTOL
        assert rel(y[k] @ chain.parameters, tau_pin) < RTOL
        assert rel(fwd[k], qdd[k]) < 1e-8
        assert rel(pin.aba(model, data, qp, qd[k], tau[k]), qdd[k]) < 1e-8


def test_inertials_match_pinocchio(robot):
    _, chain, model = robot
    pin_params = np.array(
        [model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)]
    )
    assert rel(chain.inertial, pin_params) < RTOL


def stacked_pin_regressor_rank(model, n, samples, seed):
    data = model.createData()
    q, qd, qdd = random_states(n, samples, seed)
    w = np.vstack(
        [
            pin.computeJointTorqueRegressor(
                model, data, pin_configuration(model, q[k]), qd[k], qdd[k]
            )
            for k in range(samples)
        ]
    )
    # Columns that vanish in exact arithmetic (e.g. m·x of a link on a vertical axis) carry
    # round-off of ~1e-11 relative; scaled to unit norm they would count as rank. Drop
    # them, scale the others to unit norm, and count the singular values above 1e-8.
    norms = np.linalg.norm(w, axis=0)
    keep = norms > 1e-9 * norms.max()
    s = np.linalg.svd(w[:, keep] / norms[keep], compute_uv=False)
    return int((s > 1e-8 * s[0]).sum())


def test_base_parameter_count_matches_pinocchio_rank(robot):
    _, chain, model = robot
    rank = stacked_pin_regressor_rank(model, chain.dof, 40 * chain.dof, seed=3)
    assert chain.base_parameters().count == rank


def test_friction_adds_three_base_parameters_per_joint(robot):
    name, chain, _ = robot
    _, tip, _ = ROBOTS[name]
    with_friction = prrrp.SerialChain.from_urdf(
        urdf_path(name), tip=tip, friction=["viscous", "coulomb", "offset"]
    )
    base = chain.base_parameters().count
    assert with_friction.base_parameters().count == base + 3 * chain.dof


def test_limits_come_from_the_file():
    chain = load_prrrp("panda")
    limits = chain.limits
    assert set(limits) == {"lower", "upper", "velocity", "acceleration", "effort"}
    # Panda joint 4: lower="-3.0718" upper="-0.0698" velocity="2.1750" effort="87".
    assert limits["lower"][3] == pytest.approx(-3.0718)
    assert limits["upper"][3] == pytest.approx(-0.0698)
    assert limits["velocity"][3] == pytest.approx(2.1750)
    assert limits["effort"][3] == pytest.approx(87.0)
    assert np.isnan(limits["acceleration"]).all()
    # Kinova's continuous joints have no position limits.
    kinova = load_prrrp("kinova")
    assert np.isnan(kinova.limits["lower"][0])
    assert np.isnan(kinova.limits["upper"][0])


def test_panda_without_tip_lists_the_candidate_tips():
    with pytest.raises(prrrp.PrrrpError, match="leftfinger") as e:
        prrrp.SerialChain.from_urdf(urdf_path("panda"))
    text = str(e.value)
    assert "rightfinger" in text
    # The arm's end (where the fingers branch) is proposed first, in CLI and Python terms.
    assert text.index("`panda_hand`") < text.index("`panda_leftfinger`")
    assert "--tip LINK (Python: tip=)" in text
    assert "UrdfOptions" not in text
    chain = prrrp.SerialChain.from_urdf(urdf_path("panda"), tip="panda_hand")
    assert chain.dof == 7


PANDA_DH = {
    "a": [0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088],
    "d": [0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0],
    "alpha": [0.0, -math.pi / 2, math.pi / 2, math.pi / 2, -math.pi / 2, math.pi / 2, math.pi / 2],
}


def panda_toml(inertial):
    lines = ['name = "panda"', 'convention = "modified"', "gravity = [0, 0, -9.81]"]
    for i in range(7):
        row = ", ".join(repr(float(x)) for x in inertial[i])
        lines += [
            "[[joint]]",
            'type = "revolute"',
            f"a = {PANDA_DH['a'][i]!r}",
            f"alpha = {PANDA_DH['alpha'][i]!r}",
            f"d = {PANDA_DH['d'][i]!r}",
            "theta = 0",
            f"inertial = [{row}]",
        ]
    return "\n".join(lines) + "\n"


def test_panda_dh_toml_equals_the_urdf(tmp_path):
    urdf = load_prrrp("panda")
    path = tmp_path / "panda.toml"
    path.write_text(panda_toml(urdf.inertial))
    toml = prrrp.SerialChain.from_file(str(path))
    assert toml.convention == "modified"
    q, qd, qdd = random_states(7, 20, seed=5)
    assert rel(toml.inverse_dynamics(q, qd, qdd), urdf.inverse_dynamics(q, qd, qdd)) < RTOL
    assert rel(toml.mass_matrix(q), urdf.mass_matrix(q)) < RTOL


def test_urdf_round_trip_and_export_loads_in_pinocchio(robot, tmp_path):
    name, chain, _ = robot
    text = chain.to_urdf()
    again = prrrp.SerialChain.from_urdf(text)
    q, qd, qdd = random_states(chain.dof, 10, seed=7)
    assert rel(again.inverse_dynamics(q, qd, qdd), chain.inverse_dynamics(q, qd, qdd)) < 1e-12
    assert rel(again.mass_matrix(q), chain.mass_matrix(q)) < 1e-12
    # The exported file is a URDF Pinocchio reads, with the same dynamics.
    path = tmp_path / f"{name}.urdf"
    path.write_text(text)
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    tau = chain.inverse_dynamics(q, qd, qdd)
    for k in range(len(q)):
        tau_pin = pin.rnea(model, data, pin_configuration(model, q[k]), qd[k], qdd[k])
        assert rel(tau[k], tau_pin) < RTOL


def test_export_with_new_parameters():
    chain = load_prrrp("ur5")
    params = chain.parameters * 1.5  # scaling every inertial keeps a rigid body
    again = prrrp.SerialChain.from_urdf(chain.to_urdf(params))
    np.testing.assert_allclose(again.parameters, params, rtol=1e-12, atol=1e-15)


def test_puma_dh_chain_exports_to_an_equivalent_urdf():
    puma = prrrp.SerialChain.puma560()
    again = prrrp.SerialChain.from_urdf(puma.to_urdf())
    q, qd, qdd = random_states(6, 10, seed=8)
    assert rel(again.inverse_dynamics(q, qd, qdd), puma.inverse_dynamics(q, qd, qdd)) < 1e-12


BAD_INERTIA = """<robot name="bad">
  <link name="base"/>
  <link name="l1">
    <inertial><mass value="{mass}"/><origin xyz="0 0 0.1"/>
      <inertia ixx="{ixx}" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="2" effort="10"/></joint>
</robot>"""


@pytest.mark.parametrize(("mass", "ixx"), [(-1.0, 0.01), (1.0, 0.5)])
def test_non_physical_inertials_load_and_are_flagged(mass, ixx):
    chain = prrrp.SerialChain.from_urdf(BAD_INERTIA.format(mass=mass, ixx=ixx))
    assert not chain.is_physically_consistent()
    assert chain.non_physical_links == ["l1"]
    # Forward dynamics needs a rigid body: refused, naming the link.
    with pytest.raises(prrrp.InvalidParameterError, match="'l1'"):
        chain.forward_dynamics([0.0], [0.0], [0.0])
    good = prrrp.SerialChain.from_urdf(BAD_INERTIA.format(mass=1.0, ixx=0.01))
    assert good.is_physically_consistent()


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("<robot name='x'><link name='a'/>", "XML"),
        (BAD_INERTIA.replace('xyz="0 0 1"', 'xyz="0 0 0"'), "j1"),
        (BAD_INERTIA.replace('xyz="0 0 1"', 'xyz="0 0 2"'), "j1"),
        # Spelt with all 309 digits of each number, a 756-character message.
        (BAD_INERTIA.replace('xyz="0 0 1"', 'xyz="1e308 1e308 0"'), '"1e308 1e308 0"'),
        (BAD_INERTIA.replace('type="revolute"', 'type="floating"'), "j1"),
        (BAD_INERTIA.replace('type="revolute"', 'type="planar"'), "j1"),
    ],
)
def test_bad_urdf_is_a_typed_error(text, fragment):
    with pytest.raises(prrrp.PrrrpError, match=fragment):
        prrrp.SerialChain.from_urdf(text.format(mass=1.0, ixx=0.01))


def test_bad_base_or_tip_names_the_link():
    text = BAD_INERTIA.format(mass=1.0, ixx=0.01)
    with pytest.raises(prrrp.PrrrpError, match="nolink"):
        prrrp.SerialChain.from_urdf(text, tip="nolink")
    with pytest.raises(prrrp.PrrrpError, match="base"):
        prrrp.SerialChain.from_urdf(text, base="l1", tip="base")


def test_bad_toml_names_the_key(tmp_path):
    path = tmp_path / "r.toml"
    path.write_text('name = "r"\nconvention = "standard"\ncolour = 3\n')
    with pytest.raises(prrrp.PrrrpError, match="colour"):
        prrrp.SerialChain.from_file(str(path))
    path.write_text('convention = "standard"\n[[joint]]\ntype = "revolute"\na = "x"\n')
    with pytest.raises(prrrp.PrrrpError, match="a"):
        prrrp.SerialChain.from_file(str(path))
    with pytest.raises(prrrp.PrrrpError, match="xyz"):
        prrrp.SerialChain.from_file(str(tmp_path / "robot.xyz"))
    with pytest.raises(prrrp.PrrrpError, match="missing"):
        prrrp.SerialChain.from_file(str(tmp_path / "missing.urdf"))
