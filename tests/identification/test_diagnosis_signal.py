"""Signal-level effects (backlash, joint elasticity, delay) and a small base tilt on short synthetic recordings:
named on the right joint, parameters recovered, validation error on the joint well below half (issue 6).

These 1 kHz recordings are diagnosed with a 15 Hz cutoff on a 200 Hz grid (``WIDE``), above identify's preparation
(10 Hz, the default of ``DiagnosisOptions``): a delay and a deflection live in the torque's faster part, and the
tests pin what the terms recover when the filter leaves it; the default's own figures are the benchmark's."""

from __future__ import annotations

import numpy as np
import pytest

from identification.diagnosis import (
    BacklashTerm,
    CandidateLibrary,
    DelayTerm,
    DiagnosisOptions,
    GravityTiltTerm,
    JointElasticityTerm,
    SpringTerm,
    TorqueOffsetTerm,
    diagnose,
)
from identification.virtual import effects as xp
from identification.virtual.transmission_effects import Backlash, JointElasticity
from tests.identification.diagnosis_data import recording_pair

WIDE = {"cutoff_hz": 15.0, "rate_hz": 200.0, "samples": "diagnosis"}


def _deflection(joint):
    """The deflection terms of one joint compete with each other (they were confused: elasticity read as backlash)."""
    return BacklashTerm(joint=joint) + JointElasticityTerm(joint=joint) + TorqueOffsetTerm()


def _reduction(report, joint):
    return 1.0 - report.rmse_after[joint] / report.rmse_before[joint]


def _tau_rms(recording, joint):
    return float(np.sqrt(np.mean(recording.tau[:, joint] ** 2)))


def test_clean_nominal_model_leaves_only_a_noise_level_residual(denso, denso_model):
    """The nominal friction columns are filtered like the recording: on clean data the training RMSE is below the
    0.1 N m sensor noise on every joint (it was 0.3-0.8 N m with sharp friction columns on the benchmark's
    Denso, 20 x more than with filtered ones)."""
    train, val = recording_pair(denso, [], seed=3)
    report = diagnose(
        denso, train, val, DiagnosisOptions(library=CandidateLibrary((TorqueOffsetTerm(),)), **WIDE), model=denso_model
    )
    assert max(report.rmse_train_before) < 0.1


def _deflection_report(denso, denso_model, hidden, seed):
    """Diagnosis of a recording with ``hidden`` among the deflection terms of its joint."""
    train, val = recording_pair(denso, [hidden], seed=seed)
    library = _deflection(hidden.joint)
    return diagnose(denso, train, val, DiagnosisOptions(library=library, max_effects=1, **WIDE), model=denso_model)


@pytest.mark.slow
def test_backlash_is_found_with_its_width_and_the_error_drops(denso, denso_model):
    clean, _ = recording_pair(denso, [], seed=6)
    width = np.radians(0.4)
    report = _deflection_report(
        denso, denso_model, Backlash(joint=1, width=width, torque_scale=0.02 * _tau_rms(clean, 1)), 6
    )
    first = report.findings[0]
    assert first.effect == "backlash" and first.joints == (1,)
    assert first.parameters["backlash_rad"] == pytest.approx(width, rel=0.1)
    assert _reduction(report, 1) > 0.75


@pytest.mark.slow
def test_joint_elasticity_is_not_read_as_backlash(denso, denso_model):
    clean, _ = recording_pair(denso, [], seed=7)
    stiffness = _tau_rms(clean, 2) / np.radians(0.2)  # torsion 0.2 deg at the RMS torque
    report = _deflection_report(denso, denso_model, JointElasticity(joint=2, stiffness=stiffness), 7)
    first = report.findings[0]
    assert first.effect == "joint_elasticity" and first.joints == (2,)
    assert first.parameters["stiffness_Nm_per_rad"] == pytest.approx(stiffness, rel=0.1)
    assert _reduction(report, 2) > 0.75


@pytest.mark.slow
def test_delay_is_fitted_exactly_not_by_its_expansion(denso, denso_model):
    train, val = recording_pair(denso, [xp.SignalDelay(samples=8)], seed=5)
    report = diagnose(
        denso, train, val, DiagnosisOptions(library=DelayTerm() + TorqueOffsetTerm(), **WIDE), model=denso_model
    )
    assert report.effects[0] == "delay"
    assert report.findings[0].parameters["delay_s"] == pytest.approx(0.008, abs=0.0015)
    assert min(_reduction(report, j) for j in range(3)) > 0.6


def test_small_tilt_is_found_and_halves_the_error(denso, denso_model):
    hidden = xp.GravityTilt(angle=np.radians(1.5), axis=(0.0, 1.0, 0.0))
    train, val = recording_pair(denso, [hidden], seed=8)
    report = diagnose(
        denso, train, val, DiagnosisOptions(library=GravityTiltTerm() + SpringTerm(), **WIDE), model=denso_model
    )
    first = report.findings[0]
    assert first.effect == "gravity_tilt"
    assert first.parameters["angle_deg"] == pytest.approx(1.5, rel=0.1)
    assert _reduction(report, 1) > 0.5
