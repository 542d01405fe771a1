"""carried_payload: the robot file carrying a payload finding is the arm plus that load at the flange (Pinocchio)."""

import numpy as np
import pinocchio as pin
import pytest

from identification.calibration.carried_payload import carried_payload_parameters, carrying_payloads
from identification.calibration.payload import payload_torque
from identification.data.payload import Payload
from psdm_casadi.oracle import build_pinocchio_model


def _torque(robot, q, qd, qdd):
    model = build_pinocchio_model(robot)
    data = model.createData()
    return np.array([pin.rnea(model, data, *x) for x in zip(q, qd, qdd)])


def _entry(mass, com):
    parameters = {"mass": mass, "com_x": com[0], "com_y": com[1], "com_z": com[2]}
    return {"effect": "payload", "kind": "rigid_body", "label": "payload", "diagnosis": {"parameters": parameters}}


def _states(rng, n_dof, still=()):
    q, qd, qdd = (rng.uniform(-1.5, 1.5, (5, n_dof)) for _ in range(3))
    for x in (q, qd, qdd):
        x[:, list(still)] = 0.0
    return q, qd, qdd


def test_a_payload_on_the_massless_flange_is_carried_by_the_wrist_link(denso, denso_model):
    """The Denso's flange link is massless: a load on its axis moves to link 5, the torque unchanged at any q."""
    mass, com = 2.0, (0.0, 0.0, 0.05)
    carrying = carrying_payloads(denso, denso_model, [_entry(mass, com)])
    assert carrying.links[4].mass == 0.8 + mass and carrying.links[5].mass == 0.0
    assert all(a is b for a, b in zip(carrying.links[:4], denso.links[:4]))
    q, qd, qdd = _states(np.random.default_rng(3), denso.n_dof)
    expected = _torque(denso, q, qd, qdd) + payload_torque(denso, Payload(mass=mass, com=com), q, qd, qdd)
    np.testing.assert_allclose(_torque(carrying, q, qd, qdd), expected, atol=1e-9 * np.abs(expected).max())


def test_an_off_axis_payload_is_moved_through_the_joints_between_at_zero(denso, denso_model):
    """A load off joint 6's axis is exact on joints 1-5 where joint 6 is at 0 and still (joint 6's own torque is the
    part link 5 cannot hold); the finding's fitted parameters come before the diagnosis's."""
    mass, com = 1.5, (0.04, -0.03, 0.08)
    entry = {**_entry(mass, com), "parameters": {"mass": mass, "com_x": com[0], "com_y": com[1], "com_z": com[2]}}
    entry["diagnosis"]["parameters"] = {"mass": 9.0}
    carrying = carrying_payloads(denso, denso_model, [entry])
    assert carrying.links[4].mass == 0.8 + mass
    q, qd, qdd = _states(np.random.default_rng(4), denso.n_dof, still=(5,))
    expected = _torque(denso, q, qd, qdd) + payload_torque(denso, Payload(mass=mass, com=com), q, qd, qdd)
    got = _torque(carrying, q, qd, qdd)
    np.testing.assert_allclose(got[:, :5], expected[:, :5], atol=1e-9 * np.abs(expected).max())
    assert np.abs(expected[:, 5] - got[:, 5]).max() > 0.1


def test_only_payload_findings_with_a_mass_change_the_robot(denso, denso_model):
    other = {"effect": "spring", "kind": "torque", "parameters": {"mass": 3.0}}
    assert carried_payload_parameters([other, _entry(0.0, (0.0, 0.0, 0.1))]) is None
    assert carrying_payloads(denso, denso_model, [other]) is denso
    two = carried_payload_parameters([_entry(1.0, (0.0, 0.0, 0.1)), _entry(3.0, (0.0, 0.0, 0.3))])
    np.testing.assert_allclose(two[:4], [4.0, 0.0, 0.0, 1.0])


def _augmented_torque(robot, model, coefficients, q, qd, qdd, parameter_map):
    """The torque of the diagnosis's augmented model (the robot file's base parameters, no friction) with one payload
    body of ``coefficients`` (10 dynamic parameters about the flange), less the file's own."""
    from identification.diagnosis.augmented import AugmentedModel
    from identification.diagnosis.candidates import PayloadTerm

    zeros = np.zeros(robot.n_dof)
    augmented = AugmentedModel(model, model.base_parameters(robot.nominal_dynamic_parameters()), "coulomb_viscous",
                               np.zeros(2 * robot.n_dof), zeros, zeros, (PayloadTerm(inertia=True),),
                               (tuple(coefficients),), parameter_map)  # fmt: skip
    function = augmented.build_function()
    torque = np.array([function(*x, 0.0).full().ravel() for x in zip(q, qd, qdd)])  # DM to numpy first
    return torque - _torque(robot, q, qd, qdd)


def test_the_diagnosis_folds_a_flange_payload_into_the_wrist_link(denso, denso_model):
    """The diagnosis's payload term (``PayloadTerm.theta_change``) goes through the last link's block of the parameter
    map, which is zero on the Denso (link 6 massless in the model): its augmented model carried no load. Through
    ``flange_parameter_map`` it carries it as ``carrying_payloads`` does: a load on joint 6's axis exactly (Pinocchio's
    payload torque); one off it with joint 6 at 0 with its mass (read back from the torque as a point mass at its centre
    of mass) to 0.4 % and its torque on joints 1-5 to 8 % RMS: the robot file states link 5's rx, Ixy, Ixz, Iyz zero
    (``zero_parameters``), so the model has no place for the load's moment along link 5's x."""
    from identification.calibration.carried_payload import flange_parameter_map

    assert not np.any(np.asarray(denso_model.parameter_map)[:, 55:65])  # the flange link's own block is empty
    rng = np.random.default_rng(5)
    flange_map = flange_parameter_map(denso, denso_model)
    for mass, com in ((2.0, (0.0, 0.0, 0.05)), (0.8, (0.03, 0.0, 0.06))):
        q, qd, qdd = _states(rng, denso.n_dof, still=(5,))
        expected = payload_torque(denso, Payload(mass=mass, com=com), q, qd, qdd)
        coefficients = pin.Inertia(mass, np.asarray(com), np.zeros((3, 3))).toDynamicParameters()
        before = _augmented_torque(denso, denso_model, coefficients, q, qd, qdd, None)
        assert np.abs(before).max() < 1e-9  # the load was lost
        got = _augmented_torque(denso, denso_model, coefficients, q, qd, qdd, flange_map)
        unit = payload_torque(denso, Payload(mass=1.0, com=com), q, qd, qdd)[:, :5].ravel()
        assert unit @ got[:, :5].ravel() / (unit @ unit) == pytest.approx(mass, rel=0.01)
        if com[0] == 0.0:
            np.testing.assert_allclose(got, expected, atol=1e-9 * np.abs(expected).max())
        else:
            assert np.sqrt(np.mean((got - expected)[:, :5] ** 2) / np.mean(expected[:, :5] ** 2)) < 0.1


def test_a_held_flange_link_keeps_its_own_map():
    from identification.calibration.carried_payload import flange_parameter_map
    from psdm_casadi import derive_psdm, load_robot
    from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

    scara = load_robot(BUILTIN_ROBOTS_DIR / "scara.toml")
    model = derive_psdm(scara)
    assert np.any(np.asarray(model.parameter_map)[:, 11 * (scara.n_dof - 1) : 11 * scara.n_dof - 1])
    np.testing.assert_array_equal(flange_parameter_map(scara, model), np.asarray(model.parameter_map))
