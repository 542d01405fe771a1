"""``diagnose`` of a robot file whose nominal friction has a Stribeck hump, on recordings where a joint never slows
down (the Kinova logs: joints 2 and 5 of opti_traj_testing1's first 70 % move one way): the hump's column of that
joint is zero and the check refused with 'Record training and validation runs ...' only, which a user of a shared
dataset cannot do. Identify's own route (``diagnose ROBOT ... --holdout 0.3``, printed by identify) ended there.

Reference: the refused columns are the hump's alone when the same check passes with Coulomb + viscous friction
(``friction='coulomb_viscous'``, the option the message names)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from identification.diagnosis.diagnose import DiagnosisOptions, prepare_problem
from psdm_casadi.errors import ParameterError
from tests.identification.diagnosis_data import recording_pair


def test_a_joint_that_never_slows_down_names_the_hump_and_the_friction_option(denso, denso_model):
    train, valid = recording_pair(denso, [], seed=0, train_s=6.0, val_s=4.0)
    denso = replace(denso, drives=None)  # a URDF's robot: no drives, the steady-state LuGre hump at 0.01 rad/s
    q = train.q.copy()
    q[:, 1] = 0.4 * (train.t - train.t.mean())  # joint 2 one way at 0.4 rad/s: never near its Stribeck velocity
    train = replace(train, q=q, qd=None, qdd=None)
    options = DiagnosisOptions()
    assert options.for_recording(train, denso).friction == "lugre"  # the premise: the nominal friction has a hump
    with pytest.raises(ParameterError) as refused:
        prepare_problem(denso, denso_model, train, valid, options)
    message = str(refused.value)
    assert "fs_minus_fc_2" in message and "Pass --friction coulomb_viscous" in message
    problem = prepare_problem(denso, denso_model, train, valid, replace(options, friction="coulomb_viscous"))
    assert np.all(np.isfinite(problem.y_t))  # the route the message names diagnoses these recordings
