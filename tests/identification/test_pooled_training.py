"""The diagnosis pools every training recording it is given (``pooled_context``), as the refit with its findings does.

A ripple on the SCARA's joint 1 (three periods per revolution) recorded over two stretches of the joint's range: the
first alone covers under half a period, a smooth stretch a spring's polynomial fits as well (the name the selection
gives it there), while both cover more than a period, so the pooled diagnosis names the true ripple with its amplitude
and phase. The pool's columns are each recording's own (its filter run on it alone), so pooling is no new physics.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, LoadedModel
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.diagnosis.candidates import SpringTerm, TorqueRippleTerm
from identification.diagnosis.candidates.torque import MIN_PERIODS
from identification.diagnosis.context import build_context
from identification.diagnosis.diagnose import DiagnosisOptions
from identification.diagnosis.model_file import diagnose_model
from identification.diagnosis.pooled_context import pooled_context
from psdm_casadi import derive_psdm, load_robot
from tests.identification.diagnosis_data import scara_recording

HARMONIC, AMPLITUDE, PHASE = 3.0, 0.5, 0.4  # the true ripple on joint 1: A sin(h q + phase) [N m]


def _ripple(q):
    out = np.zeros_like(q)
    out[:, 0] = AMPLITUDE * np.sin(HARMONIC * q[:, 0] + PHASE)
    return out


@pytest.fixture(scope="module")
def case():
    """The model file (identified on a ripple-free recording), two training recordings over two stretches of joint
    1's range, and two validation recordings over the middle."""
    robot = load_robot("scara")
    model = derive_psdm(robot)
    fit = identify_trajectories(robot, model, [scara_recording(robot, 0, np.zeros(4))], TrajectoryOptions(("fc", "fv")))
    loaded = LoadedModel(CalibratedModel.from_fit(robot, model, fit, robot_source="scara"), robot, model)
    zero = np.zeros(4)
    trains = [scara_recording(robot, s, zero, effect=_ripple, centre=(c, 0, 0.1, 0)) for s, c in ((1, -0.5), (2, 1.0))]
    validations = [scara_recording(robot, s, zero, effect=_ripple, centre=(c, 0, 0.1, 0), duration=8.0)
                   for s, c in ((3, 0.1), (4, -0.3))]  # fmt: skip
    return loaded, trains, validations


def test_the_pool_is_each_recordings_own_columns_one_after_the_other(case):
    """A friction column filtered at full rate (the exact sign, low-passed like the recording) on the pool equals each
    recording's own column stacked: the filter runs on each recording alone, not across the seam."""
    loaded, trains, _ = case
    contexts = [build_context(loaded.robot, loaded.model, preprocess(r, PreprocessOptions(cutoff_hz=10.0)), 100.0,
                              10.0, filtered_friction=True) for r in trains]  # fmt: skip
    pool = pooled_context(contexts)
    assert pool.n_samples == sum(c.n_samples for c in contexts) and pool.segments == (contexts[0].full_t.size,)
    assert np.all(np.diff(pool.t) > 0) and np.all(np.diff(pool.full_t) > 0)  # one timeline, the second after the first
    np.testing.assert_array_equal(pool.q, np.concatenate([c.q for c in contexts]))
    np.testing.assert_array_equal(pool.full_qd[pool.keep], pool.qd)  # the grid indexes the pooled full rate
    for j in range(2):
        stacked = np.concatenate([c.friction_sign(j) for c in contexts])
        np.testing.assert_allclose(pool.friction_sign(j), stacked, rtol=0.0, atol=1e-12)


def test_the_ripple_the_first_recording_shows_only_a_stretch_of_is_named_on_both(case):
    """The first training recording alone: a spring (its travel covers under ``MIN_PERIODS`` of the ripple); both:
    the true ripple, which predicts the validation recordings to the noise where the first one's spring does not."""
    loaded, trains, validations = case
    travel = [np.ptp(r.q[:, 0]) * HARMONIC / (2.0 * np.pi) for r in (trains[0], *trains)]
    pooled = np.ptp(np.concatenate([r.q[:, 0] for r in trains])) * HARMONIC / (2.0 * np.pi)
    assert travel[0] < 0.5 * MIN_PERIODS < MIN_PERIODS < pooled  # the premise
    options = DiagnosisOptions(library=SpringTerm() + TorqueRippleTerm(), sparse=False, cv_folds=0)
    alone = diagnose_model(loaded, trains[0], validations, options)
    both = diagnose_model(loaded, trains, validations, options)
    assert [f.effect for f in alone.findings] == ["spring"], [f.label for f in alone.findings]
    (ripple,) = both.findings
    assert ripple.label == f"torque_ripple[j1,h={HARMONIC:g}]"
    assert ripple.parameters["amplitude"] == pytest.approx(AMPLITUDE, rel=0.05)
    assert ripple.parameters["phase"] == pytest.approx(PHASE, abs=0.05)
    assert both.rmse_after[0] < 0.5 * alone.rmse_after[0]
