"""Exported equals reported, with findings: a recalibrated model's C code computes the torque its file reports.

One virtual-Denso recording pair hides one effect of every family the calibrated model holds (spring, torque
ripple, offset, coupling, Coulomb asymmetry, load-dependent friction, extra rotor inertia, payload, a torque
delay). A calibrated model is identified without them, the diagnosis' findings are given as a report (the
diagnosis itself is tested elsewhere; here the terms are the hidden ones), ``recalibrate`` identifies them
jointly, and ``psdm codegen`` compiles the result once for the module. Each family's test checks that its
term is in the exported function (the torque with and without it differs by the term computed here from its
formula and fitted coefficients), that its parameters match the hidden truth, and that the compiled C on the
validation recording reproduces the RMSE the file reports (and ``psdm validate`` prints) to 1e-9.
"""

import copy
import json
import shutil
from dataclasses import dataclass, field
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest

from codegen.calibrated import build_calibrated_functions
from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.recalibrate import recalibrate, validation_rmse
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.diagnosis.candidates import (
    CoulombAsymmetryTerm,
    CouplingTerm,
    DelayTerm,
    GravityTiltTerm,
    LoadDependentFrictionTerm,
    PayloadTerm,
    RotorInertiaTerm,
    SpringTerm,
    TorqueOffsetTerm,
    TorqueRippleTerm,
)
from identification.metrics import rmse
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
pytestmark = pytest.mark.slow  # one shared simulation, recalibration and C build of about 30 s
TOLERANCE = 1e-9
RATE, DURATION, DELAY_SAMPLES = 500.0, 10.0, 5
SPRING_K, SPRING_Q0, RIPPLE_A, RIPPLE_H, OFFSET, COUPLING, DELTA, MU, PAYLOAD = (
    40.0, 0.2, 1.0, 6, 0.8, 1.5, 1.2, 0.15, 2.0,
)  # fmt: skip
HIDDEN = (
    xp.Spring(joint=1, stiffness=SPRING_K, q0=SPRING_Q0),
    xp.TorqueRipple(joint=5, amplitude=RIPPLE_A, harmonic=float(RIPPLE_H)),
    xp.TorqueOffset(offset=(0.0, 0.0, 0.0, 0.0, 0.0, OFFSET)),
    xp.JointCoupling(matrix=COUPLING * np.outer(np.eye(6)[3], np.eye(6)[0])),  # qd of joint 1 on joint 4
    xp.CoulombAsymmetry(joint=4, delta=DELTA),
    xp.LoadDependentFriction(joint=2, coefficient=MU),
    xp.ExtraRotorInertia(inertia=(0.0, 0.0, 0.3, 0.0, 0.0, 0.0)),
    xp.Payload(mass=PAYLOAD, com=(0.0, 0.0, 0.05)),
    xp.SignalDelay(samples=DELAY_SAMPLES),
)
TERMS = (
    SpringTerm(joint=1),
    TorqueRippleTerm(joint=5, harmonic=RIPPLE_H),
    TorqueOffsetTerm(joint=5),
    CouplingTerm(joint=3, source=0),
    CoulombAsymmetryTerm(joint=4),
    LoadDependentFrictionTerm(joint=2),
    RotorInertiaTerm(joint=2),
    PayloadTerm(),
    DelayTerm(),
    GravityTiltTerm(),
)


@dataclass(frozen=True)
class _Finding:
    """What ``recalibrate`` reads of a diagnosis finding."""

    effect: str
    label: str
    joints: tuple
    coefficients: tuple
    feature_names: tuple
    parameters: dict = field(default_factory=dict)
    rmse_before: tuple = ()
    rmse_after: tuple = ()


