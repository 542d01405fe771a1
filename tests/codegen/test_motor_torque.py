"""The exported motor torque of a robot with a transmission: tau_m = N_q^-T tau, in CasADi and in the compiled C."""

import numpy as np
import pytest

from codegen.build import build_library
from codegen.export import export_c
from codegen.motor_torque import add_motor_torque
from psdm_casadi.transmission import Transmission
from tests.codegen._toy import THETA, random_inputs, toy_functions
from tests.codegen.test_build import FAST, needs_cc

COUPLING = np.array([[32.0, 0.0, 0.0], [0.0, -48.0, 0.0], [0.0, 32.0, 32.0]])  # a coupled pair, a reversed gear


def test_the_motor_torque_drives_the_joints_through_the_transposed_coupling(rng):
    toy = add_motor_torque(toy_functions(), Transmission(coupling=COUPLING))
    assert add_motor_torque(toy_functions(), None).__dict__.get("motor_torque") is None
    for _ in range(3):
        inputs = random_inputs(toy.inverse_dynamics, rng)
        tau = np.array(toy.inverse_dynamics(*inputs)).ravel()
        tau_m = np.array(toy.motor_torque(*inputs)).ravel()
        np.testing.assert_allclose(COUPLING.T @ tau_m, tau, rtol=1e-12, atol=1e-12)  # tau_j = N_q^T tau_m
        # the motors' power is the joints': tau_m . (N_q qd) = tau . qd
        qd = np.asarray(inputs[1], dtype=float)
        assert tau_m @ (COUPLING @ qd) == pytest.approx(tau @ qd, rel=1e-12)
    assert toy.motor_torque.name_in() == toy.inverse_dynamics.name_in() and toy.motor_torque.name_out() == ["tau_m"]


@pytest.mark.needs_cc
@needs_cc
def test_the_compiled_motor_torque_equals_casadi(tmp_path, rng):
    toy = add_motor_torque(toy_functions(), Transmission(coupling=COUPLING))
    export = export_c(toy, tmp_path / "out", theta=THETA)
    assert {"psdm_motor_torque", "psdm_motor_torque_theta"} <= set(export.function_names)
    compiled = build_library(export, build_dir=tmp_path / "build", flags=FAST).function("psdm_motor_torque")
    inputs = random_inputs(toy.motor_torque, rng)
    want = np.array(toy.motor_torque(*inputs)).ravel()
    got = np.array(compiled(*[x for x, name in zip(inputs, toy.motor_torque.name_in()) if name != "theta"])).ravel()
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
