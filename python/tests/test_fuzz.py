"""Property-based fuzzing of the public Python API and the CLI's CSV reader.

The contract under random shapes, dtypes, extreme values and sizes: every call either
returns a finite result or raises a `prrrp.PrrrpError` (the CSV reader: its `InputError`).
Never a panic (`pyo3.PanicException` is not an `Exception`, so it would escape the
`except` below and fail the test), an abort (kills the run), a hang (hypothesis' deadline
does not apply to hangs; the sizes drawn here are bounded so that a correct call is fast)
or a silent NaN/inf.

Profiles: `ci` (default; derandomised, bounded, about a minute) and `nightly`
(`HYPOTHESIS_PROFILE=nightly`: random seeds, 40× more examples).
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from conftest import TWO

import prrrp

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.extra import numpy as hnp  # noqa: E402

from prrrp import csvio, prediction  # noqa: E402

settings.register_profile(
    "ci",
    max_examples=40,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.register_profile(
    "nightly",
    max_examples=1600,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

EXTREME = st.sampled_from(
    [0.0, -0.0, 1.0, -1.0, 1e-300, 5e-324, 1e150, -1e150, 1e308, -1e308, math.nan, math.inf]
)
FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), EXTREME)
DTYPES = st.sampled_from([np.float64, np.float32, np.int64, np.int8, np.bool_, np.complex128])


@st.composite
def arrays(draw, near: tuple[int, ...] | None = None):
    """An array of a random dtype and a shape that is often right (`near`) and often not."""
    if near is not None and draw(st.booleans()):
        shape = near
    else:
        shape = draw(hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=7))
    dtype = draw(DTYPES)
    if dtype is np.bool_:
        elements = st.booleans()
    elif np.issubdtype(dtype, np.integer):
        info = np.iinfo(dtype)
        elements = st.integers(int(info.min), int(info.max))
    elif dtype is np.complex128:
        elements = st.complex_numbers(allow_nan=True, allow_infinity=True)
    else:
        elements = FLOATS if dtype is np.float64 else st.floats(width=32)
    a = draw(hnp.arrays(dtype, shape, elements=elements))
    kind = draw(st.sampled_from(["array", "list", "fortran", "strided"]))
    if kind == "list":
        return a.tolist()
    if kind == "fortran":
        return np.asfortranarray(a)
    if kind == "strided" and a.ndim >= 1 and a.shape[0] > 1:
        return a[::2]
    return a


ARGS = st.one_of(arrays(near=(5,)), arrays(near=(4, 5)), FLOATS, st.none(), st.text(max_size=3))


def finite(x) -> bool:
    """True when every number in a result (array, scalar, dict, tuple, object) is finite."""
    if isinstance(x, dict):
        return all(finite(v) for v in x.values())
    if isinstance(x, list | tuple):
        return all(finite(v) for v in x)
    if isinstance(x, np.ndarray):
        return x.dtype.kind not in "fc" or bool(np.isfinite(x).all())
    if isinstance(x, float | np.floating):
        return math.isfinite(x)
    return True


def holds_contract(call) -> None:
    try:
        result = call()
    except prrrp.PrrrpError:
        return
    except TypeError as e:
        # pyo3 raises TypeError only for a non-numeric Python object where a number (or
        # None) is required, e.g. a str passed as a float setting.
        message = str(e)
    else:
        assert finite(result), result
        return
    assert "argument" in message or "float" in message or "int" in message, message


ROBOT = prrrp.Robot.paper()
PUMA = prrrp.SerialChain.puma560()


@given(q=ARGS, qd=ARGS, qdd=ARGS, lam=st.one_of(st.none(), arrays(near=(8,))))
def test_robot_dynamics(q, qd, qdd, lam):
    holds_contract(lambda: ROBOT.inverse_dynamics(q, qd, qdd, lam=lam))
    holds_contract(lambda: ROBOT.forward_dynamics(q, qd, qdd, lam=lam))
    holds_contract(lambda: ROBOT.mass_matrix(q, lam=lam))
    holds_contract(lambda: ROBOT.regressor(q, qd, qdd))
    holds_contract(lambda: ROBOT.forward_derivatives(q, qd, qdd, lam=lam))


@given(q=arrays(near=(6,)), qd=arrays(near=(3, 6)), qdd=arrays(near=(6,)))
def test_chain_dynamics(q, qd, qdd):
    holds_contract(lambda: PUMA.inverse_dynamics(q, qd, qdd))
    holds_contract(lambda: PUMA.forward_dynamics(q, qd, qdd))
    holds_contract(lambda: PUMA.regressor(q, qd, qdd))
    holds_contract(lambda: PUMA.mass_matrix(q))


@given(a=ARGS, b=ARGS)
def test_metrics(a, b):
    for f in (prrrp.rms, prrrp.rsd, prrrp.agreement_index, prrrp.error_indices):
        holds_contract(lambda f=f: f(a, b))
    holds_contract(lambda: prrrp.relative_errors_percent(a, b))


@given(
    dh=arrays(near=(2, 4)),
    types=st.one_of(st.sampled_from(["RR", "RP", "R", "", "RX"]), st.text(max_size=3)),
    inertial=st.one_of(st.none(), arrays(near=(2, 10))),
    gravity=st.one_of(st.none(), arrays(near=(3,))),
    friction=st.one_of(st.none(), st.sampled_from(["viscous", "viscous+", "coulomb+offset", ""])),
)
def test_chain_constructor(dh, types, inertial, gravity, friction):
    holds_contract(
        lambda: prrrp.SerialChain(
            dh, types, inertial=inertial, gravity=gravity, friction=friction
        ).inverse_dynamics(np.zeros(2), np.zeros(2), np.zeros(2))
    )


@given(
    q=arrays(near=(60, 5)),
    noise=st.floats(allow_nan=True, allow_infinity=True),
    n=st.integers(0, 80),
)
def test_least_squares_and_preprocess(q, noise, n):
    t = 0.02 * np.arange(n)
    rng = np.random.default_rng(0)
    tau = rng.normal(size=(n, 5)) * (noise if math.isfinite(noise) else 1.0)
    holds_contract(lambda: prrrp.least_squares(q, q, q, q))
    holds_contract(lambda: prrrp.preprocess(t, rng.normal(size=(n, 5)), tau))


@given(text=st.text(max_size=400))
def test_urdf_text(text):
    holds_contract(lambda: prrrp.SerialChain.from_urdf("<" + text))


URDF_PIECES = st.sampled_from(
    [
        '<robot name="r">',
        "</robot>",
        '<link name="a"/>',
        '<link name="b"><inertial><mass value="1"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>',
        '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
        '<axis xyz="0 0 1"/></joint>',
        '<joint name="k" type="prismatic"><parent link="b"/><child link="a"/></joint>',
        '<joint name="f" type="floating"><parent link="a"/><child link="c"/></joint>',
        '<axis xyz="0 0 0"/>',
        '<origin xyz="1e308 0 0" rpy="nan 0 0"/>',
    ]
)


HOSTILE_URDF_PIECES = st.sampled_from(
    [
        '<robot name="r" version="1.1">',
        '<joint name="c" type="revolute"><parent link="b"/><child link="a"/>'
        '<axis xyz="0 0 1"/></joint>',
        '<origin xyz="0 0 0" quat_xyzw="nan nan nan nan"/>',
        '<origin quat_xyzw="0 0 0 0"/>',
        '<origin quat_xyzw="0 0 0.7071067811865476 0.7071067811865476"/>',
        "<x>" * 70,
        "</x>" * 70,
        "<x>" * 20 + "</x>" * 20,
        '<origin xyz="inf 0 0"/>',
    ]
)


@given(
    pieces=st.lists(URDF_PIECES | HOSTILE_URDF_PIECES, max_size=8),
    base=st.sampled_from([None, "a", "b", "c"]),
    tip=st.sampled_from([None, "a", "b", "c"]),
)
def test_urdf_structures(pieces, base, tip):
    # Cycles through --base, deep nesting, NaN or zero quaternions: a chain or a typed
    # error, never a hang, an abort or a stack overflow.
    holds_contract(lambda: prrrp.SerialChain.from_urdf("".join(pieces), base=base, tip=tip))


NAMES = st.text(min_size=0, max_size=12)


@given(link=NAMES, joint=NAMES, robot=NAMES)
def test_urdf_names_round_trip(link, joint, robot):
    """Any name a URDF can hold survives read → to_urdf → read; any other is refused by
    one of the two with a typed error, never written into a file that does not read."""
    from xml.sax.saxutils import quoteattr

    xml = (
        f'<robot name={quoteattr(robot)}><link name="base"/><link name={quoteattr(link)}/>'
        f'<joint name={quoteattr(joint)} type="continuous"><parent link="base"/>'
        f'<child link={quoteattr(link)}/><axis xyz="0 0 1"/></joint></robot>'
    )
    try:
        chain = prrrp.SerialChain.from_urdf(xml)
    except prrrp.PrrrpError:
        return
    try:
        text = chain.to_urdf()
    except prrrp.PrrrpError:
        return
    back = prrrp.SerialChain.from_urdf(text)
    assert back.joint_names == chain.joint_names
    assert back.link_names == chain.link_names
    assert back.name == chain.name


@given(body=st.binary(max_size=600))
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_csv_reader(tmp_path_factory, body):
    path = tmp_path_factory.mktemp("csv") / "data.csv"
    header = ",".join(csvio.REQUIRED_COLUMNS).encode()
    path.write_bytes(header + b"\n" + body)
    try:
        data = csvio.read_measurements(path)
    except csvio.InputError:
        return
    assert all(np.isfinite(v).all() for v in data.values())


@given(rows=st.lists(st.lists(FLOATS, min_size=11, max_size=11), max_size=40))
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_csv_reader_numbers(tmp_path_factory, rows):
    path = tmp_path_factory.mktemp("csv") / "data.csv"
    lines = [",".join(csvio.REQUIRED_COLUMNS)] + [",".join(repr(x) for x in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    try:
        data = csvio.read_measurements(path)
    except csvio.InputError:
        return
    assert all(np.isfinite(v).all() for v in data.values())


# ------------------------------------------------------------------ any robot's workflow

SEVEN = prrrp.SerialChain.from_urdf(
    TWO,
    friction="viscous+coulomb",
)


@given(
    body=st.binary(max_size=600),
    header=st.sampled_from(
        [b"t,q1,q2,tau1,tau2", b"t,q1,q2,tau1,tau2,qd1,qd2", b"t,q1,q2,q3,tau1", b"time,q1"]
    ),
)
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_any_robot_csv_reader(tmp_path_factory, body, header):
    path = tmp_path_factory.mktemp("csv") / "log.csv"
    path.write_bytes(header + b"\n" + body)
    try:
        raw = prrrp.read_measurements(path, SEVEN)
    except csvio.InputError:
        return
    assert all(np.isfinite(v).all() for v in raw.values())
    holds_contract(lambda: prrrp.measurements_to_dataset(raw))


@given(
    harmonics=st.one_of(st.integers(-3, 8), st.just(2**63)),
    base_frequency=FLOATS,
    sample_rate=FLOATS,
    margin=FLOATS,
    evaluations=st.integers(0, 60),
)
def test_design_excitation(harmonics, base_frequency, sample_rate, margin, evaluations):
    try:
        out = prrrp.design_excitation(
            SEVEN,
            harmonics=harmonics,
            base_frequency=base_frequency,
            sample_rate=sample_rate,
            margin=margin,
            restarts=2,
            max_evaluations=evaluations,
        )
    except prrrp.PrrrpError:
        return
    out = {k: v for k, v in out.items() if k not in ("trajectory", "limit_usage")}
    assert finite(out), out


@given(candidates=st.one_of(st.none(), st.lists(FLOATS, max_size=4)), folds=st.integers(0, 6))
def test_coulomb_scale(candidates, folds):
    t = np.arange(40) * 0.05
    q = np.column_stack([np.sin(t), np.cos(1.3 * t)])
    qd = np.column_stack([np.cos(t), -1.3 * np.sin(1.3 * t)])
    qdd = np.column_stack([-np.sin(t), -1.69 * np.cos(1.3 * t)])
    data = prrrp.Dataset(t, q, qd, qdd, SEVEN.inverse_dynamics(q, qd, qdd))
    holds_contract(lambda: SEVEN.coulomb_scale(data, candidates=candidates, folds=folds))


# ------------------------------------------------------------------ estimators on any data

METHODS = ("ls", "wls", "rls", "adaline", "hopfield", "ekf", "physical")


@st.composite
def datasets(draw):
    """Columns of a Dataset of SEVEN: exact torques of a smooth motion (so that every method has
    something to find), then a random corruption: extreme values in one column, a
    constant (unexciting) motion, few samples, or a scale far from SI."""
    n = draw(st.integers(0, 60))
    t = 0.02 * np.arange(n)
    q = np.column_stack([np.sin(1.3 * t), np.cos(0.7 * t)])
    qd = np.column_stack([1.3 * np.cos(1.3 * t), -0.7 * np.sin(0.7 * t)])
    qdd = np.column_stack([-1.69 * np.sin(1.3 * t), -0.49 * np.cos(0.7 * t)])
    tau = SEVEN.inverse_dynamics(q, qd, qdd) if n else np.zeros((0, 2))
    cols = [q, qd, qdd, tau]
    kind = draw(st.sampled_from(["clean", "extreme", "constant", "scaled"]))
    if n and kind == "extreme":
        k, row, j = draw(st.integers(0, 3)), draw(st.integers(0, n - 1)), draw(st.integers(0, 1))
        cols[k] = cols[k].copy()
        cols[k][row, j] = draw(EXTREME)
    elif kind == "constant":
        cols = [np.zeros_like(c) for c in cols[:3]] + [cols[3]]
    elif kind == "scaled":
        cols[3] = cols[3] * draw(st.sampled_from([1e-200, 1e150, 1e300, -1.0]))
    return t, cols


@given(
    data=datasets(),
    method=st.one_of(st.sampled_from(METHODS), st.text(max_size=4)),
    setting=st.sampled_from(
        [{}, {"max_epochs": 3}, {"max_epochs": 0}, {"forgetting": 0.5}, {"forgetting": 2.0}]
    ),
)
def test_identify_any_data(data, method, setting):
    """`prrrp.identify` on corrupted data of any method: a typed error or a model whose
    numbers are finite; an unknown setting or method is a TypeError / PrrrpError."""
    t, cols = data
    try:
        model = prrrp.identify(SEVEN, prrrp.Dataset(t, *cols), method, **setting)
    except (prrrp.PrrrpError, TypeError):
        return
    assert finite(np.asarray(model.beta)), model.beta
    assert finite(np.asarray(model.residual_rms))


@given(
    q=arrays(near=(30, 2)),
    tau=arrays(near=(30, 2)),
    kind=st.sampled_from(["adaline", "hopfield", "rls", "ekf"]),
    epochs=st.one_of(st.integers(-2, 3), st.just(2**63), st.just(10**12)),
    rate=FLOATS,
)
def test_estimator_classes(q, tau, kind, epochs, rate):
    """The estimator classes of a chain with random arrays, step sizes and epoch counts:
    a typed error or finite estimates, never a panic, abort or huge allocation."""

    def run():
        if kind == "adaline":
            est = prrrp.Adaline(SEVEN, learning_rate=rate)
            return est.train(q, q, q, tau, epochs), est.estimate
        if kind == "hopfield":
            est = prrrp.Hopfield(SEVEN, dt=rate)
            return est.train(q, q, q, tau, epochs), est.estimate
        if kind == "rls":
            return prrrp.Rls(SEVEN, forgetting=rate).run(q, q, q, tau)
        est = prrrp.Ekf(SEVEN, dt=rate)
        return est.run(q, q, q, tau), est.parameter_std

    holds_contract(run)


# ------------------------------------------------------------- issue 25: input surfaces

JOINTS = list(SEVEN.joint_names)
NAME = st.one_of(st.sampled_from([*JOINTS, "gripper"]), st.text(max_size=3))


@st.composite
def joint_states(draw):
    """JointState messages that are often right and often not: names repeated or missing,
    position/velocity/effort arrays of any length."""
    count = draw(st.integers(0, 12))
    messages = []
    for k in range(count):
        names = [*JOINTS] if draw(st.booleans()) else draw(st.lists(NAME, max_size=4))
        n = len(names)
        lengths = [
            draw(st.one_of(st.just(n), st.integers(0, n + 2))) for _ in ("position", "velocity")
        ]
        effort = draw(st.one_of(st.just(n), st.integers(0, n + 2)))
        value = draw(st.one_of(st.just(0.1 * k), FLOATS))
        messages.append(
            (
                100.0 + 0.01 * k,
                names,
                np.full(lengths[0], value),
                np.zeros(lengths[1]),
                np.ones(effort),
            )
        )
    return messages


@given(messages=joint_states())
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture], max_examples=25)
def test_bag_messages(tmp_path_factory, messages):
    """A bag of malformed JointState messages: an InputError naming the bag, or
    measurements with one finite row per message and the robot's joints."""
    pytest.importorskip("rosbags")
    from test_measurements import write_messages

    bag = tmp_path_factory.mktemp("bag") / "bag"
    write_messages(bag, messages)
    try:
        raw = prrrp.read_measurements(bag, SEVEN)
    except csvio.InputError as e:
        error = str(e)
    else:
        error = None
    if error is not None:
        assert str(bag) in error
        return
    assert len(raw["t"]) == len(messages)
    for key in ("q", "tau"):
        assert raw[key].shape == (len(messages), 2)
        assert np.isfinite(raw[key]).all()
    for _, names, position, velocity, effort in messages:
        assert len(set(names)) == len(names)
        assert len(position) == len(effort) == len(names)
        assert len(velocity) in (0, len(names))


