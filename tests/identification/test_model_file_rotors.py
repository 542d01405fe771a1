"""``diagnose MODEL`` keeps a drive inertia its model file fitted outside the base parameters (drive column ``Ia<j>``).

Virtual SCARA whose joint 2 has a drive inertia of 0.08 kg m^2 that no base parameter holds (identify fits it as a
column of its own, ``inertia_joints``). Left in the nominal robot's rotor, it was in the diagnosis's prior fit but not
in its recalibrated rigid body (the PSDM base parameters and the friction fitted again): that fit dropped it and the
diagnosis reported it missing (``rotor_inertia[j2]``, as the belt cobot of ``benchmarks/unseen_belt_cobot.py`` got a
``rotor_inertia[j4]`` of 0.120 kg m^2 its model file held as 0.112). Held at the file's value
(``HeldFriction.of_model_file``, ``without_held_rotors``), every fit keeps it and the "before" is ``psdm validate``'s.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, LoadedModel, calibrated_robot
from identification.calibration.finding_value import validation_rmse
from identification.calibration.held_friction import HeldFriction, without_held_rotors
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.diagnosis.candidates import RotorInertiaTerm, TorqueOffsetTerm
from identification.diagnosis.diagnose import DiagnosisOptions, diagnose
from identification.diagnosis.model_file import diagnose_model, model_file_options
from psdm_casadi import derive_psdm, load_robot
from tests.identification.diagnosis_data import scara_recording

ROTOR = np.array([0.0, 0.08, 0.0, 0.0])  # [kg m^2]: joint 2's, outside the SCARA's base parameters


@pytest.fixture(scope="module")
def case():
    robot = load_robot("scara")
    model = derive_psdm(robot)
    train, held = (scara_recording(robot, seed, np.zeros(4), armature=ROTOR) for seed in (0, 1))
    fit = identify_trajectories(robot, model, [train], TrajectoryOptions(friction=("fc", "fv"), inertia_joints=(1,)))
    calibrated = CalibratedModel.from_fit(robot, model, fit, robot_source="scara")
    return LoadedModel(calibrated, robot, model), train, held


def test_the_file_fits_the_drive_inertia_as_a_column_and_the_diagnosis_holds_it(case):
    loaded, _, _ = case
    drive = dict(zip(loaded.calibrated.document["drive"]["names"], loaded.calibrated.document["drive"]["values"]))
    assert drive["Ia2"] == pytest.approx(ROTOR[1], rel=0.1)  # the truth, recovered by identify
    held = dict(HeldFriction.of_model_file(loaded.calibrated.document).drive_inertias)
    assert held == {"Ia2": pytest.approx(drive["Ia2"], rel=1e-12)}


@pytest.mark.parametrize("rigid_body", ["prior", "identified"])
def test_a_rotor_inertia_the_model_file_holds_is_not_reported_missing(case, rigid_body):
    loaded, train, held = case
    own = validation_rmse(loaded.calibrated, loaded.model, held)[0]
    options = DiagnosisOptions(rigid_body=rigid_body, library=RotorInertiaTerm() + TorqueOffsetTerm(), sparse=False,
                               cv_folds=0)  # fmt: skip
    report = diagnose_model(loaded, train, held, options)
    assert not [f.label for f in report.findings if f.effect == "rotor_inertia"], [f.label for f in report.findings]
    np.testing.assert_allclose(report.model_file_rmse, own, rtol=1e-9)
    np.testing.assert_allclose(report.rmse_before, own, rtol=1e-9)  # the report's "before" is validate's
    # the diagnosis's own nominal (before the file's "before" replaces it): joint 2 predicted as the file predicts it,
    # its rigid body recalibrated or not
    given = model_file_options(loaded.calibrated, options)
    robot = without_held_rotors(calibrated_robot(loaded.calibrated, loaded.robot), given.held_friction)
    nominal = diagnose(robot, train, held, given, model=loaded.model)
    assert nominal.rmse_before[1] <= 1.2 * own[1], (nominal.rmse_before, own)
