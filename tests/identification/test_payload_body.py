"""A payload with its own inertia (issue 16): the diagnosis' payload term as a rigid body, not only a point mass.

References: Pinocchio's RNEA with the body added to the last link (the columns), the parameters a virtual
payload is simulated with (the finding), and the compiled C of the recalibrated model (exported = reported).
"""

from __future__ import annotations

import shutil

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.recalibrate import recalibrate, validation_rmse
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.diagnosis import DiagnosisOptions, diagnose
from identification.diagnosis.candidates import PayloadTerm
from identification.diagnosis.candidates.inertial import payload_inertia_about_com
from identification.diagnosis.context import build_context
from identification.diagnosis.term_spec import term_from_spec
from identification.metrics import rmse
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.oracle import build_pinocchio_model
from tests.conftest import DENSO_FILE
from tests.identification.diagnosis_data import recording_pair
from trajopt.experiments import sine_experiment

MASS, LENGTH, RADIUS = 4.0, 0.4, 0.02  # a 4 kg bar 0.4 m long


def bar(axis: int, com) -> xp.Payload:
    """A solid bar along flange axis ``axis`` with its centre of mass at ``com`` [m] (a tool, a welding torch)."""
    across = MASS * (3 * RADIUS**2 + LENGTH**2) / 12
    moments = np.full(3, across)
    moments[axis] = MASS * RADIUS**2 / 2
    return xp.Payload(mass=MASS, com=tuple(com), inertia=tuple(map(tuple, np.diag(moments))))


@pytest.fixture(scope="module")
def context(denso, denso_model):
    rng = np.random.default_rng(5)
    options = SimulationOptions(record_tau=True, record_current=False)
    rec, _ = simulate_recording(denso, sine_experiment(denso, duration=2.0, rng=rng).reference(), options, rng)
    return build_context(denso, denso_model, preprocess(rec, PreprocessOptions(cutoff_hz=15.0)), rate_hz=100.0)


def test_body_columns_are_the_torque_of_the_body_on_the_last_link(denso, context):
    payload = bar(axis=0, com=(0.03, -0.02, 0.1))
    _, with_body = payload.modify_model(denso, denso.nominal_dynamic_parameters())
    tau = []
    for parameters in (denso.nominal_dynamic_parameters(), with_body):
        pmodel = build_pinocchio_model(denso, parameters)
        data = pmodel.createData()
        tau.append(np.array([pin.rnea(pmodel, data, *x) for x in zip(context.q, context.qd, context.qdd)]))
    expected = tau[1] - tau[0]
    term = PayloadTerm(inertia=True)
    predicted = term.columns(context) @ payload.dynamic_parameters()
    np.testing.assert_allclose(predicted, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    # the point mass is the body's first four columns; it misses the bar's rotational inertia
    point = PayloadTerm().columns(context) @ payload.dynamic_parameters()[:4]
    np.testing.assert_array_equal(PayloadTerm().columns(context), term.columns(context)[:, :, :4])
    wrist = [3, 5]  # joints 4 and 6, whose torque of the bar is mostly its rotational inertia
    assert np.all(rmse(point[:, wrist], expected[:, wrist]) > 0.5 * rmse(0.0 * expected[:, wrist], expected[:, wrist]))


def test_body_parameters_are_the_simulated_ones_and_an_inconsistent_body_is_refused():
    payload = bar(axis=2, com=(0.01, 0.0, 0.2))
    term = PayloadTerm(inertia=True)
    c = payload.dynamic_parameters()
    found = term.physical_parameters(c)
    assert found["mass"] == pytest.approx(MASS) and found["com_z"] == pytest.approx(0.2)
    np.testing.assert_allclose(payload_inertia_about_com(c), np.asarray(payload.inertia), atol=1e-12)
    assert found["Ixx_com"] == pytest.approx(payload.inertia[0][0]) and found["Ixy_com"] == pytest.approx(0.0)
    assert term.implausibility(c) is None
    squashed = c.copy()
    squashed[9] -= 0.05  # Izz about the origin well below what the mass at its distance alone gives
    assert "not a consistent body" in term.implausibility(squashed)
    assert "negative mass" in term.implausibility(-c)
    assert term.label == "payload[inertia]" and len(term.feature_names()) == 10
    assert term_from_spec(term.spec()) == term and term_from_spec(PayloadTerm().spec()) == PayloadTerm()
    assert term_from_spec({"key": "payload"}) == PayloadTerm()  # a file written before the body variant
    assert PayloadTerm().shape_variants(None) == (PayloadTerm(), term) and term.shape_variants(None) == (term,)


needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


@pytest.mark.slow
@pytest.mark.needs_cc
@needs_cc
def test_a_bar_on_the_flange_is_found_with_its_inertia_and_exported_as_reported(
    denso, denso_model, tmp_path, monkeypatch
):
    """A tool 0.4 m long along the flange axis: its inertia about the flange is 5x what its mass at the centre
    of mass gives, which the point-mass term cannot carry; the body is found, recalibrated and exported."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    payload = bar(axis=2, com=(0.0, 0.0, 0.2))
    train, val = recording_pair(denso, [payload], seed=7, train_s=12.0, val_s=6.0)
    report = diagnose(denso, train, val, DiagnosisOptions(sparse=False), model=denso_model)
    assert report.rigid_body == "prior" and report.rigid_body_notes == ()
    found = [f for f in report.findings if f.effect == "payload"]
    assert [f.label for f in found] == ["payload[inertia]"], report.summary()
    p = found[0].parameters
    assert p["mass"] == pytest.approx(MASS, rel=0.03) and p["com_z"] == pytest.approx(0.2, abs=0.01)
    across = payload.inertia[0][0]
    assert p["Ixx_com"] == pytest.approx(across, rel=0.15) and p["Iyy_com"] == pytest.approx(across, rel=0.15)
    assert abs(p["Izz_com"]) < 0.1 * across
    # exported = reported: the recalibrated model takes the body up; its compiled C gives the file's RMSE
    for name, rec in (("train.csv", train), ("valid.csv", val)):
        save_recording(rec, tmp_path / name)
    fit = identify_trajectories(denso, denso_model, [train], TrajectoryOptions())
    before = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    result = recalibrate(before, denso, denso_model, report, train, val, robot_source=DENSO_FILE)
    result.after.save(tmp_path / "new.json")
    out = tmp_path / "c_code"
    assert main(["codegen", str(tmp_path / "new.json"), "--out", str(out), "--compile"]) == 0
    compiled = ca.external("psdm_inverse_dynamics", str(out / "libpsdm_dynamics.so"))
    after = load_calibrated_model(tmp_path / "new.json")
    _, _, prepared, predicted = validation_rmse(after, denso_model, val)
    x = (prepared.q, prepared.qd, prepared.qdd)
    tau = np.array(compiled.map(prepared.n_samples)(*(c.T for c in x)), dtype=float).T
    np.testing.assert_allclose(tau, predicted, rtol=0, atol=1e-9 * np.abs(predicted).max())
    reported = after.document["validation"]["recordings"][0]["rmse"]
    np.testing.assert_allclose(rmse(prepared.tau, tau), reported, rtol=1e-9)
    entry = next(e for e in after.document["findings"] if e["label"] == "payload[inertia]")
    assert entry["kind"] == "rigid_body" and entry["parameters"]["mass"] == pytest.approx(p["mass"])
