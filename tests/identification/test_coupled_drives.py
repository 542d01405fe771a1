"""identify on a coupled wrist the robot file states (``coupled_drives``): known truth, not the diagnosis's.

The truth is the Denso's rigid body by Pinocchio, Coulomb-viscous friction per joint and, as a coupled transmission
drives it (``theta_m = N_q q``, motor 6 turning with joints 5 and 6: ``N_q[5, 4] = N_q[5, 5] = 1``), motor 6's inertia
and viscous friction on both joints (``tau = N_q^T tau_m``, motor 6's velocity ``qd5 + qd6``), along sum-of-sines
trajectories with noise. identify with that transmission must fit ``coupling[j6->j5]`` and ``coupling[j5->j6]`` at motor
6's viscous friction and inertia, and its held-out joint 5 must be no worse than the robot file's. Without the coupling
terms (per-joint drive columns only) joint 5 carries ``Ia qdd6 + b qd6``, which no column of its own holds.
"""

import dataclasses

import numpy as np
import pytest

from identification.calibration.coupled_drives import coupling_terms
from identification.calibration.identify_route import identify_recordings
from identification.data.recording import Recording
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.transmission import Transmission
from trajopt.experiments import sine_experiment

MOTOR_INERTIA, MOTOR_VISCOUS = 0.05, 0.8  # motor 6 seen through a unit ratio [kg m^2], [N m s/rad]


def _coupling() -> np.ndarray:
    matrix = np.eye(6)
    matrix[5, 4] = 1.0  # motor 6 turns with joint 5 too
    return matrix


def _recording(robot, seed, duration):
    rng = np.random.default_rng(seed)
    experiment = sine_experiment(robot, duration=duration, rng=rng)
    t = experiment.time_grid(200.0)
    q, qd, qdd = experiment.sample(t)
    tau = PinocchioOracle(robot).rnea(q, qd, qdd) + 1.0 * np.tanh(qd / 0.05) + 0.5 * qd
    matrix = _coupling()
    motor = MOTOR_INERTIA * (qdd @ matrix.T)[:, 5] + MOTOR_VISCOUS * (qd @ matrix.T)[:, 5]
    tau += np.outer(motor, matrix[5])  # N_q^T e_6 tau_m6: on joints 5 and 6
    return Recording(t=t, q=q, tau=tau + rng.normal(scale=0.05, size=tau.shape), name=f"coupled{seed}")


@pytest.fixture(scope="module")
def coupled(denso, denso_model):
    robot = dataclasses.replace(denso, transmission=Transmission(coupling=_coupling()))
    train, held = _recording(denso, 11, 12.0), _recording(denso, 12, 6.0)
    return identify_recordings(robot, denso_model, [train], validation=[held])


def test_the_files_coupling_gives_both_directions_of_the_coupled_pair(denso):
    robot = dataclasses.replace(denso, transmission=Transmission(coupling=_coupling()))
    assert [t.label for t in coupling_terms(robot)] == ["coupling[j6->j5]", "coupling[j5->j6]"]
    assert coupling_terms(denso) == []  # a diagonal transmission (or none): nothing


def test_identify_fits_the_coupled_motors_inertia_and_friction_on_both_joints(coupled):
    findings = {e["label"]: e for e in coupled.calibrated.document.get("findings") or []}
    for label in ("coupling[j6->j5]", "coupling[j5->j6]"):
        viscous, inertia = findings[label]["coefficients"]
        assert viscous == pytest.approx(MOTOR_VISCOUS, rel=0.05), label
        # joint 5's acceleration on joint 6 is partly a cross inertia of link 6 too (base parameters): looser
        assert inertia == pytest.approx(MOTOR_INERTIA, rel=0.3), label
        assert findings[label]["source"] == "robot file transmission"
    assert coupled.coupled.kept == ("coupling[j6->j5]", "coupling[j5->j6]")
    assert any(line.startswith("coupled transmission: coupling[j6->j5], coupling[j5->j6] fitted (of")
               for line in coupled.describe())  # fmt: skip


def test_the_coupled_joint_held_out_is_no_worse_than_the_robot_files(coupled):
    check = coupled.file_check
    assert 4 not in check.worse and 5 not in check.worse
    assert check.comparison.after[4] < check.comparison.before[4]  # joint 5 nearer than the robot file's
