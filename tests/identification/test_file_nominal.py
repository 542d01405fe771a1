"""The nominal model of ``diagnose MODEL`` is the model file itself: its rigid body, its friction per joint as written
(Coulomb-viscous, Stribeck at its velocity, a viscous power law, LuGre held at its values), its torque offsets.

Reference: ``psdm validate``'s prediction of the same file on the same recording (``file_prediction``, the one path
``CalibratedModel.predict_recording``), independent of the diagnosis's columns. On the file's own training recording
the diagnosis's refit of the file's friction is the file's friction again, so the nominal model's validation RMSE is the
file's, per joint, to 1e-6; a finding's gain is then measured against the file (a hidden spring of known stiffness).
"""

import copy
from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.calibrated_model import LUGRE_VERSION, CalibratedModel, LoadedModel, calibrated_robot
from identification.calibration.held_friction import without_held_rotors
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.diagnosis.candidates import CandidateLibrary
from identification.diagnosis.candidates.friction import FrictionShapeTerm, PreslidingTerm
from identification.diagnosis.diagnose import DiagnosisOptions, prepare_problem, select_terms
from identification.diagnosis.file_friction import FileFriction
from identification.diagnosis.model_file import diagnose_model, file_prediction, model_file_options
from identification.friction.models import LUGRE_PARAMETER_NAMES
from identification.metrics import rmse
from identification.virtual.effects import Spring
from identification.virtual.simulation import SimulationOptions, simulate_recording
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

STIFFNESS = 6.0  # the hidden spring on joint 4 [N m/rad]
#: Joint 3 (0-based 2) is Stribeck in the file, the others Coulomb-viscous; viscous power laws on four joints.
EXPONENTS = (0.9, 0.55, 0.7, 1.0, 0.6, 0.7)


@pytest.fixture(scope="module")
def recordings(denso):
    """A training (6 s) and a validation (4 s) recording of the virtual Denso with a spring on joint 4 that its robot
    file does not know."""
    out = []
    for seed, duration in ((0, 6.0), (1, 4.0)):
        rng = np.random.default_rng(seed)
        reference = sine_experiment(denso, duration=duration, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=500.0)
        recording, _ = simulate_recording(denso, reference, options, rng, extras=[Spring(joint=3, stiffness=STIFFNESS,
                                                                                          q0=0.4)])  # fmt: skip
        out.append(recording)
    return tuple(out)


def _identified(denso, denso_model, recording, exponents=EXPONENTS):
    """The model identified on ``recording``: Stribeck on joint 3, Coulomb-viscous elsewhere, viscous power laws of
    ``exponents``, torque offsets, no spring (``LoadedModel``; its Stribeck velocity held and no envelope: a second's
    fit)."""
    options = TrajectoryOptions(
        friction=("fc", "fs", "fv", "offset"),
        stribeck_joints=(2,),
        viscous_exponent=exponents,
        stribeck_held=(0.0, 0.0, 0.03, 0.0, 0.0, 0.0),
        envelope=False,
    )  # a cheap fit
    fit = identify_trajectories(denso, denso_model, [recording], options)
    calibrated = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    return LoadedModel(calibrated, denso, denso_model)


def _lugre_joints(loaded, drives: dict):
    """``loaded`` with each joint of ``drives`` (0-based -> ``DriveParameters``) LuGre at those parameters (a mixed
    model, ``mixed_friction``): their steady-state columns 0, ``drive.lugre`` null on the other joints."""
    document = copy.deepcopy(loaded.calibrated.document)
    values, n = document["drive"], loaded.calibrated.n_dof
    for k, name in enumerate(values["names"]):
        if name[:2] in ("fc", "fs", "fv") and int(name[2:]) - 1 in drives:
            values["values"][k] = 0.0
    shapes = ["lugre" if j in drives else shape for j, shape in enumerate(values["friction_shapes"])]
    values["lugre"] = {name: [getattr(drives[j], name) if j in drives else None for j in range(n)]
                       for name in LUGRE_PARAMETER_NAMES}  # fmt: skip
    values["lugre"]["joints"] = [j + 1 for j in sorted(drives)]
    values.update(friction_shape="lugre", friction_shapes=shapes)
    document["version"] = LUGRE_VERSION
    return replace(loaded, calibrated=CalibratedModel(document))


