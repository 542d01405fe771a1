"""A lag is not named when friction the nominal model lacks explains it (issue 25): the virtual Denso's recordings have
no positive lag between torque and motion, a Coulomb-viscous diagnosis of them names no delay, and a true 10 ms delay
is still found first."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from identification.data.preprocessing import PreprocessOptions, preprocess, zero_phase_filter
from identification.diagnosis import DiagnosisOptions, diagnose
from identification.diagnosis.candidates import BacklashTerm, CandidateLibrary, DelayTerm, JointElasticityTerm
from identification.diagnosis.candidates.friction import lacking_friction_shapes
from identification.virtual import effects as xp
from psdm_casadi.oracle import build_pinocchio_model
from tests.identification.diagnosis_data import sine_recording

CUTOFF_HZ = 15.0


def _best_shift(t, tau, model, shifts) -> float:
    """The shift d [s] for which the recorded torque at t + d fits the model torque at t best (RMS, ends trimmed)."""
    keep = slice(300, -300)
    errors = []
    for d in shifts:
        shifted = np.column_stack([np.interp(t + d, t, tau[:, j]) for j in range(tau.shape[1])])
        errors.append(np.sqrt(np.mean((shifted[keep] - model[keep]) ** 2)))
    return float(shifts[int(np.argmin(errors))])


def test_the_virtual_robot_records_no_positive_lag_between_torque_and_motion(denso):
    # independent reference: Pinocchio's rnea of the true inertia on the preprocessed motion plus the simulator's own
    # friction (the truth) filtered like the recording; the torque fits it best a quarter sample *early* (the command
    # is held over each sample period, the simulation module's docstring), never late
    robot = denso
    recording, truth = sine_recording(robot, 0, 3.0, noise=0.0)
    prepared = preprocess(recording, PreprocessOptions(cutoff_hz=CUTOFF_HZ))
    pmodel = build_pinocchio_model(robot, robot.nominal_dynamic_parameters())
    data = pmodel.createData()
    rigid = np.array([pin.rnea(pmodel, data, a, b, c) for a, b, c in zip(prepared.q, prepared.qd, prepared.qdd)])
    friction = zero_phase_filter(truth.tau_friction, 1000.0, CUTOFF_HZ, PreprocessOptions().order)
    shift = _best_shift(prepared.t, prepared.tau, rigid + friction, np.arange(-2e-3, 6e-3, 0.25e-3))
    assert -0.75e-3 <= shift <= 0.0


def _lags(robot, model, extras, seed: int, shapes: bool = False, identify_preparation: bool = False, **more):
    """A Coulomb-viscous diagnosis (the nominal model of a model file identified that way) of a 4 s training and a 3 s
    validation recording, with the lag candidates only (fast; with ``shapes`` the friction shapes such a model lacks
    too, as the default library takes them); the validation recording judges alone (no block cross-validation), so
    the friction rival is what decides. ``identify_preparation``: the default preparation (identify's, 10 Hz) instead of
    the 15 Hz / 200 Hz one below; ``more``: further ``DiagnosisOptions``."""
    train, _ = sine_recording(robot, seed, 4.0, extras)
    validation, _ = sine_recording(robot, seed + 1, 3.0, extras)
    library = DelayTerm() + JointElasticityTerm() + BacklashTerm()
    if shapes:
        library = library + CandidateLibrary(lacking_friction_shapes())
    # the 15 Hz / 200 Hz preparation the rival was built on; at identify's (10 Hz, its samples: DiagnosisOptions'
    # default since issue 25's one preparation) seed 0 gets a joint_elasticity on joint 3 or 4 (issue 25, open)
    preparation = {} if identify_preparation else {"cutoff_hz": 15.0, "rate_hz": 200.0, "samples": "diagnosis"}
    options = DiagnosisOptions(
        rigid_body="prior",
        sparse=False,
        library=library,
        cv_folds=0,
        **{"friction": "coulomb_viscous", **preparation, **more},
    )
    return diagnose(robot, train, validation, options, model=model)


def test_a_coulomb_viscous_diagnosis_of_lugre_friction_names_no_delay(denso, denso_model):
    # the virtual Denso has LuGre friction and no delay: the delay qualifies against the Coulomb-viscous model (a lag
    # of the friction), but friction shapes the nominal model lacks explain it; no lag of any kind is named, and the
    # shapes that explain it are offered and named instead (its drives' viscous friction is not linear, dv != 1, and
    # their bristles give pre-sliding)
    report = _lags(denso, denso_model, (), 0, max_effects=2)
    assert report.findings and {f.effect for f in report.findings} <= {"friction_shape", "presliding"}
    assert any(text.startswith("delay not named") for text in report.dropped)
    for finding in report.findings:
        assert finding.explanation.startswith(f"friction on joint {finding.joints[0] + 1} is not Coulomb-viscous")
        j = finding.joints[0]
        assert finding.rmse_after[j] < 0.8 * finding.rmse_before[j]


def test_a_true_10_ms_delay_is_still_named_first(denso, denso_model):
    report = _lags(denso, denso_model, (xp.SignalDelay(samples=10),), 0)
    assert report.findings and report.findings[0].effect == "delay"
    # the Coulomb-viscous model's friction lag adds to the estimate (about 7 ms of it: 17 ms on this recording); the
    # diagnosis benchmark checks the size with the robot file's LuGre friction
    assert 0.008 <= report.findings[0].parameters["delay_s"] <= 0.02
    assert not any(text.startswith("delay not named") for text in report.dropped)


@pytest.mark.parametrize("shape", ["stribeck", "smooth_coulomb", "presliding"])
def test_friction_shape_columns_are_odd_and_bounded(shape):
    # each shape is an odd function of the motion (a friction) of unit amplitude: bounded by 1, the pre-sliding deficit
    # by 2 (from one sliding level to the other after a reversal)
    from types import SimpleNamespace

    from identification.diagnosis.friction_rival import shape_column

    t = np.arange(0.0, 2.0, 1e-3)
    qd = np.sin(2 * np.pi * t)[:, None]
    ctx = SimpleNamespace(full_qd=qd, full_t=t, keep=np.arange(t.size), filtered_friction=False)
    up = shape_column(ctx, 0, shape, 0.05 if shape != "presliding" else 1e-3)
    ctx.full_qd = -qd
    down = shape_column(ctx, 0, shape, 0.05 if shape != "presliding" else 1e-3)
    bound = 2.0 if shape == "presliding" else 1.0
    assert 0.1 < np.max(np.abs(up)) <= bound + 1e-12
    np.testing.assert_allclose(up[1:], -down[1:], atol=1e-9)


@pytest.mark.parametrize(
    ("friction", "mass_tolerance", "com_tolerance_m"), [("lugre", 0.02, 0.01), ("coulomb_viscous", 0.1, 0.03)]
)
def test_the_payload_finding_on_the_benchmark_recordings_is_as_good_as_the_nominal_friction(
    denso, denso_model, friction, mass_tolerance, com_tolerance_m
):
    # benchmarks/payload.py --diagnose --duration 8: the unknown 0.8 kg tool at (0.03, 0, 0.06) m on two new 8 s
    # recordings. With the true rigid body as the prior the payload's error comes from the nominal friction alone:
    # the robot's own LuGre friction gives 0.800 kg and a centre of mass 2 mm off; a Coulomb-viscous model (what a
    # model file identified that way brings) 0.835 kg and 2.4 cm off, its centre of mass 2.3 cm low, as with the
    # calibrated arm as the prior (0.847 kg, 2.3 cm): the limit of that friction shape, not of the rigid body
    from identification.diagnosis.candidates import CandidateLibrary, PayloadTerm

    truth_mass, truth_com = 0.8, np.array([0.03, 0.0, 0.06])
    tool = xp.Payload(mass=truth_mass, com=tuple(truth_com))
    train, validation = (sine_recording(denso, 400 + k, 8.0, (tool,))[0] for k in range(2))
    options = DiagnosisOptions(friction=friction, rigid_body="prior", library=CandidateLibrary((PayloadTerm(),)),
                               sparse=False, refine=False, cv_folds=0)  # fmt: skip
    report = diagnose(denso, train, validation, options, model=denso_model)
    (found,) = [f.parameters for f in report.findings if f.effect == "payload"]
    com = np.array([found["com_x"], found["com_y"], found["com_z"]])
    assert abs(found["mass"] - truth_mass) <= mass_tolerance * truth_mass
    assert np.linalg.norm(com - truth_com) <= com_tolerance_m


STRIBECK_JOINT, STRIBECK_PEAK, STRIBECK_VELOCITY = 3, 1.5, 0.25  # [N m above fc = 3.59 N m], [rad/s]


def stribeck_robot(denso):
    """The Denso whose joint 4 alone has a Stribeck peak (fs - fc = 1.5 N m, vs = 0.25 rad/s), every drive's viscous
    friction linear (dv = 1) and its bristles stiff and lightly damped (sigma0 5e4 N m/rad, sigma1 0.5 N m s/rad), so
    that the friction is the steady-state curve a friction shape describes (the file's sigma1 of 9 N m s/rad adds up
    to 0.7 N m below 0.1 rad/s, a damping no velocity curve follows)."""
    from dataclasses import replace

    drives = tuple(
        replace(d, fs=d.fc + (STRIBECK_PEAK if j == STRIBECK_JOINT else 0.0), dv=1.0, sigma0=5e4, sigma1=0.5,
                vs=STRIBECK_VELOCITY if j == STRIBECK_JOINT else d.vs)
        for j, d in enumerate(denso.drives)
    )  # fmt: skip
    return replace(denso, drives=drives)


@pytest.fixture(scope="module")
def stribeck_denso(denso):
    return stribeck_robot(denso)


def _stribeck_finding(report):
    label = f"friction_shape[j{STRIBECK_JOINT + 1},stribeck]"
    (finding,) = [f for f in report.findings if f.label == label]
    return finding


def test_a_stribeck_peak_a_coulomb_viscous_model_lacks_is_named_with_its_size(stribeck_denso, denso_model):
    # known truth: the simulated joint 4's Stribeck peak; the finding's coefficient is the peak above the Coulomb level
    # (1.70 N m, vs 0.289 rad/s on this recording pair, beside the pre-sliding of its bristles; 1.40 N m without the
    # pre-sliding candidate, 1.52 and 0.268 on seed 2), its scale the Stribeck velocity. The bristles' pre-sliding is
    # named too: its level is the joint's Coulomb friction, which builds up after each reversal (3.61 N m; truth 3.59).
    # With the 15 Hz / 200 Hz preparation seed 2 names nothing and seed 0 a delay of 6 ms beside the peak: the stiff,
    # lightly damped bristles stick at reversals, a lag of the motion the default preparation's 10 Hz filter leaves out
    # one filter period trimmed, the preparation this scenario was built on: with identify's three, 0.3 s of each end of
    # the 3 s / 4 s recordings goes, the peak comes out 1.91 N m and the pre-sliding is named on joint 3 (issue 25)
    report = _lags(stribeck_denso, denso_model, (), 0, shapes=True, identify_preparation=True, refine=False,
                   edge_periods=1)  # fmt: skip
    finding = _stribeck_finding(report)
    assert finding.parameters["stribeck_peak_Nm"] == pytest.approx(STRIBECK_PEAK, rel=0.15)
    assert finding.parameters["stribeck_velocity_rad_s"] == pytest.approx(STRIBECK_VELOCITY, rel=0.25)
    assert f"a Stribeck peak of {finding.parameters['stribeck_peak_Nm']:.3g} N m" in finding.explanation
    assert finding.rmse_after[STRIBECK_JOINT] < 0.8 * finding.rmse_before[STRIBECK_JOINT]
    (presliding,) = [f for f in report.findings if f.label == f"presliding[j{STRIBECK_JOINT + 1}]"]
    fc = stribeck_denso.drives[STRIBECK_JOINT].fc
    assert presliding.parameters["presliding_coulomb_Nm"] == pytest.approx(fc, rel=0.15)
    assert "identify --friction lugre" in presliding.explanation
    assert not any(f.effect == "delay" for f in report.findings)
    assert not any(f.effect == "friction_shape" and f.joints != (STRIBECK_JOINT,) and "stribeck" in f.label
                   for f in report.findings)  # fmt: skip


def test_a_true_delay_beside_a_stribeck_peak_is_named_a_delay_first(stribeck_denso, denso_model):
    report = _lags(
        stribeck_denso, denso_model, (xp.SignalDelay(samples=10),), 0, shapes=True, identify_preparation=True
    )
    assert report.findings[0].effect == "delay"
    assert 0.008 <= report.findings[0].parameters["delay_s"] <= 0.02
    finding = _stribeck_finding(report)  # and the peak beside it
    assert finding.parameters["stribeck_peak_Nm"] == pytest.approx(STRIBECK_PEAK, rel=0.15)