@given(
    table=hnp.arrays(
        np.float64,
        st.tuples(st.integers(20, 70), st.just(11)),
        elements=st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False),
    ),
    chunk=st.integers(1, 9),
    bad=st.one_of(st.none(), st.tuples(st.integers(0, 69), st.integers(1, 10))),
)
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_csv_streaming_reader(tmp_path_factory, table, chunk, bad):
    """The block-by-block reader equals numpy's reading of the same file at any block size,
    and a bad cell's error names its line and column."""
    import unittest.mock

    table = table.copy()
    table[:, 0] = np.arange(len(table)) * 0.01
    lines = csvio.format_table(list(csvio.REQUIRED_COLUMNS), table).splitlines()
    if bad is not None and bad[0] < len(table):
        row, col = bad
        cells = lines[row + 1].split(",")
        cells[col] = "x1"
        lines[row + 1] = ",".join(cells)
    path = tmp_path_factory.mktemp("csv") / "data.csv"
    path.write_text("\n".join(lines) + "\n")
    error = None
    with unittest.mock.patch.object(csvio, "CHUNK_LINES", chunk):
        try:
            data = csvio.read_measurements(path)
        except csvio.InputError as e:
            error = str(e)
    if error is not None:
        assert bad is not None
        assert f"line {bad[0] + 2}, column '{csvio.REQUIRED_COLUMNS[bad[1]]}'" in error
        return
    assert bad is None or bad[0] >= len(table)
    reference = np.loadtxt(path, delimiter=",", skiprows=1)
    assert np.array_equal(data["t"], reference[:, 0])
    assert np.array_equal(data["q"], reference[:, 1:6])
    assert np.array_equal(data["tau"], reference[:, 6:11])