@pytest.fixture(scope="module")
def stribeck_file(denso, denso_model, recordings):
    """The model identified on the training recording (``_identified``)."""
    return _identified(denso, denso_model, recordings[0])


@pytest.fixture(scope="module")
def lugre_file(stribeck_file, denso):
    """The same file with joint 2 LuGre at the robot file's drive parameters (``_lugre_joints``)."""
    return _lugre_joints(stribeck_file, {1: denso.drives[1]})


def _nominal(loaded, recordings):
    """The validation RMSE per joint of the diagnosis's nominal model of ``loaded`` (its friction refitted on the
    training recording, no candidate) from the file's robot as ``diagnose_model`` builds it, its options and the
    prepared problem."""
    options = model_file_options(loaded.calibrated, DiagnosisOptions(rigid_body="prior", friction_shapes=False,
                                                                     library=CandidateLibrary(())))  # fmt: skip
    robot = without_held_rotors(calibrated_robot(loaded.calibrated, loaded.robot), options.held_friction)
    problem = prepare_problem(robot, loaded.model, recordings[0], recordings[1], options)
    selection = select_terms(robot, problem, options)
    return rmse(problem.y_v, selection.nominal_validation), options, problem


def _file_coefficients(loaded, own) -> np.ndarray:
    """The file's own friction values in the layout of ``FileFriction.columns`` (a LuGre joint's steady-state values, no
    bristle column: compared on the steady-state joints only)."""
    values = dict(zip(loaded.calibrated.document["drive"]["names"], loaded.calibrated.drive))
    n, out = loaded.calibrated.n_dof, []
    for j in range(n):
        p = own.lugre[j]
        fc, fs, fv = (p.fc, p.fs, p.fv) if p is not None else (values[f"fc{j + 1}"], values[f"fs{j + 1}"],
                                                                 values[f"fv{j + 1}"])  # fmt: skip
        out += [fc, fs - fc, fv] if own.kind != "coulomb_viscous" else [fc, fv]
    return np.array(out + [0.0] * (n if own.kind == "lugre" else 0))  # the steady-state joints' (the others' unused)


@pytest.mark.parametrize("which", ["stribeck_file", "lugre_file"])
def test_the_nominal_model_predicts_the_validation_recording_as_psdm_validate(which, request, recordings):
    """The steady-state joints' columns at the file's values are its friction exactly (the file's whole prediction
    there to 1e-9 of the torque), and their refit is the file's friction again: their validation RMSE is ``psdm
    validate``'s to 1e-6. A LuGre joint keeps the diagnosis's LuGre columns (``file_friction``): near the file."""
    loaded = request.getfixturevalue(which)
    ours, options, problem = _nominal(loaded, recordings)
    validated, _, predicted = file_prediction(loaded, recordings[1])
    own = options.file_friction
    steady = [j for j in range(6) if j not in own.lugre_joints]
    np.testing.assert_allclose(ours[steady], validated[steady], rtol=1e-6)
    at_file = problem.ctx_v.tau - problem.y_v + problem.base_v.dense() @ _file_coefficients(loaded, own)
    np.testing.assert_allclose(at_file[:, steady], predicted[:, steady], rtol=0, atol=1e-9 * np.abs(predicted).max())
    assert own.shapes[2] == "stribeck" and own.shapes[0] == "coulomb-viscous"
    assert own.lugre_joints == ((1,) if which == "lugre_file" else ())
    assert own.kind == ("lugre" if which == "lugre_file" else "stribeck")
    assert "Stribeck on joint 3" in own.describe() and ("LuGre on joint 2" in own.describe()) == (which == "lugre_file")


def test_the_shapes_the_file_holds_are_not_offered_again(lugre_file):
    own = FileFriction.of_model(lugre_file.calibrated)
    assert own.holds(FrictionShapeTerm(joint=2, shape="stribeck"))  # the file's Stribeck joint
    assert not own.holds(FrictionShapeTerm(joint=0, shape="stribeck"))  # a Coulomb-viscous joint lacks it
    assert not own.holds(FrictionShapeTerm(joint=2, shape="smooth_coulomb"))
    assert own.holds(PreslidingTerm(joint=1)) and own.holds(FrictionShapeTerm(joint=1, shape="smooth_coulomb"))
    assert not own.holds(PreslidingTerm(joint=2))
    assert not own.holds(FrictionShapeTerm(joint=1, shape="stribeck"))  # LuGre: a peak at another velocity is lacking