def _report(n_dof: int):
    """A diagnosis report naming the hidden terms (the delay with its true size, a tilt that is not there)."""
    findings, coefficients = [], []
    for term in TERMS:
        c = np.zeros(len(term.feature_names()))
        if term.key == "delay":
            c[0] = DELAY_SAMPLES / RATE
        if term.key == "gravity_tilt":
            c[:] = (0.01, -0.02)
        parameters = term.physical_parameters(c) if term.key != "payload" else {"mass": PAYLOAD}
        joints = tuple(term.joints) if term.joint is not None else tuple(range(n_dof))
        findings.append(_Finding(term.key, term.label, joints, tuple(c), tuple(term.feature_names()), parameters))
        coefficients.append(c)
    return SimpleNamespace(findings=tuple(findings), augmented=SimpleNamespace(terms=TERMS, coefficients=coefficients))


@pytest.fixture(scope="module")
def loop(tmp_path_factory, denso, denso_model):
    """Recordings with every hidden effect, the model identified without them, and the recalibrated model."""
    folder = tmp_path_factory.mktemp("findings")
    recordings = []
    for k, name in enumerate(("train.csv", "valid.csv")):
        rng = np.random.default_rng(40 + k)
        reference = sine_experiment(denso, duration=DURATION, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.05, rate=RATE)
        recording, _ = simulate_recording(denso, reference, options, rng, extras=HIDDEN)
        save_recording(recording, folder / name)
        recordings.append(recording)
    fit = identify_trajectories(denso, denso_model, recordings[:1], TrajectoryOptions())
    before = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    before.save(folder / "model.json")
    result = recalibrate(before, denso, denso_model, _report(denso.n_dof), *recordings, robot_source=DENSO_FILE)
    result.after.save(folder / "new.json")
    return SimpleNamespace(folder=folder, recordings=recordings, result=result)


@pytest.fixture(scope="module")
def compiled(loop):
    """``psdm codegen new.json --compile``, once for the module: the compiled inverse dynamics."""
    out = loop.folder / "c_code"
    assert main(["codegen", str(loop.folder / "new.json"), "--out", str(out), "--compile"]) == 0
    header = (out / "psdm_dynamics.h").read_text()
    assert "spring[j2]: spring_k_2 = " in header and "delay_s" in header and "Im_3" not in header  # see below
    return ca.external("psdm_inverse_dynamics", str(out / "libpsdm_dynamics.so"))


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def _mapped(function, *columns):
    return np.array(function.map(columns[0].shape[0])(*(c.T for c in columns)), dtype=float).T


def _dropped(calibrated, label: str) -> dict:
    """The recalibration's record of the finding ``label`` it left out."""
    (entry,) = [d for d in calibrated.document["recalibration"]["dropped_findings"] if d["label"] == label]
    return entry


def _entry(model: CalibratedModel, label: str) -> dict:
    return next(e for e in model.document["findings"] if e["label"] == label)


def _without(model: CalibratedModel, label: str) -> CalibratedModel:
    document = copy.deepcopy(model.document)
    document["findings"] = [e for e in document["findings"] if e["label"] != label]
    return CalibratedModel(document)


def _check_exported_equals_reported(loop, compiled, denso_model, capsys):
    """The compiled C on the validation recording gives the RMSE in the file and the one 'psdm validate' prints."""
    after = load_calibrated_model(loop.folder / "new.json")
    _, _, prepared, predicted = validation_rmse(after, denso_model, loop.recordings[1])
    tau = _mapped(compiled, prepared.q, prepared.qd, prepared.qdd)
    np.testing.assert_allclose(tau, predicted, rtol=0, atol=TOLERANCE * np.abs(predicted).max())
    reported = after.document["validation"]["recordings"][0]["rmse"]
    np.testing.assert_allclose(rmse(prepared.tau, tau), reported, rtol=TOLERANCE)
    assert main(["validate", str(loop.folder / "new.json"), str(loop.folder / "valid.csv"), "--json"]) == 0
    validated = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    np.testing.assert_allclose(rmse(prepared.tau, tau), validated, rtol=TOLERANCE)
    return prepared