JSON_VALUES = st.recursive(
    st.one_of(
        st.none(),
        st.booleans(),
        st.integers(-(2**70), 2**70),
        st.floats(allow_nan=False, allow_infinity=False),
        st.text(max_size=4),
    ),
    lambda inner: st.one_of(
        st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=3), inner, max_size=3)
    ),
    max_leaves=5,
)


def _model_document() -> dict:
    t = np.arange(0, 4, 0.01)
    q = np.column_stack([0.8 * np.sin(t), 0.6 * np.cos(1.3 * t)])
    qd = np.column_stack([0.8 * np.cos(t), -0.78 * np.sin(1.3 * t)])
    qdd = np.column_stack([-0.8 * np.sin(t), -1.014 * np.cos(1.3 * t)])
    data = prrrp.Dataset(t, q, qd, qdd, SEVEN.inverse_dynamics(q, qd, qdd))
    record = {"settings": {"cutoff_hz": 5.0}, "report": None, "coulomb_scale": None}
    model = prrrp.identify(SEVEN, data, "ls", preprocessing=record)
    import json

    return json.loads(model.to_json())


MODEL_DOC = _model_document()
PATHS = [
    ("preprocessing", "settings", "cutoff_hz"),
    ("preprocessing", "settings", "order"),
    ("preprocessing", "settings", "filter_torque"),
    ("preprocessing", "settings", "rate_hz"),
    ("preprocessing", "settings"),
    ("preprocessing",),
    ("settings", "epochs"),
    ("settings",),
    ("epochs",),
    ("converged",),
    ("cond",),
    ("method",),
]


