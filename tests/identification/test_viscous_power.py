"""The viscous power law of the column choice (``viscous_power``): the paper's ``fv |qd|^dv sign(qd)`` (eq. 14).

The truth is written here independently of the fit: the Denso's rigid body by Pinocchio plus Coulomb friction and, on
joint 3 only, the viscous power law ``fv |qd|^0.7 sign(qd)`` (linear viscous friction on the others), evaluated in numpy
on the exact states of a sine excitation, with white torque noise. The training motion is slow, the held-out one faster:
a linear viscous fit of joint 3 misses the faster motion, the power law predicts it.
"""

import dataclasses
import shutil

import casadi as ca
import numpy as np
import pytest

from identification.calibration.column_choice import ColumnRequest, choose_columns
from identification.calibration.trajectory_data import friction_term, prepare_recording, viscous_column
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories, predict_torque
from psdm_casadi.errors import ParameterError
from psdm_casadi.oracle import PinocchioOracle
from tests.identification.friction_signal import exact_recording

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
RATE, DURATION, NOISE, EPS = 200.0, 12.0, 0.05, 0.05
DV = np.array([1.0, 1.0, 0.7, 1.0, 1.0, 1.0])  # joint 3: a harmonic drive's sublinear viscous friction
FV = np.array([1.0, 1.0, 3.0, 0.5, 0.3, 0.2])


def _friction(qd):
    return 2.0 * np.tanh(qd / EPS) + FV * np.abs(qd) ** DV * np.sign(qd)


def _recording(robot, seed, fraction):
    return exact_recording(robot, seed, _friction, duration=DURATION, rate=RATE, noise=NOISE, name=f"viscous{seed}",
                           fraction=fraction)  # fmt: skip


@pytest.fixture(scope="module")
def viscous_data(denso, denso_model):
    """A slow training recording, a faster held-out one, and the column choice on the first."""
    train, held = _recording(denso, 31, 0.35), _recording(denso, 32, 0.8)
    choice = choose_columns(denso, denso_model, [train], request=ColumnRequest(drive_inertia="off", offset="off"))
    return train, held, choice


def test_a_sublinear_joint_gets_the_power_law_with_its_exponent_and_a_linear_one_does_not(viscous_data):
    train, held, choice = viscous_data
    speed = [np.abs(np.gradient(r.q[:, 2], r.t)).max() for r in (train, held)]
    assert speed[1] > 1.1 * speed[0], speed  # validated beyond the training speed
    found = {e.joint: e for e in choice.evidence if e.term == "viscous"}
    assert found[2].kept and found[2].std > 0, found[2]
    assert abs(found[2].estimate - DV[2]) < 3 * found[2].std, found[2]
    assert not any(e.kept for j, e in found.items() if j != 2), found  # the linear joints keep their linear column
    assert choice.viscous_exponent[2] == found[2].estimate
    assert all(dv == 1.0 for j, dv in enumerate(choice.viscous_exponent) if j != 2)
    assert choice.options(TrajectoryOptions()).viscous_exponent == choice.viscous_exponent
    assert f"joint 3: viscous friction ~ |qd|^{found[2].estimate:.2f}" in " ".join(choice.describe())
    assert choice.to_dict()["viscous_exponent"] == list(choice.viscous_exponent)


@pytest.mark.slow
def test_the_power_law_predicts_the_faster_held_out_motion(viscous_data, denso, denso_model):
    from identification.metrics import rmse

    train, held, choice = viscous_data
    power = choice.options(TrajectoryOptions())
    linear = dataclasses.replace(power, viscous_exponent=None)
    fits = {name: identify_trajectories(denso, denso_model, [train], options)
            for name, options in (("power", power), ("linear", linear))}  # fmt: skip
    assert fits["power"].viscous_exponent == choice.viscous_exponent and fits["linear"].viscous_exponent == ()
    ready, _, _ = prepare_recording(held, None)
    x = (ready.q, ready.qd, ready.qdd)
    errors = {name: np.asarray(rmse(ready.tau, predict_torque(denso_model, fit, *x))) for name, fit in fits.items()}
    assert errors["power"][2] < 0.5 * errors["linear"][2], errors
    assert np.all(errors["power"] < 1.1 * errors["linear"] + 0.01), errors  # no other joint worse


