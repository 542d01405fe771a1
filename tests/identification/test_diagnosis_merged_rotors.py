"""The diagnosis's robot-file baselines in identify's map (``merged_rotors.robot_file_theta``, issue 25).

On motor currents identify holds the rotor inertias the base parameters merge near the robot file's
(``merged_rotors``); the diagnosis's enveloped recalibration (``envelope_check``), the augmented model's robot-file
rigid body and the moved parameters used the derived map without them, so their links absorbed the rotors there.
References: Pinocchio's inverse dynamics with the file's rotors as armature, and the virtual Denso's motor currents
(``test_drive_loss.recorded``: rotors and friction on the motor side) with a rigid-body model (no drive inertia in
the derivation, as a URDF with rotor inertias per link gives it).
"""

from dataclasses import replace

import numpy as np

from identification.calibration.merged_rotors import robot_file_theta
from identification.calibration.trajectory_fit import separate_inertia_joints
from identification.diagnosis.diagnose import DiagnosisOptions, DiagnosisProblem, prepare_problem
from identification.diagnosis.envelope_check import EnvelopedRecalibration
from identification.diagnosis.rigid_body_choice import recalibration_parts
from psdm_casadi.oracle import PinocchioOracle
from tests.identification.test_drive_loss import recorded


def test_the_robot_file_theta_holds_the_merged_rotors_on_currents_as_pinocchio_does(denso_merged_rotors):
    robot, model = denso_merged_rotors
    kt = np.array([d.kt for d in robot.drives])
    rng = np.random.default_rng(5)
    q = rng.uniform(robot.q_min, robot.q_max, size=(30, robot.n_dof))
    qd, qdd = rng.normal(size=(2, 30, robot.n_dof))
    standard = robot.nominal_dynamic_parameters()
    with_rotors = PinocchioOracle(robot, standard).rnea(q, qd, qdd)
    bare = standard.copy()
    bare[:, 10] = 0.0
    rigid = PinocchioOracle(robot, bare).rnea(q, qd, qdd)
    separate = separate_inertia_joints(model, robot)
    assert separate and len(separate) < robot.n_dof  # some rotors merge (joints 1-2), the others have no place
    expected = with_rotors.copy()
    expected[:, separate] -= standard[separate, 10] * qdd[:, separate]
    regressor = model.regressor(q, qd, qdd)
    assert np.allclose(regressor @ robot_file_theta(robot, model, kt), expected, atol=1e-8)
    # a torque signal (no kt): the rigid body alone, as before
    assert np.allclose(regressor @ robot_file_theta(robot, model), rigid, atol=1e-8)
    assert not np.allclose(rigid[:, :2], expected[:, :2], atol=1e-2)  # the rotors matter on joints 1-2


def test_the_enveloped_recalibration_on_currents_keeps_the_rotors_out_of_the_links(denso_merged_rotors):
    robot, model = denso_merged_rotors
    recording = recorded(robot, 21)
    train, validation = recording.time_slice(-np.inf, 8.0), recording.time_slice(8.0, np.inf)
    options = DiagnosisOptions(friction="coulomb_viscous", cutoff_hz=15.0, rate_hz=100.0, samples="diagnosis")
    problem = prepare_problem(robot, model, train, [validation], options)
    assert np.allclose(problem.ctx_t.torque_constants, [d.kt for d in robot.drives])
    recal = DiagnosisProblem(**recalibration_parts(problem, model))
    contexts, friction = (recal.ctx_t, recal.ctx_v), (problem.base_t, problem.base_v)
    merged = EnvelopedRecalibration(robot, model, contexts, friction).rmse([])
    # the same currents judged in the derived map (what the check did): links 1-2 must take the rotors
    plain = tuple(replace(ctx, torque_constants=None) for ctx in contexts)
    derived = EnvelopedRecalibration(robot, model, plain, friction).rmse([])
    assert np.all(merged[:2] < 0.6 * derived[:2]), (merged, derived)  # measured 0.39 and 0.49 x