@given(where=st.sampled_from(PATHS), value=JSON_VALUES)
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_hand_edited_model_json(tmp_path_factory, where, value):
    """A model.json with any JSON value at a setting: loading and `prrrp predict`'s
    preparation end in a typed error (PrrrpError, or ValueError naming the setting) or a
    prediction at every row of the log."""
    import copy
    import json

    doc = copy.deepcopy(MODEL_DOC)
    node = doc
    for key in where[:-1]:
        if not isinstance(node.get(key), dict):
            node[key] = {}
        node = node[key]
    node[where[-1]] = value
    folder = tmp_path_factory.mktemp("model")
    path = folder / "model.json"
    path.write_text(json.dumps(doc))
    t = np.arange(0, 3, 0.01)
    q = np.column_stack([np.sin(t), np.cos(t)])
    raw = {"t": t, "q": q, "tau": SEVEN.inverse_dynamics(q, q, q)}
    try:
        model = prrrp.IdentifiedModel.load(path)
        grid = prediction.prepare(raw, prediction.recorded_settings(model))
        tau = grid.predict(model)
    except (prrrp.PrrrpError, ValueError):
        return
    assert tau.shape == (len(t), 2)
    assert np.isfinite(tau).all()


@given(umask=st.integers(0, 0o777))
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture], max_examples=20)
def test_output_folder_mode(tmp_path_factory, umask):
    from prrrp import outdir

    folder = tmp_path_factory.mktemp("out")
    old = os.umask(umask & 0o077)  # the owner keeps rwx, or the test could not clean up
    try:
        outdir.write_dir(folder / "o", lambda tmp: (tmp / "a").write_text("1"))
    finally:
        os.umask(old)
    assert (folder / "o").stat().st_mode & 0o777 == 0o777 & ~(umask & 0o077)


@given(duration=FLOATS, rate=FLOATS)
def test_excite_sizes(duration, rate):
    """Any duration and rate: a typed error (refused before allocating when too large) or
    a trajectory of rate × duration + 1 samples."""
    from prrrp import workflow

    samples = duration * rate
    if math.isfinite(samples) and 1e5 < samples <= workflow.MAX_SAMPLES:
        return  # accepted and large: right, but too slow and big for this property's budget
    try:
        out = workflow.excite(
            SEVEN, duration, rate=rate, harmonics=1, max_evaluations=2, restarts=1
        )
    except (prrrp.PrrrpError, ValueError):
        return
    assert len(out["t"]) == round(duration * rate) + 1 <= workflow.MAX_SAMPLES + 1
    assert np.isfinite(out["q"]).all()
