"""The gas-spring lever law: its columns against the strut's own torque law, its geometry by variable projection, its
physical bounds, and the whole loop on a virtual Denso hiding a gas-spring counterbalance (chosen over the
polynomial spring by BIC, the torque curve of the truth recovered, the exported C equal to the report)."""

from __future__ import annotations

import shutil
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.extra_terms import TermContext
from identification.calibration.recalibrate import recalibrate, validation_rmse
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.diagnosis import DiagnosisOptions, diagnose
from identification.diagnosis.candidates import GasSpringTerm
from identification.diagnosis.candidates.gas_spring import fit_geometry, lever_columns
from identification.diagnosis.term_spec import term_from_spec
from identification.metrics import rmse
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

# the hidden strut: levers 0.25 m (base) and 0.1 m (link), aligned at q2 = -0.9 rad, 300 N at 0.35 m, 1500 N/m
STRUT = xp.GasSpringCounterbalance(joint=1, a=0.25, b=0.1, q0=-0.9, preload=300.0, length0=0.35, stiffness=1500.0)


def _true_coefficients(strut):
    """The term's coefficients of a strut: p1 = b (F0 + k l0), p2 = k a b, with a the longer lever."""
    long_, short = max(strut.a, strut.b), min(strut.a, strut.b)
    return np.array([short * (strut.preload + strut.stiffness * strut.length0), strut.stiffness * long_ * short])


def test_the_lever_columns_with_the_true_coefficients_are_the_strut_torque():
    term = GasSpringTerm(joint=1, ratio=0.1 / 0.25, q0=-0.9)
    q = np.linspace(-0.85, 2.5, 200)
    # the motors supply the opposite of the strut's torque (virtual effect, written from the strut's geometry)
    np.testing.assert_allclose(term.torque_of_angle(q, _true_coefficients(STRUT)), -STRUT.strut_torque(q), atol=1e-12)
    # the CasADi expression (the export) is the same function of the angle
    qs = ca.SX.sym("q", 6)
    expression = term.casadi_expression(qs, qs, qs, 0.0, None, list(_true_coefficients(STRUT)))
    function = ca.Function("f", [qs], [expression])
    values = [float(function(np.r_[0.0, x, 0, 0, 0, 0])[1]) for x in q[::20]]
    np.testing.assert_allclose(values, -STRUT.strut_torque(q[::20]), atol=1e-12)
    assert term_from_spec(term.spec()) == term


def test_the_geometry_is_found_by_variable_projection_among_other_columns(rng):
    """A strut's torque hidden in a signal with a sine, a constant and friction-like columns the fit also holds."""
    n = 3000
    q = -0.2 + 0.7 * np.sin(np.linspace(0, 9, n)) + 0.05 * rng.normal(size=n)
    qd = np.gradient(q)
    other = np.column_stack([np.sin(q), np.cos(q), np.ones(n), np.tanh(qd / 1e-3), qd])
    y = -STRUT.strut_torque(q) + other @ rng.normal(0, 5, 5) + 0.05 * rng.normal(size=n)

    def sse(columns):  # the least-squares SSE with the other columns fitted alongside (what JointScore computes)
        basis = np.column_stack([columns, other])
        return float(np.sum((y - basis @ np.linalg.lstsq(basis, y, rcond=None)[0]) ** 2))

    ratio, q0 = fit_geometry(q, sse)
    assert ratio == pytest.approx(0.4, abs=0.01) and q0 == pytest.approx(-0.9, abs=0.01)
    assert sse(lever_columns(q, ratio, q0)) < 1.01 * sse(lever_columns(q, 0.4, -0.9))


def test_a_strut_that_would_pull_or_soften_is_not_a_gas_spring():
    term = GasSpringTerm(joint=1, ratio=0.4, q0=-0.9, q_range=(-0.8, 0.6))
    assert term.implausibility(_true_coefficients(STRUT)) is None
    assert "would pull" in term.implausibility(-_true_coefficients(STRUT))
    assert "negative strut stiffness" in term.implausibility([80.0, -5.0])
    with pytest.raises(ValueError, match="GasSpringTerm.ratio must be in"):
        GasSpringTerm(joint=1, ratio=1.0)


