"""A LuGre nominal friction is offered the Stribeck peak it lacks (issue 25): the robot file's LuGre friction holds one
Stribeck peak, at the drive's velocity; a hump at another velocity (grease, a seal: the diagnosis benchmark's scenario
25) is a ``FrictionShapeTerm`` Stribeck peak of a fitted velocity, the candidate ``lacking_friction_shapes("lugre")``
offers beside it. Known truth: the virtual Denso with a hump on joint 3 five times wider than its drive's Stribeck
curve, and without it."""

from __future__ import annotations

import pytest

from identification.diagnosis import DiagnosisOptions, diagnose
from identification.diagnosis.candidates import CandidateLibrary, FrictionShapeTerm, PreslidingTerm
from identification.diagnosis.candidates.friction import lacking_friction_shapes
from identification.virtual import effects as xp
from tests.identification.test_diagnosis_friction_rival import _record


def test_a_lugre_nominal_friction_is_offered_a_stribeck_peak_at_another_velocity():
    (shape,) = lacking_friction_shapes("lugre")
    assert type(shape) is FrictionShapeTerm and shape.shape == "stribeck" and shape.scale is None
    coulomb_viscous = lacking_friction_shapes()
    assert {getattr(s, "shape", None) for s in coulomb_viscous if type(s) is FrictionShapeTerm} == {
        "stribeck",
        "smooth_coulomb",
    }
    assert any(isinstance(s, PreslidingTerm) for s in coulomb_viscous)


HUMP_JOINT, HUMP_HEIGHT, HUMP_VELOCITY = 2, 1.5, 0.15  # [N m], [rad/s]: 5 times the drive's Stribeck velocity (0.032)


def _hump_diagnosis(denso, denso_model, extras):
    """The default (LuGre) diagnosis of a 4 s training and a 3 s validation recording with the Stribeck-peak
    candidates only (the default library takes them beside the others), the robot file's inertia, no block
    cross-validation: fast."""
    train, _ = _record(denso, 0, 4.0, extras)
    validation, _ = _record(denso, 1, 3.0, extras)
    options = DiagnosisOptions(rigid_body="prior", sparse=False, cv_folds=0,
                               library=CandidateLibrary(lacking_friction_shapes("lugre")))  # fmt: skip
    return diagnose(denso, train, validation, options, model=denso_model)


def test_a_hump_wider_than_the_drives_stribeck_curve_is_named_with_its_height_and_velocity(denso, denso_model):
    hump = xp.StribeckHump(joint=HUMP_JOINT, height=HUMP_HEIGHT, velocity=HUMP_VELOCITY, smoothing_velocity=0.01)
    report = _hump_diagnosis(denso, denso_model, [hump])
    (finding,) = report.findings
    assert finding.label == f"friction_shape[j{HUMP_JOINT + 1},stribeck]"
    assert finding.parameters["stribeck_peak_Nm"] == pytest.approx(HUMP_HEIGHT, rel=0.3)
    assert finding.parameters["stribeck_velocity_rad_s"] == pytest.approx(HUMP_VELOCITY, rel=0.3)
    assert report.rmse_after[HUMP_JOINT] < 0.7 * report.rmse_before[HUMP_JOINT]


def test_without_a_hump_the_lugre_nominal_friction_gets_no_stribeck_peak(denso, denso_model):
    assert not _hump_diagnosis(denso, denso_model, []).findings