def _term_torque(loop, denso, denso_model, label: str, formula) -> None:
    """The exported function with minus without the finding is ``formula(q, qd, qdd, coefficients)`` on its joint."""
    after = loop.result.after
    prepared = validation_rmse(after, denso_model, loop.recordings[1])[2]
    x = (prepared.q, prepared.qd, prepared.qdd)
    with_term = _mapped(build_calibrated_functions(after, denso_model, denso).inverse_dynamics, *x)
    without = _mapped(build_calibrated_functions(_without(after, label), denso_model, denso).inverse_dynamics, *x)
    entry = _entry(after, label)
    coefficients = [0.0 if c is None else c for c in entry["coefficients"]]
    joint = entry["joints"][0] - 1 if entry["effect"] != "coupling" else entry["term"]["joint"] - 1
    expected = np.zeros_like(with_term)
    expected[:, joint] = formula(*x, coefficients)
    np.testing.assert_allclose(with_term - without, expected, rtol=0, atol=1e-9 * np.abs(with_term).max())


@pytest.mark.needs_cc
@needs_cc
def test_spring_is_identified_jointly_and_exported(loop, compiled, denso, denso_model, capsys):
    entry = _entry(loop.result.after, "spring[j2]")
    assert entry["kind"] == "torque" and entry["parameters"]["k"] == pytest.approx(SPRING_K, rel=0.05)
    assert entry["parameters"]["q0"] == pytest.approx(SPRING_Q0, abs=0.05)
    assert entry["validation_rmse_without"][1] > 2 * entry["validation_rmse_after"][1]  # what the spring explains
    _term_torque(loop, denso, denso_model, "spring[j2]", lambda q, qd, qdd, c: c[0] * q[:, 1] + c[1])
    _check_exported_equals_reported(loop, compiled, denso_model, capsys)


@pytest.mark.needs_cc
@needs_cc
def test_ripple_offset_and_coupling_are_exported(loop, compiled, denso, denso_model, capsys):
    after = loop.result.after
    assert _entry(after, f"torque_ripple[j6,h={RIPPLE_H}]")["parameters"]["amplitude"] == pytest.approx(
        RIPPLE_A, rel=0.1
    )
    assert _entry(after, "torque_offset[j6]")["parameters"]["offset"] == pytest.approx(OFFSET, abs=0.1)
    assert _entry(after, "coupling[j1->j4]")["parameters"]["viscous"] == pytest.approx(COUPLING, rel=0.1)
    h = RIPPLE_H
    _term_torque(loop, denso, denso_model, f"torque_ripple[j6,h={h}]",
                 lambda q, qd, qdd, c: c[0] * np.sin(h * q[:, 5]) + c[1] * np.cos(h * q[:, 5]))  # fmt: skip
    _term_torque(loop, denso, denso_model, "coupling[j1->j4]", lambda q, qd, qdd, c: c[0] * qd[:, 0] + c[1] * qdd[:, 0])
    _check_exported_equals_reported(loop, compiled, denso_model, capsys)


@pytest.mark.needs_cc
@needs_cc
def test_friction_families_use_the_models_own_torque(loop, compiled, denso, denso_model, capsys):
    after = loop.result.after
    asymmetry = _entry(after, "coulomb_asymmetry[j5]")
    assert asymmetry["parameters"]["delta"] == pytest.approx(DELTA, rel=0.15)
    load = _entry(after, "load_dependent_friction[j3]")
    # the truth is mu |tau_motor| sign(qd); the model's mu' |tau_b| sign(qd) with tau_b the torque without it
    assert MU / (1 + MU) * 0.9 < load["parameters"]["coefficient"] < MU / (1 - MU) * 1.1
    v = asymmetry["term"]["velocity"]
    _term_torque(loop, denso, denso_model, "coulomb_asymmetry[j5]",
                 lambda q, qd, qdd, c: 0.5 * c[0] * (1 + np.tanh(qd[:, 4] / v)))  # fmt: skip
    base = _without(after, "load_dependent_friction[j3]")
    _term_torque(loop, denso, denso_model, "load_dependent_friction[j3]",
                 lambda q, qd, qdd, c: c[0] * np.abs(base.predict(denso_model, q, qd, qdd)[:, 2])
                 * np.tanh(qd[:, 2] / v))  # fmt: skip
    _check_exported_equals_reported(loop, compiled, denso_model, capsys)


