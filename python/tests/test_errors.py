"""Errors: every bad input raises a prrrp exception that names the argument and says what
to fix; input faults are also ValueErrors; no Rust panic reaches Python."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import shape_error_of_qd

import prrrp
from prrrp import csvio, outdir

UR5_LIKE = Path(__file__).resolve().parents[2] / "tests" / "data" / "ur5_like_friction.toml"


def test_hierarchy():
    assert issubclass(prrrp.PrrrpError, Exception)
    assert issubclass(prrrp.InvalidInputError, prrrp.PrrrpError)
    assert issubclass(prrrp.InvalidInputError, ValueError)
    for exc in [
        prrrp.InvalidParameterError,
        prrrp.NonFiniteError,
        prrrp.ShapeMismatchError,
        prrrp.TooFewSamplesError,
        prrrp.NonIncreasingTimeError,
        prrrp.RankDeficientError,
        prrrp.NotPositiveDefiniteError,
        prrrp.InfeasibleError,
    ]:
        assert issubclass(exc, prrrp.InvalidInputError), exc
        assert exc.__module__ == "prrrp"
        assert exc.__doc__
    assert issubclass(prrrp.DivergedError, prrrp.PrrrpError)
    assert issubclass(prrrp.DivergedError, ArithmeticError)
    assert not issubclass(prrrp.DivergedError, ValueError)
    # The Python side's own errors are prrrp errors too, so one `except prrrp.PrrrpError`
    # catches whatever prrrp raises.
    assert issubclass(prrrp.TrackingError, prrrp.PrrrpError)
    assert issubclass(prrrp.TrackingError, RuntimeError)
    assert issubclass(csvio.InputError, prrrp.InvalidInputError)
    assert issubclass(outdir.OutputDirError, prrrp.InvalidInputError)


def test_python_api_refusals_are_prrrp_errors():
    robot = prrrp.load_robot(str(UR5_LIKE))
    with pytest.raises(prrrp.InvalidInputError, match="rate"):
        prrrp.excite(robot, 10.0, rate=1e-300)
    traj = prrrp.excite(robot, 10.0, max_evaluations=20)
    with pytest.raises(prrrp.InvalidInputError, match="noise"):
        prrrp.simulate(robot, traj, noise=1e300)
    # Epoch-sized time stamps (t + 1e9 s) were "not uniformly spaced": their own round-off
    # (1e-7 s) exceeded the 1e-6·dt tolerance. The run is the one from t = 0 but for that
    # round-off: the rate taken from the stamps is off by ~1e-5 of itself, and so is τ.
    late = {**traj, "t": np.asarray(traj["t"]) + 1e9}
    a = prrrp.simulate(robot, traj, seed=2, noise=0.0)
    b = prrrp.simulate(robot, late, seed=2, noise=0.0)
    scale = np.abs(a["tau"]).max()
    # (The last row is at rest, where the exact-sign Coulomb term flips with the sign of a
    # round-off velocity.)
    np.testing.assert_allclose(b["tau"][:-1], a["tau"][:-1], rtol=0, atol=1e-4 * scale)
    uneven = {**traj, "t": np.asarray(traj["t"]) * np.linspace(1, 1.01, len(traj["t"]))}
    with pytest.raises(prrrp.InvalidInputError, match="uniformly spaced"):
        prrrp.simulate(robot, uneven)


def test_batch_rls_initial_covariance_is_bounded():
    # 1e300 diverged at sample 7 ("the covariance is no longer positive definite");
    # refused up front, naming the setting, as the online identifier does.
    robot = prrrp.load_robot(str(UR5_LIKE))
    traj = prrrp.excite(robot, 10.0, max_evaluations=20)
    rec = prrrp.simulate(robot, traj, seed=1)
    with pytest.raises(prrrp.InvalidParameterError, match="initial_covariance"):
        prrrp.identify_measurements(robot, rec, "rls", initial_covariance=1e12)
    # 1e-300 returned the zero start with σ ≈ 1e-150 as "converged".
    with pytest.raises(prrrp.InvalidParameterError, match="MIN_INITIAL_COVARIANCE"):
        prrrp.identify_measurements(robot, rec, "rls", initial_covariance=1e-300)
    model = prrrp.identify_measurements(robot, rec, "rls", initial_covariance=1e9).model
    assert np.all(np.isfinite(model.beta))


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros(4),
        np.zeros(6),
        np.zeros((3, 4)),
        np.zeros((2, 3, 5)),
        np.zeros(()),
        np.zeros((5, 1)),
    ],
    ids=lambda a: str(a.shape),
)
def test_wrong_shape_names_argument_and_expected_shape(robot, bad):
    error = shape_error_of_qd(robot, 5, bad)
    assert error.got == (
        "(" + ", ".join(map(str, bad.shape)) + ("," if bad.ndim == 1 else "") + ")"
    )


def test_wrong_lambda_shape(robot):
    with pytest.raises(prrrp.ShapeMismatchError, match=r"`lam`.*\(8,\) or \(N, 8\)"):
        robot.mass_matrix(np.zeros(5), lam=np.ones(5))


def test_batch_lengths_must_agree(robot):
    with pytest.raises(prrrp.ShapeMismatchError, match=r"`qdd`.*\(3, 5\).*as `q`") as e:
        robot.inverse_dynamics(np.zeros((3, 5)), np.zeros(5), np.zeros((4, 5)))
    assert e.value.got == "(4, 5)"
    with pytest.raises(prrrp.ShapeMismatchError, match="`lam`"):
        robot.inverse_dynamics(np.zeros((3, 5)), np.zeros(5), np.zeros(5), lam=np.ones((2, 8)))


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_non_finite_single(robot, value):
    q = np.zeros(5)
    q[2] = value
    with pytest.raises(prrrp.NonFiniteError, match="`q`") as e:
        robot.mass_matrix(q)
    assert e.value.what == "q"
    assert e.value.row is None
    assert isinstance(e.value, ValueError)


def test_non_finite_batch_names_row(robot):
    tau = np.zeros((10, 5))
    tau[7, 4] = np.nan
    with pytest.raises(prrrp.NonFiniteError, match=r"`tau`.*row 7") as e:
        robot.forward_dynamics(np.zeros((10, 5)), np.zeros((10, 5)), tau)
    assert e.value.row == 7


def test_non_finite_lambda(robot):
    lam = robot.base_parameters()
    lam[0] = np.nan
    with pytest.raises(prrrp.NonFiniteError, match="`lam`"):
        robot.inverse_dynamics(np.zeros(5), np.zeros(5), np.zeros(5), lam=lam)


@pytest.mark.parametrize("bad", ["abc", [1, 2, "x", 4, 5], {"a": 1}, None, [[1, 2], [3]]])
def test_not_an_array(robot, bad):
    with pytest.raises(prrrp.InvalidInputError, match="`qd`"):
        robot.inverse_dynamics(np.zeros(5), bad, np.zeros(5))


def test_not_positive_definite(robot):
    lam = -robot.base_parameters()
    with pytest.raises(prrrp.NotPositiveDefiniteError, match="positive definite") as e:
        robot.forward_dynamics(np.zeros(5), np.zeros(5), np.zeros(5), lam=lam)
    assert isinstance(e.value, ValueError)
    assert not hasattr(e.value, "sample")


def test_batch_error_reports_sample(robot):
    lam = np.tile(robot.base_parameters(), (6, 1))
    lam[4] *= -1.0
    with pytest.raises(prrrp.NotPositiveDefiniteError) as e:
        robot.forward_derivatives(np.zeros((6, 5)), np.zeros((6, 5)), np.zeros((6, 5)), lam=lam)
    assert e.value.sample == 4
    assert any("sample 4" in n for n in e.value.__notes__)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"mass": [1, 1, -1, 1, 1]}, "mass[2] (m3)"),
        ({"mass": [1, 1, 1, 1, 0]}, "mass[4] (m5)"),
        ({"length": [0.5, 0.2, np.nan, 0.2, 0.1]}, "length[2] (l3)"),
        ({"com": [0.0, -0.01, 0.0]}, "com[1] (lc3)"),
        ({"inertia_zz": [0.0, 0.0, -1e-3]}, "inertia_zz[2] (I4zz)"),
        ({"gravity": -9.81}, "gravity"),
        ({"gravity": np.inf}, "gravity"),
    ],
)
def test_robot_validation(kwargs, field):
    with pytest.raises(prrrp.InvalidParameterError) as e:
        prrrp.Robot(**kwargs)
    assert e.value.field == field
    assert isinstance(e.value, ValueError)
    assert field in str(e.value)


def test_robot_parameter_shapes():
    with pytest.raises(prrrp.ShapeMismatchError, match=r"`mass`.*\(5,\)"):
        prrrp.Robot(mass=[1, 2, 3])
    with pytest.raises(prrrp.ShapeMismatchError, match=r"`com`.*\(3,\)"):
        prrrp.Robot(com=np.zeros((1, 3)))
    with pytest.raises(prrrp.InvalidInputError, match="`inertia_zz`"):
        prrrp.Robot(inertia_zz="heavy")


def test_module_function_errors():
    z = np.zeros(5)
    with pytest.raises(prrrp.InvalidParameterError, match="gravity"):
        prrrp.regressor(z, z, z, gravity=np.nan)
    with pytest.raises(prrrp.ShapeMismatchError, match="`q`"):
        prrrp.observation_matrix(np.zeros((3, 4)), z, z)
    with pytest.raises(prrrp.ShapeMismatchError, match="at least as many rows"):
        prrrp.singular_values(np.ones((3, 8)))
    with pytest.raises(prrrp.NonFiniteError):
        prrrp.condition_number(np.full((10, 8), np.nan))
    with pytest.raises(prrrp.InvalidInputError):
        prrrp.condition_number(np.ones(8))


def test_observation_matrix_overflow_is_a_typed_error():
    """The stacked regressors overflow like every batched quantity: a NonFiniteError naming
    the sample, never a matrix of inf."""
    big = np.full((3, 5), 1e300)
    big[0] = 1.0
    with pytest.raises(prrrp.NonFiniteError, match="overflowed") as e:
        prrrp.observation_matrix(big, big, np.ones(5))
    assert e.value.sample == 1


def test_extreme_values_do_not_panic(robot):
    """Huge but finite inputs overflow; that is a typed error, never a crash or a silent
    inf/NaN in the output."""
    big = np.full(5, 1e308)
    with pytest.raises(prrrp.NonFiniteError, match="overflowed"):
        robot.inverse_dynamics(big, big, big)
    with pytest.raises(prrrp.NonFiniteError, match="overflowed") as e:
        robot.inverse_dynamics(np.zeros((2, 5)), np.zeros((2, 5)), np.vstack([np.zeros(5), big]))
    assert e.value.sample == 1
    with pytest.raises(prrrp.PrrrpError):
        robot.forward_dynamics(big, big, big, lam=np.full(8, 1e308))
    with pytest.raises(prrrp.NonFiniteError):
        robot.forward_dynamics(np.zeros(5), np.zeros(5), big)
    with pytest.raises(prrrp.NonFiniteError):
        prrrp.relative_errors_percent([np.nan, 1.0], [1.0, 1.0])
    with pytest.raises(prrrp.InvalidParameterError, match="phase"):
        prrrp.SinusoidReference(
            offset=np.zeros(5), amplitude=np.ones(5), omega=np.ones(5), phase=[np.nan] * 5
        )