def test_a_spring_s_gain_is_measured_against_the_model_file(stribeck_file, recordings):
    """The spring the file lacks is found on joint 4 near its stiffness, its "before" the file's own validation RMSE
    (``psdm validate``'s), and no Stribeck peak is proposed on the file's Stribeck joint."""
    options = DiagnosisOptions(rigid_body="prior", sparse=False, max_effects=1, refine=False)
    report = diagnose_model(stribeck_file, recordings[0], [recordings[1]], options)
    validated = file_prediction(stribeck_file, recordings[1])[0]
    (spring,) = [f for f in report.findings if f.effect == "spring"]
    assert tuple(spring.joints) == (3,)
    np.testing.assert_allclose(spring.rmse_before, validated, rtol=1e-6)
    assert spring.rmse_after[3] < 0.5 * validated[3]
    assert abs(spring.parameters["k"] - STIFFNESS) < 0.25 * STIFFNESS
    labels = [f.label for f in report.findings] + [u.label for u in report.unstable] + [r[0] for r in report.rejected]
    assert "friction_shape[j3,stribeck]" not in labels
    assert (
        "the model file's per-joint (Coulomb-viscous on joints 1, 2, 4, 5, 6; Stribeck on joint 3"
        in report.to_markdown()
    )


#: Joint 2's Stribeck peak in the truth of ``peak_case`` (a grease hump): static friction over the Coulomb level and its
#: velocity [rad/s].
PEAK, PEAK_VS = 2.0, 0.1


@pytest.fixture(scope="module")
def peak_case(denso, denso_model):
    """(the true drives, the file identified on the training recording, the training and validation recordings):
    ``recordings``' motions again, without a spring, joint 2's drive given a wide Stribeck peak (``PEAK`` x fc at
    ``PEAK_VS``)."""
    drives = list(denso.drives)
    drives[1] = replace(drives[1], fs=PEAK * drives[1].fc, vs=PEAK_VS)
    robot, out = replace(denso, drives=tuple(drives)), []
    for seed, duration in ((0, 6.0), (1, 4.0)):
        rng = np.random.default_rng(seed)
        reference = sine_experiment(robot, duration=duration, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=500.0)
        out.append(simulate_recording(robot, reference, options, rng)[0])
    return tuple(drives), _identified(denso, denso_model, out[0]), tuple(out)


def _stribeck_peaks(loaded, recordings) -> dict:
    """The Stribeck peaks the selection names on ``loaded`` (label -> fitted velocity [rad/s]) from a library of that
    shape alone (no friction rival)."""
    library = CandidateLibrary((FrictionShapeTerm(shape="stribeck"),))
    options = model_file_options(loaded.calibrated, DiagnosisOptions(rigid_body="prior", friction_shapes=False,
                                                                     library=library))  # fmt: skip
    robot = without_held_rotors(calibrated_robot(loaded.calibrated, loaded.robot), options.held_friction)
    problem = prepare_problem(robot, loaded.model, recordings[0], recordings[1], options)
    return {step.term.label: step.term.scale for step in select_terms(robot, problem, options).steps}


def test_a_stribeck_peak_a_lugre_joint_of_the_file_lacks_is_named_at_the_truth_s_velocity(peak_case):
    """Known truth: joint 2 has a wide Stribeck peak (``PEAK_VS``), every joint LuGre friction. A file LuGre on every
    joint at the truth's values but joint 2's, which has no peak (a static level below the Coulomb one at an eighth of
    that velocity: what a shooting fit can leave), lacks that peak, and the selection names friction_shape[j2,stribeck]
    alone, within a factor 2 of the truth's velocity (before, a LuGre joint was taken to hold any Stribeck peak: none
    was offered there). The file with joint 2's truth too holds every peak: none is named."""
    truth, identified, recordings = peak_case
    drives = dict(enumerate(truth))
    lacking = {**drives, 1: replace(truth[1], fs=0.5 * truth[1].fc, vs=PEAK_VS / 8.0)}
    named = _stribeck_peaks(_lugre_joints(identified, lacking), recordings)
    assert list(named) == ["friction_shape[j2,stribeck]"]
    assert 0.5 * PEAK_VS < named["friction_shape[j2,stribeck]"] < 2.0 * PEAK_VS
    assert not _stribeck_peaks(_lugre_joints(identified, drives), recordings)
