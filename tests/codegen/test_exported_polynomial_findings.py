"""Findings beyond a linear spring reach the exported C: a cubic counterbalance and an unnamed (sparse) term.

A virtual-Denso recording pair hides a cubic counterbalance on joint 2 and a position-dependent friction on joint 3
(outside the named library). A calibrated model is identified without them; the diagnosis' findings are given as a
report (the terms a diagnosis proposes: a spring of order 3 and an unnamed term whose features are the hidden law's,
plus a torque ripple that is not there). ``recalibrate`` fits them jointly, drops the ripple (it does not lower its
joint's validation RMSE), and ``psdm codegen`` compiles the model file. References: the hidden laws (known synthetic
truth) and ``CalibratedModel.predict`` (the compiled C must equal it to 1e-9).
"""

import json
import shutil
from dataclasses import dataclass
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest

from codegen.calibrated import build_calibrated_functions
from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.recalibrate import recalibrate, validation_rmse
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.diagnosis.candidates import SpringTerm, TorqueRippleTerm
from identification.diagnosis.sparse_terms import SparseTerm, sparse_features
from identification.diagnosis.term_spec import term_from_spec
from identification.metrics import rmse
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
pytestmark = pytest.mark.slow  # one shared simulation, two recalibration fits and a C build
TOLERANCE = 1e-9
RATE, DURATION, NOISE = 500.0, 10.0, 0.05
A1, A3, Q0 = 15.0, 12.0, 0.1  # cubic counterbalance on joint 2: A1 (q - Q0) + A3 (q - Q0)^3
FRICTION_A = 1.5  # position-dependent friction on joint 3: FRICTION_A sin(2 q3) sign(qd3)


@dataclass(frozen=True)
class CubicCounterbalance(xp.ExtraPhysics):
    """The hidden nonlinear counterbalance of joint ``joint``."""

    joint: int
    has_torque = True

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        x = q[self.joint] - Q0
        out[self.joint] = A1 * x + A3 * x**3
        return out


def _law(q):
    return A1 * (q - Q0) + A3 * (q - Q0) ** 3


def _finding(term, coefficients):
    return SimpleNamespace(
        effect=term.key, label=term.label, joints=tuple(term.joints), coefficients=tuple(coefficients),
        feature_names=tuple(term.feature_names()), parameters={}, rmse_before=(), rmse_after=(),
    )  # fmt: skip


@pytest.fixture(scope="module")
def loop(tmp_path_factory, denso, denso_model):
    folder = tmp_path_factory.mktemp("polynomial")
    hidden = (
        CubicCounterbalance(joint=1),
        xp.PositionDependentFriction(joint=2, amplitude=FRICTION_A, harmonic=2.0, smoothing_velocity=0.02),
    )
    recordings = []
    # two motions whose joint 2 and 3 ranges overlap: a polynomial is judged inside the range it was fitted on
    for seed, name in ((79, "train.csv"), (72, "valid.csv")):
        rng = np.random.default_rng(seed)
        reference = sine_experiment(denso, duration=DURATION, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=NOISE, rate=RATE)
        recording, _ = simulate_recording(denso, reference, options, rng, extras=hidden)
        save_recording(recording, folder / name)
        recordings.append(recording)
    fit = identify_trajectories(denso, denso_model, recordings[:1], TrajectoryOptions())
    before = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    before.save(folder / "model.json")
    q = recordings[0].q[:, 1]
    lo, hi = float(q.min()), float(q.max())
    spring = SpringTerm(joint=1, order=3, centre=0.5 * (lo + hi), q_range=(lo, hi))
    library = {f.name(2): f for f in sparse_features()}
    unnamed = SparseTerm(joint=2, features=(library["sin(2q3) sign(qd3)"],), centre=0.0)
    ripple = TorqueRippleTerm(joint=4, harmonic=7)
    terms = (spring, unnamed, ripple)
    coefficients = [np.zeros(len(t.feature_names())) for t in terms]
    report = SimpleNamespace(
        findings=tuple(_finding(t, c) for t, c in zip(terms, coefficients)),
        augmented=SimpleNamespace(terms=terms, coefficients=coefficients),
    )
    result = recalibrate(before, denso, denso_model, report, *recordings, robot_source=DENSO_FILE)
    result.after.save(folder / "new.json")
    return SimpleNamespace(folder=folder, recordings=recordings, result=result, spring=spring, q_range=(lo, hi))


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def _mapped(function, q, qd, qdd):
    return np.array(function.map(q.shape[0])(q.T, qd.T, qdd.T), dtype=float).T


def _entry(model, label):
    return next(e for e in model.document["findings"] if e["label"] == label)


def test_the_cubic_counterbalance_is_fitted_as_the_true_law(loop):
    after = load_calibrated_model(loop.folder / "new.json")
    entry = _entry(after, "spring[j2,order=3]")
    assert entry["kind"] == "torque" and entry["term"]["spec"]["order"] == 3
    assert entry["feature_names"] == ["k1_q2", "k2_q2", "k3_q2", "c_2"]
    coefficients = [0.0 if c is None else c for c in entry["coefficients"]]
    q = np.linspace(*loop.q_range, 50)
    fitted = loop.spring.torque_of_angle(q, coefficients)
    # the spring's constant is shared with the joint's drive offset (absorbed or split): compare the shape
    shape_error = (fitted - fitted.mean()) - (_law(q) - _law(q).mean())
    assert np.max(np.abs(shape_error)) < 0.05 * np.ptp(_law(q)), np.max(np.abs(shape_error))
    assert entry["validation_rmse_without"][1] > 3 * entry["validation_rmse_after"][1]
    before = after.document["recalibration"]["before"]["validation_rmse"][1]
    assert entry["validation_rmse_after"][1] < 0.5 * before


