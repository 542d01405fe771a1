"""A rotor inertia inside a model file's base parameters is a change of them, not missing physics (``base_change``).

Virtual SCARA: the model file is identified on a recording without drive inertia, the diagnosis's recordings carry
0.05 kg m^2 on joint 1, whose drive inertia adds to link 1's Izz about the vertical axis (one base parameter,
``merged_rotor_map``). The diagnosis of the model file found ``rotor_inertia[j1]`` and reported it as missing physics;
the file holds that torque in its base parameter, so the report states the base parameter's change (the truth: +0.05)
instead. A robot file's diagnosis still reports the rotor it lacks.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, LoadedModel
from identification.calibration.merged_rotors import merged_rotor_map
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.diagnosis.base_change import base_changes
from identification.diagnosis.candidates import RotorInertiaTerm, TorqueOffsetTerm
from identification.diagnosis.diagnose import DiagnosisOptions, diagnose
from identification.diagnosis.model_file import diagnose_model
from psdm_casadi import derive_psdm, load_robot
from tests.identification.diagnosis_data import scara_recording

ROTOR = np.array([0.05, 0.0, 0.0, 0.0])  # [kg m^2]: joint 1's, inside the base parameters


@pytest.fixture(scope="module")
def case():
    robot = load_robot("scara")
    model = derive_psdm(robot)
    fit = identify_trajectories(robot, model, [scara_recording(robot, 0, np.zeros(4))], TrajectoryOptions(("fc", "fv")))
    calibrated = CalibratedModel.from_fit(robot, model, fit, robot_source="scara")
    train, held = (scara_recording(robot, seed, np.zeros(4), armature=ROTOR) for seed in (1, 2))
    options = DiagnosisOptions(library=RotorInertiaTerm() + TorqueOffsetTerm(), sparse=False, cv_folds=0)
    return LoadedModel(calibrated, robot, model), train, held, options


def test_joint_1s_rotor_lies_in_one_base_parameter(case):
    loaded = case[0]
    span = merged_rotor_map(loaded.model, loaded.robot, [0, 1])
    assert list(span) == [0]  # joint 2's has a column of its own
    assert np.count_nonzero(span[0]) == 1


def test_the_model_files_diagnosis_states_the_base_parameter_change(case):
    loaded, train, held, options = case
    report = diagnose_model(loaded, train, held, options)
    assert not [f.label for f in report.findings if f.effect == "rotor_inertia"], [f.label for f in report.findings]
    notes = [n for n in report.rigid_body_notes if "`rotor_inertia[j1]`" in n]
    assert len(notes) == 1 and "no missing physics" in notes[0]
    name = loaded.model.base_names[int(np.flatnonzero(merged_rotor_map(loaded.model, loaded.robot, [0])[0])[0])]
    change = float(re.search(rf"{name} ([+-][0-9.e+-]+)", notes[0]).group(1))
    assert change == pytest.approx(ROTOR[0], rel=0.1)  # the truth's change of that base parameter


def test_the_robot_files_diagnosis_still_reports_the_rotor_it_lacks(case):
    loaded, train, held, options = case
    report = diagnose(loaded.robot, train, held, options, model=loaded.model)
    found = {f.label: f for f in report.findings}
    assert found["rotor_inertia[j1]"].parameters["inertia"] == pytest.approx(ROTOR[0], rel=0.1)
    changes = base_changes(report.findings, loaded.robot, loaded.model)  # what base_change would say of it
    assert changes["rotor_inertia[j1]"][0] == 0