@pytest.fixture(scope="module")
def loop(tmp_path_factory, denso, denso_model):
    """Training and validation recordings with the hidden strut, the diagnosis, and the recalibrated model file."""
    folder = tmp_path_factory.mktemp("gas_spring")
    recordings = []
    for seed in (79, 72):  # joint 2 sweeps -0.87..0.62 rad (training) and -0.20..0.61 rad (validation)
        rng = np.random.default_rng(seed)
        reference = sine_experiment(denso, duration=10.0, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.05, rate=500.0)
        recordings.append(simulate_recording(denso, reference, options, rng, extras=(STRUT,))[0])
    report = diagnose(denso, *recordings, DiagnosisOptions(), model=denso_model)
    fit = identify_trajectories(denso, denso_model, recordings[:1], TrajectoryOptions())
    before = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    after = recalibrate(before, denso, denso_model, report, *recordings, robot_source=DENSO_FILE).after
    after.save(folder / "model.json")
    return SimpleNamespace(folder=folder, recordings=recordings, report=report)


@pytest.mark.slow
def test_the_diagnosis_chooses_the_lever_law_and_recovers_the_strut(loop):
    (finding,) = loop.report.findings
    assert finding.label == "gas_spring[j2]" and finding.effect == "spring"
    term = next(t for t in loop.report.augmented.terms if t.label == finding.label)
    assert isinstance(term, GasSpringTerm)
    # chosen against the polynomial shapes by BIC: the finding's shape note lists them
    assert "spring[j2,order=3]: dBIC" in finding.shape_note and "gas_spring[j2] chosen by BIC" in finding.shape_note
    # the torque curve over the recorded range equals the strut's within 1 % of its span
    q = np.linspace(*term.q_range, 200)
    fitted = term.torque_of_angle(q, finding.coefficients)
    truth = -STRUT.strut_torque(q)
    assert np.max(np.abs(fitted - truth)) < 0.01 * np.ptp(truth), np.max(np.abs(fitted - truth))
    assert finding.parameters["ratio"] == pytest.approx(0.4, abs=0.01)
    assert finding.parameters["q0"] == pytest.approx(-0.9, abs=0.01)


@pytest.mark.slow
@pytest.mark.needs_cc
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_the_exported_c_of_the_gas_spring_model_equals_the_report(loop, denso_model, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(loop.folder / "cache"))
    after = load_calibrated_model(loop.folder / "model.json")
    entry = next(e for e in after.document["findings"] if e["label"] == "gas_spring[j2]")
    assert entry["kind"] == "torque" and entry["term"]["spec"]["key"] == "gas_spring"
    out = loop.folder / "c_code"
    assert main(["codegen", str(loop.folder / "model.json"), "--out", str(out), "--compile"]) == 0
    compiled = ca.external("psdm_inverse_dynamics", str(out / "libpsdm_dynamics.so"))
    _, _, prepared, predicted = validation_rmse(after, denso_model, loop.recordings[1])
    n = prepared.q.shape[0]
    tau = np.array(compiled.map(n)(prepared.q.T, prepared.qd.T, prepared.qdd.T), dtype=float).T
    reported = after.document["validation"]["recordings"][0]["rmse"]
    np.testing.assert_allclose(rmse(prepared.tau, tau), reported, rtol=1e-9)
    np.testing.assert_allclose(tau, predicted, rtol=0, atol=1e-9 * np.abs(predicted).max())
    # the strut's torque is in the exported model: joint 2's validation RMSE is far below the one without it
    assert entry["validation_rmse_without"][1] > 10 * entry["validation_rmse_after"][1]


def test_the_columns_equal_the_casadi_expression_and_leave_the_inputs_alone(rng):
    q, qd, qdd = (rng.uniform(-1, 1, (20, 6)) for _ in range(3))
    context = TermContext(np.arange(20.0), q.copy(), qd, qdd)
    term = GasSpringTerm(joint=2, ratio=0.3, q0=0.4)
    columns = term.columns(context)
    assert columns.shape == (20, 6, 2) and not np.any(columns[:, [0, 1, 3, 4, 5], :])
    np.testing.assert_array_equal(context.q, q)
    qs = ca.SX.sym("q", 6)
    function = ca.Function("f", [qs], [term.casadi_expression(qs, qs, qs, 0.0, None, [1.3, -0.7])])
    expected = columns @ np.array([1.3, -0.7])
    np.testing.assert_allclose(np.array(function.map(20)(q.T)).T, expected, rtol=1e-12, atol=1e-12)