def test_the_unnamed_term_is_a_torque_of_the_model(loop):
    after = load_calibrated_model(loop.folder / "new.json")
    entry = _entry(after, "unnamed_effect[j3]")
    assert entry["kind"] == "torque" and entry["term"]["spec"]["features"][0]["position"] == ["sin", 2]
    assert entry["coefficients"][0] == pytest.approx(FRICTION_A, rel=0.05)
    assert entry["validation_rmse_without"][2] > 1.5 * entry["validation_rmse_after"][2]


def test_a_finding_that_does_not_help_is_dropped_and_the_model_refitted_without_it(loop, denso_model):
    after = load_calibrated_model(loop.folder / "new.json")
    dropped = after.document["recalibration"]["dropped_findings"]
    assert [d["label"] for d in dropped] == ["torque_ripple[j5,h=7]"]
    assert dropped[0]["validation_rmse_without"][0] <= dropped[0]["validation_rmse_with"][0]
    labels = [e["label"] for e in after.document["findings"]]
    assert labels == ["spring[j2,order=3]", "unnamed_effect[j3]"]
    names = after.document["drive"]["names"]
    assert not any("ripple" in n for n in names)
    reported = after.document["recalibration"]["after"]["validation_rmse"]
    np.testing.assert_allclose(reported, validation_rmse(after, denso_model, loop.recordings[1])[0], rtol=1e-12)


@pytest.mark.needs_cc
@needs_cc
def test_exported_c_equals_predict_and_the_reported_rmse(loop, denso_model, capsys):
    out = loop.folder / "c_code"
    assert main(["codegen", str(loop.folder / "new.json"), "--out", str(out), "--compile"]) == 0
    header = (out / "psdm_dynamics.h").read_text()
    assert "spring[j2,order=3]: k1_q2 = " in header and "unnamed_effect[j3]: sin(2q3) sign(qd3)_on_3 = " in header
    compiled = ca.external("psdm_inverse_dynamics", str(out / "libpsdm_dynamics.so"))
    after = load_calibrated_model(loop.folder / "new.json")
    _, _, prepared, predicted = validation_rmse(after, denso_model, loop.recordings[1])
    n = prepared.q.shape[0]
    tau = np.array(compiled.map(n)(prepared.q.T, prepared.qd.T, prepared.qdd.T), dtype=float).T
    np.testing.assert_allclose(tau, predicted, rtol=0, atol=TOLERANCE * np.abs(predicted).max())
    np.testing.assert_allclose(
        rmse(prepared.tau, tau), after.document["validation"]["recordings"][0]["rmse"], rtol=TOLERANCE
    )
    capsys.readouterr()
    assert main(["validate", str(loop.folder / "new.json"), str(loop.folder / "valid.csv"), "--json"]) == 0
    validated = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    np.testing.assert_allclose(rmse(prepared.tau, tau), validated, rtol=TOLERANCE)


@pytest.mark.needs_cc
@needs_cc
def test_diagnose_apply_and_codegen_carry_the_cubic_counterbalance(loop, denso, denso_model, capsys):
    """The whole loop on the command line: the diagnosis picks the cubic shape, --apply fits it jointly, the
    compiled C equals predict, and its spring torque is the hidden law (up to the constant shared with the drive
    offset)."""
    folder = loop.folder
    argv = ["diagnose", str(folder / "model.json"), "--train", str(folder / "train.csv"), "--validate",
            str(folder / "valid.csv"), "--apply", str(folder / "diagnosed.json")]  # fmt: skip
    assert main(argv) == 0
    assert "## Recalibration with the findings" in capsys.readouterr().out
    after = load_calibrated_model(folder / "diagnosed.json")
    entry = _entry(after, "spring[j2,order=3]")
    spring = term_from_spec(entry["term"]["spec"])
    q = np.linspace(*spring.q_range, 50)
    fitted = spring.torque_of_angle(q, [0.0 if c is None else c for c in entry["coefficients"]])
    shape_error = (fitted - fitted.mean()) - (_law(q) - _law(q).mean())
    assert np.max(np.abs(shape_error)) < 0.05 * np.ptp(_law(q)), np.max(np.abs(shape_error))
    out = folder / "c_diagnosed"
    assert main(["codegen", str(folder / "diagnosed.json"), "--out", str(out), "--compile"]) == 0
    compiled = ca.external("psdm_inverse_dynamics", str(out / "libpsdm_dynamics.so"))
    _, _, prepared, predicted = validation_rmse(after, denso_model, loop.recordings[1])
    x = (prepared.q, prepared.qd, prepared.qdd)
    tau = _mapped(compiled, *x)
    np.testing.assert_allclose(tau, predicted, rtol=0, atol=TOLERANCE * np.abs(predicted).max())
    without = CalibratedModel(
        dict(after.document, findings=[e for e in after.document["findings"] if e["label"] != entry["label"]])
    )
    exported_spring = (tau - _mapped(build_calibrated_functions(without, denso_model, denso).inverse_dynamics, *x))[
        :, 1
    ]
    law = _law(prepared.q[:, 1])
    error = (exported_spring - exported_spring.mean()) - (law - law.mean())
    assert np.sqrt(np.mean(error**2)) < 0.03 * np.ptp(law), np.sqrt(np.mean(error**2))