@pytest.mark.slow
@pytest.mark.needs_cc
@needs_cc
def test_the_model_file_exported_c_and_diagnosis_drives_predict_the_power_law_alike(
    viscous_data, denso, denso_model, tmp_path, monkeypatch
):
    from codegen.build import build_library
    from codegen.calibrated import build_calibrated_functions, header_note
    from codegen.export import export_c
    from identification.calibration.calibrated_model import CalibratedModel, friction_drives, load_calibrated_model
    from tests.conftest import DENSO_FILE

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    train, _, choice = viscous_data
    fit = identify_trajectories(denso, denso_model, [train], choice.options(TrajectoryOptions()))
    path = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE).save(tmp_path / "viscous.json")
    calibrated = load_calibrated_model(path)
    assert calibrated.document["drive"]["viscous_exponent"] == list(choice.viscous_exponent)
    library = build_library(export_c(build_calibrated_functions(calibrated, denso_model, denso), tmp_path / "c"),
                            flags=("-O1",))  # fmt: skip
    rng = np.random.default_rng(8)
    q = rng.uniform(denso.q_min, denso.q_max, (300, denso.n_dof))
    qd, qdd = rng.normal(scale=1.0, size=q.shape), rng.normal(size=q.shape)
    tau = np.array(library.function("psdm_inverse_dynamics").map(q.shape[0])(q.T, qd.T, qdd.T), dtype=float).T
    predicted = calibrated.predict(denso_model, q, qd, qdd)
    np.testing.assert_allclose(predicted, predict_torque(denso_model, fit, q, qd, qdd), rtol=1e-12)
    assert np.max(np.abs(tau - predicted).max(axis=0) / np.abs(predicted).max(axis=0)) < 1e-9
    # predict is the paper's power law beyond the smoothing velocity: the fitted values in an independent expression
    values = dict(zip(fit.drive_names, fit.drive))
    dv, v = np.array(choice.viscous_exponent), fit.coulomb_velocity
    fc, fv = (np.array([values[f"{n}{j + 1}"] for j in range(6)]) for n in ("fc", "fv"))
    friction = fc * np.tanh(qd / v) + fv * qd * (qd**2 + v**2) ** ((dv - 1) / 2)
    np.testing.assert_allclose(predicted, PinocchioOracle(denso, fit.standard).rnea(q, qd, qdd) + friction,
                               rtol=1e-9, atol=1e-9)  # fmt: skip
    assert "dv3 = " in header_note(calibrated)
    drives = friction_drives(calibrated, denso)  # the nominal of 'diagnose MODEL': the file's fv and dv
    assert [d.dv for d in drives] == list(choice.viscous_exponent) and drives[2].fv == pytest.approx(values["fv3"])


def test_the_viscous_column_is_one_definition_for_numbers_and_casadi_and_the_paper_s_law_beyond_smoothing():
    qd = np.linspace(-3.0, 3.0, 61)
    assert np.array_equal(viscous_column(qd, 1.0, EPS), qd)  # linear: the plain column
    column = friction_term("fv", qd, EPS, None, 0.7)
    fast = np.abs(qd) > 20 * EPS
    np.testing.assert_allclose(column[fast], np.abs(qd[fast]) ** 0.7 * np.sign(qd[fast]), rtol=2e-3)
    x = ca.SX.sym("x")
    symbolic = ca.Function("f", [x], [friction_term("fv", x, EPS, None, 0.7)])
    np.testing.assert_allclose(np.array([float(symbolic(v)) for v in qd]), column, rtol=1e-12, atol=1e-15)
    slope = ca.Function("g", [x], [ca.jacobian(friction_term("fv", x, EPS, None, 0.7), x)])
    assert np.isfinite(float(slope(0.0))) and float(slope(0.0)) == pytest.approx(EPS ** (0.7 - 1.0))