@pytest.mark.needs_cc
@needs_cc
def test_rotor_inertia_and_payload_are_taken_up_by_the_rigid_body(loop, compiled, denso, denso_model, capsys):
    after, before = loop.result.after, loop.result.before
    # the fit identifies joint 3's Ia already: the rotor's column absorbed, the finding holds no torque in the model
    # written and is left out by the gain rule (no_gain.GAIN_RULE), with its reason
    rotor = _dropped(after, "rotor_inertia[j3]")
    assert rotor["no_gain"] and rotor["share_lower"] == [0.0] and "holds no torque" in rotor["reason"]
    assert "rotor_inertia[j3]" not in [f["label"] for f in after.document["findings"]]
    assert _entry(after, "payload")["kind"] == "rigid_body"
    prepared = _check_exported_equals_reported(loop, compiled, denso_model, capsys)
    # the recalibration explains the data: the validation error falls on every joint with a torque finding
    assert np.all(loop.result.rmse_after[[0, 1, 2, 3, 4, 5]] < loop.result.rmse_before[[0, 1, 2, 3, 4, 5]])
    assert prepared.n_samples > 100 and before.document["findings"] == []


@pytest.mark.needs_cc
@needs_cc
def test_signal_findings_are_corrections_and_reported_ones_change_nothing(loop, compiled, denso_model, capsys):
    after = loop.result.after
    assert after.corrections == {"delay": {"effect": "delay", "delay_s": pytest.approx(DELAY_SAMPLES / RATE)}}
    # the tilt, reported (not part of the model's torque) and not there, changes nothing: the gain rule leaves it out
    tilt = _dropped(after, "gravity_tilt")
    assert tilt["no_gain"] and tilt["share_lower"] == [0.0] * 6 and "holds no torque" in tilt["reason"]
    assert "gravity_tilt" not in [f["label"] for f in after.document["findings"]]
    # without its correction the same model fits the recording worse: the delay is in the measurement
    uncorrected = copy.deepcopy(after.document)
    uncorrected["corrections"] = {}
    worse = validation_rmse(CalibratedModel(uncorrected), denso_model, loop.recordings[1])[0]
    assert np.all(worse[:3] > validation_rmse(after, denso_model, loop.recordings[1])[0][:3])
    _check_exported_equals_reported(loop, compiled, denso_model, capsys)


def test_version_1_files_are_read_and_predict_as_before(loop, denso_model, tmp_path):
    document = copy.deepcopy(load_calibrated_model(loop.folder / "model.json").document)
    document["version"] = 1
    del document["findings"]
    path = tmp_path / "v1.json"
    path.write_text(json.dumps(document))
    old = load_calibrated_model(path)
    prepared = validation_rmse(old, denso_model, loop.recordings[1])[2]
    x = (prepared.q, prepared.qd, prepared.qdd)
    np.testing.assert_array_equal(old.predict(denso_model, *x), loop.result.before.predict(denso_model, *x))
    assert old.corrections == {} and old.torque_findings == []


def test_a_malformed_finding_is_refused_naming_it(loop, denso_model, capsys):
    document = copy.deepcopy(loop.result.after.document)
    spring = next(e for e in document["findings"] if e["label"] == "spring[j2]")
    spring["coefficients"] = spring["coefficients"][:1]
    path = loop.folder / "bad.json"
    path.write_text(json.dumps(document))
    assert main(["validate", str(path), str(loop.folder / "valid.csv")]) == 2
    err = capsys.readouterr().err
    assert "findings['spring[j2]'].coefficients must be 2 finite numbers" in err and "Traceback" not in err
