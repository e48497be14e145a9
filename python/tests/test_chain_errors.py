"""Errors of `prrrp.SerialChain` and `prrrp.BaseParameters`: every bad input raises a
`prrrp.PrrrpError` subclass (a ValueError for input faults) naming the argument; no Rust
panic reaches Python."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import shape_error_of_qd

import prrrp

ROW = [0.3, 0.0, 0.0, 0.0]


@pytest.fixture(scope="module")
def chain():
    return prrrp.SerialChain.puma560()


@pytest.mark.parametrize(
    "bad", [np.zeros(5), np.zeros(7), np.zeros((3, 5)), np.zeros((2, 3, 6)), np.zeros(())]
)
def test_wrong_shape_names_argument(chain, bad):
    shape_error_of_qd(chain, 6, bad)


def test_batch_lengths_must_agree(chain):
    with pytest.raises(prrrp.ShapeMismatchError, match="qdd"):
        chain.inverse_dynamics(np.zeros((4, 6)), np.zeros((4, 6)), np.zeros((3, 6)))


@pytest.mark.parametrize("method", ["inverse_dynamics", "regressor", "base_regressor"])
def test_nan_is_refused_with_its_row(chain, method):
    q = np.zeros((5, 6))
    q[3, 1] = np.nan
    with pytest.raises(prrrp.NonFiniteError) as e:
        getattr(chain, method)(np.zeros((5, 6)), q, np.zeros(6))
    assert e.value.what == "qd"
    assert e.value.row == 3


def test_not_a_number_array(chain):
    with pytest.raises(prrrp.InvalidInputError, match="`q`"):
        chain.mass_matrix("abc")


@pytest.mark.parametrize("types", ["X", ["R", "revolver"], "r?", 3])
def test_unknown_joint_type(types):
    with pytest.raises(prrrp.InvalidParameterError, match="joint_types") as e:
        prrrp.SerialChain([ROW] * (len(types) if isinstance(types, str | list) else 1), types)
    assert isinstance(e.value, ValueError)
    assert e.value.field.startswith("joint_types")


def test_joint_types_accept_words_and_case():
    c = prrrp.SerialChain([ROW, ROW, ROW], ["revolute", "P", "r"])
    assert c.joint_types == "RPR"


def test_bad_dh_tables():
    with pytest.raises(prrrp.ShapeMismatchError, match=r"`dh`.*\(n, 4\)"):
        prrrp.SerialChain([[0.0, 0.0, 0.0]], "R")
    with pytest.raises(prrrp.ShapeMismatchError, match="joint_types"):
        prrrp.SerialChain([ROW, ROW], "R")
    with pytest.raises(prrrp.ShapeMismatchError, match="DH table"):
        prrrp.SerialChain(np.zeros((0, 4)), "")
    with pytest.raises(prrrp.InvalidParameterError, match=r"dh\[1\]\.a"):
        prrrp.SerialChain([ROW, [np.nan, 0, 0, 0]], "RR")
    with pytest.raises(prrrp.InvalidParameterError, match="convention"):
        prrrp.SerialChain([ROW], "R", convention="craig")


def test_bad_inertial_gravity_friction():
    with pytest.raises(prrrp.ShapeMismatchError, match=r"`inertial`.*\(2, 10\)"):
        prrrp.SerialChain([ROW, ROW], "RR", inertial=np.zeros((2, 9)))
    neg = np.zeros((2, 10))
    neg[1, 0] = -1.0
    # A file's inertials are only a prior: non-physical ones load and are reported.
    assert prrrp.SerialChain([ROW, ROW], "RR", inertial=neg).non_physical_links == ["link2"]
    with pytest.raises(prrrp.InvalidParameterError, match="inertial"):
        prrrp.SerialChain([ROW, ROW], "RR", inertial=np.full((2, 10), np.nan))
    with pytest.raises(prrrp.InvalidParameterError, match="gravity"):
        prrrp.SerialChain([ROW], "R", gravity=[0.0, np.inf, 0.0])
    with pytest.raises(prrrp.ShapeMismatchError, match="gravity"):
        prrrp.SerialChain([ROW], "R", gravity=[0.0, 9.81])
    with pytest.raises(prrrp.InvalidParameterError, match="friction"):
        prrrp.SerialChain([ROW], "R", friction="stiction")
    with pytest.raises(prrrp.InvalidParameterError, match="friction_params"):
        prrrp.SerialChain([ROW], "R", friction_params=[[1.0, 0.0, 0.0]])
    with pytest.raises(prrrp.ShapeMismatchError, match="friction_params"):
        prrrp.SerialChain([ROW], "R", friction="viscous", friction_params=[[1.0, 0.0]])
    with pytest.raises(prrrp.InvalidParameterError, match="coulomb_smoothing"):
        prrrp.SerialChain([ROW], "R", friction="coulomb", coulomb_smoothing=-1.0)


def test_singular_mass_matrix_names_the_sample():
    massless = prrrp.SerialChain([ROW, ROW], "RR")
    with pytest.raises(prrrp.NotPositiveDefiniteError) as e:
        massless.forward_dynamics(np.zeros((3, 2)), np.zeros(2), np.zeros(2))
    assert e.value.sample == 0


def test_base_parameter_errors(chain):
    with pytest.raises(prrrp.TooFewSamplesError) as e:
        chain.base_parameters(samples=3)
    assert e.value.got == 3
    with pytest.raises(prrrp.InvalidParameterError, match="rank_tolerance"):
        chain.base_parameters(rank_tolerance=2.0)
    base = chain.base_parameters()
    with pytest.raises(prrrp.ShapeMismatchError, match=r"`parameters`.*\(60,\)"):
        base.base_values(np.zeros(50))
    paper_base = prrrp.SerialChain.paper().base_parameters()
    z = np.zeros(6)
    with pytest.raises(prrrp.ShapeMismatchError, match="base parameters"):
        chain.base_regressor(z, z, z, base=paper_base)
    with pytest.raises(TypeError):
        chain.base_regressor(z, z, z, base="default")