def test_friction_a_model_file_holds_is_predicted_with_the_files_viscous_exponent():
    """``diagnose MODEL`` holds the friction a model file's identify held (``HeldFriction.of_model_file``) and predicts
    it as the file does. Reference: the paper's law written here, ``fc tanh(qd / v) + fv qd (qd^2 + v^2)^((dv - 1) /
    2)`` with the file's values (what ``CalibratedModel.predict`` computes, ``test_the_model_file_exported_c_...``).
    Joint 3 holds a power law (dv 0.7), joint 1 a linear one; joint 2, not held, contributes nothing."""
    from identification.calibration.held_friction import HeldFriction

    dv, v = [1.0, 1.0, 0.7, 1.0, 1.0, 1.0], 0.03
    names = [f"{t}{j}" for t in ("fc", "fv") for j in range(1, 7)]
    document = {"identification": {"worse_joints": {"held_friction": {"fc1": 1.5, "fv1": 0.8, "fc3": 2.0, "fv3": 3.0}}},
                "drive": {"names": names, "values": [1.0] * 12, "coulomb_velocity": v, "viscous_exponent": dv},
                "standard": {"values": [0.0] * 66}}  # fmt: skip
    held = HeldFriction.of_model_file(document)
    assert held.joints == (0, 2) and held.viscous_exponent == tuple(dv)
    qd = np.random.default_rng(5).normal(scale=1.5, size=(200, 6))
    torque = held.torque(qd)
    np.testing.assert_allclose(torque[:, 0], 1.5 * np.tanh(qd[:, 0] / v) + 0.8 * qd[:, 0], rtol=1e-12)
    law = 2.0 * np.tanh(qd[:, 2] / v) + 3.0 * qd[:, 2] * (qd[:, 2] ** 2 + v**2) ** ((0.7 - 1.0) / 2)
    np.testing.assert_allclose(torque[:, 2], law, rtol=1e-12)
    assert np.all(torque[:, [1, 3, 4, 5]] == 0.0)
    x = ca.SX.sym("qd", 6)
    symbolic = ca.Function("held", [x], [held.expression(x)])
    np.testing.assert_allclose(np.array(symbolic(qd.T)).T, torque, rtol=1e-12, atol=1e-12)  # the exported form too
    linear = HeldFriction.of_model_file({**document, "drive": {**document["drive"], "viscous_exponent": None}})
    assert not np.allclose(linear.torque(qd)[:, 2], law, rtol=1e-3)  # a linear hold would not be the file's
    with pytest.raises(ParameterError, match="viscous_exponent must be positive"):
        HeldFriction((("fv3", 1.0),), 0.05, (1.0, 1.0, -0.7))


def test_a_joint_identify_holds_is_written_linear_and_the_others_keep_their_exponents():
    """``with_held_values``: a held joint's friction is the held Coulomb-viscous one (the robot file's fit), so the fit
    (and the model file) states exponent 1 for it; a joint not held keeps the exponent the column choice chose."""
    from identification.calibration.held_friction import with_held_values

    @dataclasses.dataclass(frozen=True)
    class Fit:  # the fields of a TrajectoryFit it reads
        drive: np.ndarray
        drive_ols: np.ndarray
        drive_names: tuple
        viscous_exponent: tuple

    names = ("fc1", "fc2", "fc3", "fv1", "fv2", "fv3")
    fit = Fit(np.ones(6), np.ones(6), names, (1.0, 0.8, 0.7))
    options = TrajectoryOptions(held_friction=(("fc3", 2.0), ("fv3", 3.0)))
    held = with_held_values(fit, options)
    assert held.viscous_exponent == (1.0, 0.8, 1.0)
    assert dict(zip(names, held.drive))["fv3"] == 3.0 and dict(zip(names, held.drive_ols))["fc3"] == 2.0
    only = with_held_values(Fit(np.ones(6), np.ones(6), names, (1.0, 1.0, 0.7)), options)
    assert only.viscous_exponent == ()  # every joint linear: no power law stated
