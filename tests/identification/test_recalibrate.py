"""The discovery loop: psdm diagnose MODEL --apply NEW re-identifies a calibrated model with its findings.

The end-to-end test hides a spring on joint 2 of the virtual Denso: the calibration without it puts the
spring into the gravity parameters; the diagnosis of the calibrated model finds it, and the recalibration
with it gives gravity torques close to the truth (Pinocchio on the robot file's inertia, which the
simulation used). The other tests check the consistency gate's message, the command line's refusals and
that a rotor inertia a URDF-like model has no base parameter for stays in the diagnosis' saved function.
"""

import dataclasses
import json
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, calibrated_robot, load_calibrated_model
from identification.calibration.findings import correct_recording
from identification.calibration.recalibrate import consistency_failure
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.recording import Recording
from identification.diagnosis.augmented import AugmentedModel
from identification.diagnosis.candidates import RotorInertiaTerm
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from identification.virtual.transmission_effects import Backlash, JointElasticity
from psdm_casadi.cli import main
from psdm_casadi.derive import derive_psdm
from psdm_casadi.oracle import PinocchioOracle
from tests.conftest import DENSO_FILE
from tests.identification.diagnosis_data import SPRING_K, SPRING_Q0, hidden_spring_files
from trajopt.experiments import sine_experiment


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def test_consistency_failure_names_the_eigenvalue_and_the_links_parameters():
    standard = np.tile([1.0, 0, 0, 0, 0.1, 0, 0.1, 0, 0, 0.1, 0.0], (2, 1))
    standard[1, 4] = -0.3  # link 2: a negative moment of inertia
    document = {"robot": {"joint_names": ["a", "b"]},
                "standard": {"values": standard.ravel().tolist(), "consistent": False, "checked": True,
                             "min_pseudo_inertia_eigenvalue": -0.2}}  # fmt: skip
    message = consistency_failure(SimpleNamespace(after=CalibratedModel(document), min_mass_eigenvalue=-0.1))
    assert "smallest pseudo-inertia eigenvalue -0.2" in message and "mass-matrix eigenvalue -0.1" in message
    assert "link 2 (m2, mx2" in message and "link 1" not in message
    document["standard"].update(consistent=True, min_pseudo_inertia_eigenvalue=0.01)
    document["standard"]["values"] = np.tile(standard[0], 2).tolist()
    assert consistency_failure(SimpleNamespace(after=CalibratedModel(document), min_mass_eigenvalue=0.5)) is None


@pytest.mark.parametrize(
    "effect, correction",
    [
        (xp.SignalDelay(samples=7), {"delay": {"effect": "delay", "delay_s": 7e-3}}),
        (JointElasticity(joint=1, stiffness=400.0),
         {"joint_elasticity[j2]": {"effect": "joint_elasticity", "joint": 2, "compliance_rad_per_Nm": 1 / 400.0}}),
        (Backlash(joint=2, width=0.01, torque_scale=0.3),
         {"backlash[j3]": {"effect": "backlash", "joint": 3, "backlash_rad": 0.01, "torque_scale_Nm": 0.3}}),
    ],
)  # fmt: skip
def test_measurement_corrections_undo_what_the_virtual_robot_measures(effect, correction):
    t = np.arange(0.0, 2.0, 1e-3)
    q = np.column_stack([np.sin(2 * t + k) for k in range(3)])
    tau = np.column_stack([5 * np.cos(3 * t + k) for k in range(3)])
    q_rec, tau_rec = effect.measure(t, q, tau)
    corrected = correct_recording(Recording(t=t, q=q_rec, tau=tau_rec), correction)
    inside = slice(0, t.size - 10)  # a delay holds the last recorded samples
    np.testing.assert_allclose(corrected.q[inside], q[inside], atol=1e-12)
    np.testing.assert_allclose(corrected.tau[inside], tau[inside], atol=1e-9)
    assert not np.allclose(q_rec, q) or not np.allclose(tau_rec, tau)  # the effect was there to undo


def test_a_joint_without_torque_keeps_its_recorded_position_under_an_elasticity_correction():
    """A recording whose joint 1 torque is missing (a dead channel, NaN; the Kinova Gen3 log RunTrajectory1 has one):
    the elasticity correction of joint 1 cannot be made there, so q1 stays as recorded (diagnose --apply failed with
    'Recording.q must be finite' before); joint 2's correction is still the virtual robot's truth, and the recording
    still names the missing torque."""
    t = np.arange(0.0, 2.0, 1e-3)
    q = np.column_stack([np.sin(2 * t + k) for k in range(2)])
    tau = np.column_stack([5 * np.cos(3 * t + k) for k in range(2)])
    q_rec, tau_rec = JointElasticity(joint=1, stiffness=400.0).measure(t, q, tau)
    tau_rec = tau_rec.copy()
    tau_rec[:, 0] = np.nan
    recording = Recording(t=t, q=q_rec, tau=tau_rec, missing_torque=((0, "dead channel"),))
    corrections = {
        f"joint_elasticity[j{j}]": {"effect": "joint_elasticity", "joint": j, "compliance_rad_per_Nm": 1 / 400.0}
        for j in (1, 2)
    }
    corrected = correct_recording(recording, corrections)
    np.testing.assert_array_equal(corrected.q[:, 0], q_rec[:, 0])
    np.testing.assert_allclose(corrected.q[:, 1], q[:, 1], atol=1e-12)
    assert corrected.missing_torque == ((0, "dead channel"),)


def test_apply_needs_a_calibrated_model_and_a_model_brings_its_locks(capsys, tmp_path):
    argv = ["--train", "a.csv", "--validate", "b.csv"]
    assert main(["diagnose", str(DENSO_FILE), *argv, "--apply", str(tmp_path / "new.json")]) == 2
    assert "diagnose --apply needs a calibrated model" in capsys.readouterr().err
    assert main(["diagnose", str(tmp_path / "model.json"), *argv, "--lock", "J6"]) == 2
    assert "Drop --lock" in capsys.readouterr().err
    assert main(["diagnose", str(tmp_path / "missing.json"), *argv]) == 2
    assert "missing.json" in capsys.readouterr().err and not (tmp_path / "new.json").exists()


def test_a_rotor_inertia_outside_the_base_parameters_stays_in_the_saved_function(denso, rng):
    """A robot without drive inertias in its model (as a URDF robot): the term is a torque, not a theta change."""
    robot = dataclasses.replace(denso, drive_inertia=(False,) * denso.n_dof)
    model = derive_psdm(robot)
    assert not np.any(model.parameter_map[:, 10::11])
    term, inertia = RotorInertiaTerm(joint=2), 0.3
    common = dict(model=model, theta=model.base_parameters(robot.nominal_dynamic_parameters()),
                  friction_kind="coulomb_viscous", friction_coefficients=np.zeros(2 * robot.n_dof),
                  friction_vs=np.full(robot.n_dof, 0.05), friction_dv=np.ones(robot.n_dof))  # fmt: skip
    with_term = AugmentedModel(terms=(term,), coefficients=(np.array([inertia]),), **common)
    without = AugmentedModel(terms=(), coefficients=(), **common)
    assert with_term.signal_corrections == {}
    q, qd, qdd = rng.uniform(-1, 1, (3, robot.n_dof))
    function = with_term.build_function()
    assert isinstance(function, ca.Function)
    difference = np.array(function(q, qd, qdd, 0.0) - without.build_function()(q, qd, qdd, 0.0))
    np.testing.assert_allclose(difference.ravel(), inertia * qdd * (np.arange(robot.n_dof) == 2), atol=1e-12)


def test_an_offset_chosen_from_the_data_is_left_to_a_found_spring_s_constant():
    """The two are one column: the spring's constant (its rest angle) takes a joint's offset chosen from the data,
    of a linear spring and of a polynomial alike; an offset asked for (``offset_joints`` None) and an offset on a
    joint without a constant finding stay."""
    from identification.calibration.findings import FindingTerm, offsets_left_to_findings
    from identification.diagnosis.candidates import SpringTerm

    chosen = TrajectoryOptions(friction=("fc", "fv", "offset"), offset_joints=(0, 1, 2))
    ripple = FindingTerm("torque_ripple", 2, harmonic=1)
    cubic = FindingTerm("spring", 0, spec=SpringTerm(joint=0, order=3).spec())
    assert offsets_left_to_findings(chosen, [FindingTerm("spring", 1), ripple, cubic]).offset_joints == (2,)
    assert offsets_left_to_findings(chosen, [ripple]) is chosen
    asked = dataclasses.replace(chosen, offset_joints=None)
    assert offsets_left_to_findings(asked, [FindingTerm("spring", 1)]) is asked


def test_an_offset_held_at_zero_absorbs_no_spring_constant(denso, denso_model):
    """``recalibrate``'s absorbed features (``absorbed_features.absorbed_mask``) are judged against the columns the
    fit frees: a spring's constant on a joint whose offset is held at 0 (outside ``offset_joints``) stays in the fit
    (it is the only column to carry the spring's ``-k q0``), beside a chosen offset on that joint it is absorbed; its
    ``k`` stays either way."""
    from identification.calibration.absorbed_features import absorbed_mask
    from identification.calibration.findings import FindingColumns, FindingTerm

    rng = np.random.default_rng(5)
    reference = sine_experiment(denso, duration=3.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=200.0)
    recording, _ = simulate_recording(denso, reference, options, rng)
    columns = FindingColumns((FindingTerm("spring", 1),))
    for offset_joints, keep in (((2,), (True, True)), ((1, 2), (True, False)), (None, (True, False))):
        fit_options = TrajectoryOptions(friction=("fc", "fv", "offset"), offset_joints=offset_joints)
        assert absorbed_mask(denso, denso_model, [recording], fit_options, columns) == keep, offset_joints


@pytest.fixture(scope="module")
def spring_loop(tmp_path_factory, denso, denso_model):
    """A training and a validation recording with a hidden spring, and the model identified without it."""
    return hidden_spring_files(tmp_path_factory.mktemp("loop"), denso, denso_model, DENSO_FILE, 10.0, 500.0)


def _gravity_error(calibrated, denso, denso_model, rng) -> np.ndarray:
    """RMS over random configurations of the model's gravity torque minus the truth's (Pinocchio), per joint."""
    q = rng.uniform(denso.q_min, denso.q_max, (300, denso.n_dof))
    zero = np.zeros_like(q)
    error = denso_model.inverse_dynamics(q, zero, zero, calibrated.theta) - PinocchioOracle(denso).rnea(q, zero, zero)
    return np.sqrt(np.mean(error**2, axis=0))


@pytest.mark.slow
def test_diagnose_apply_finds_the_spring_and_restores_the_rigid_body(spring_loop, denso, denso_model, capsys, rng):
    folder = spring_loop
    argv = ["diagnose", str(folder / "model.json"), "--train", str(folder / "train.csv"), "--validate",
            str(folder / "valid.csv"), "--apply", str(folder / "new.json")]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "## Recalibration with the findings" in out and "validation RMSE after" in out
    assert "validation RMSE [N m] without -> with it (its torque taken out, not refitted): joint 2:" in out
    before, after = load_calibrated_model(folder / "model.json"), load_calibrated_model(folder / "new.json")
    assert after.document["version"] == 2 and before.document["findings"] == []
    spring = next(e for e in after.document["findings"] if e["label"] == "spring[j2]")
    assert spring["parameters"]["k"] == pytest.approx(SPRING_K, abs=3 * spring["std"][0] + 0.05 * SPRING_K)
    # the spring was in the gravity parameters of joint 2; with it modelled, they are right again
    error_before = _gravity_error(before, denso, denso_model, rng)[1]
    error_after = _gravity_error(after, denso, denso_model, rng)[1]
    assert error_after < 0.25 * error_before, (error_before, error_after)
    block = after.document["recalibration"]
    assert block["after"]["validation_rmse"][1] < 0.5 * block["before"]["validation_rmse"][1]
    assert any(m["name"].startswith("theta") for m in block["moved_parameters"])
    assert main(["validate", str(folder / "new.json"), str(folder / "valid.csv"), "--json"]) == 0
    validated = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    np.testing.assert_allclose(validated, after.document["validation"]["recordings"][0]["rmse"], rtol=1e-12)
    assert main(argv) == 2  # the new model is not overwritten without --overwrite
    assert "--overwrite" in capsys.readouterr().err


def test_the_nominal_robot_of_a_calibrated_model_is_its_identified_rigid_body(spring_loop, denso, denso_model, rng):
    """``psdm diagnose MODEL`` starts from the file's inertia: Pinocchio on it gives the model's rigid-body torque."""
    calibrated = load_calibrated_model(spring_loop / "model.json")
    nominal = calibrated_robot(calibrated, calibrated.load_robot())
    q, qd, qdd = rng.uniform(-1.5, 1.5, (3, 50, denso.n_dof))
    expected = denso_model.inverse_dynamics(q, qd, qdd, calibrated.theta)
    np.testing.assert_allclose(PinocchioOracle(nominal).rnea(q, qd, qdd), expected, atol=1e-9 * np.abs(expected).max())
    prior = PinocchioOracle(denso).rnea(q, qd, qdd)
    assert np.abs(prior - expected).max() > 1.0  # the spring moved the identified inertia away from the robot file


@pytest.mark.slow
def test_diagnose_apply_keeps_the_drive_columns_the_model_was_identified_with(spring_loop, denso, denso_model, capsys):
    """A model whose offsets were chosen per joint (``column_choice``) is refitted with the same columns, but for the
    chosen offset of joint 2, which the spring found there takes as its constant (``findings.offsets_left_to_findings``;
    the virtual robot has no offset and the spring's rest angle is SPRING_Q0). Kept beside the spring, the offset had
    held -7.99 N m (-k q0) and the spring read q0 = 0; the validation RMSE is the same to 4 digits either way."""
    from identification.calibration.column_choice import ColumnChoice, ColumnRequest
    from identification.data.io import load_recording

    folder = spring_loop
    options = TrajectoryOptions(friction=("fc", "fv", "offset"), offset_joints=(1,))
    fit = identify_trajectories(denso, denso_model, [load_recording(folder / "train.csv", denso.n_dof)], options)
    chosen = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    choice = ColumnChoice("coulomb-viscous", (1,), (), ColumnRequest())
    chosen.document["identification"]["column_choice"] = choice.to_dict()
    chosen.save(folder / "chosen.json")
    argv = ["diagnose", str(folder / "chosen.json"), "--train", str(folder / "train.csv"), "--validate",
            str(folder / "valid.csv"), "--apply", str(folder / "chosen_new.json")]  # fmt: skip
    assert main(argv) == 0
    capsys.readouterr()
    after = json.loads((folder / "chosen_new.json").read_text())
    offsets = {n: v for n, v in zip(after["drive"]["names"], after["drive"]["values"]) if n.startswith("offset")}
    assert set(offsets.values()) == {0.0}  # held at 0 as the choice said; joint 2's left to the spring's constant
    assert after["identification"]["column_choice"]["offset_joints"] == [2]  # the choice itself is carried
    spring = next(e for e in after["findings"] if e["label"] == "spring[j2]")
    assert abs(spring["parameters"]["q0"] - SPRING_Q0) < 0.02, spring


@pytest.mark.slow
def test_diagnose_apply_keeps_the_friction_identify_held(spring_loop, denso, denso_model, capsys):
    """A model whose joint-4 friction identify held to the robot file's fit (``one_way_friction``: a joint that moved
    one way only) is refitted with it held at the same values, as the file states it; the spring is found as before."""
    from identification.data.io import load_recording

    folder = spring_loop
    train = [load_recording(folder / "train.csv", denso.n_dof)]
    free = identify_trajectories(denso, denso_model, train, TrajectoryOptions())
    held = tuple((name, float(free.drive[free.drive_names.index(name)]) + 0.1) for name in ("fc4", "fv4"))
    fit = identify_trajectories(denso, denso_model, train, TrajectoryOptions(held_friction=held))
    model = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    model.document["identification"]["one_way_friction"] = {"held": dict(held), "held_joints": [4]}
    model.save(folder / "held.json")
    argv = ["diagnose", str(folder / "held.json"), "--train", str(folder / "train.csv"), "--validate",
            str(folder / "valid.csv"), "--apply", str(folder / "held_new.json")]  # fmt: skip
    assert main(argv) == 0
    capsys.readouterr()
    after = json.loads((folder / "held_new.json").read_text())
    values = dict(zip(after["drive"]["names"], after["drive"]["values"]))
    assert {name: values[name] for name, _ in held} == dict(held)  # not fitted again
    assert after["identification"]["one_way_friction"]["held"] == dict(held)
    assert any(e["label"] == "spring[j2]" for e in after["findings"])


@pytest.mark.slow
def test_diagnose_reads_a_vendor_log_as_identify_did_and_apply_keeps_how(spring_loop, tmp_path, capsys):
    """A model identified from a controller's log with ``--columns`` (``provenance.columns``): diagnose reads the
    logs the same way without the option and says so, and the model ``--apply`` writes keeps how (validate reads
    with it next)."""
    folder = spring_loop
    for name in ("train.csv", "valid.csv"):
        lines = [line for line in (folder / name).read_text().splitlines() if not line.startswith("#")]
        renamed = {"t": "Time", **{f"q{j}": f"Position{j}" for j in range(1, 7)},
                   **{f"tau{j}": f"TorqueSm{j}" for j in range(1, 7)}}  # fmt: skip
        header = ",".join(renamed.get(name, name) for name in lines[0].split(","))
        (tmp_path / name).write_text("\n".join([header, *lines[1:]]) + "\n")
    document = json.loads((folder / "model.json").read_text())
    document["provenance"]["columns"] = {"columns": "t=Time,q=Position,tau=TorqueSm", "rate": None}
    (tmp_path / "model.json").write_text(json.dumps(document))
    argv = ["diagnose", str(tmp_path / "model.json"), "--train", str(tmp_path / "train.csv"), "--validate",
            str(tmp_path / "valid.csv"), "--apply", str(tmp_path / "new.json")]  # fmt: skip
    assert main(argv) == 0
    assert "read as identify read the model's (--columns t=Time,q=Position,tau=TorqueSm" in capsys.readouterr().err
    after = json.loads((tmp_path / "new.json").read_text())
    assert after["provenance"]["columns"] == document["provenance"]["columns"]


@pytest.mark.slow
def test_diagnose_apply_keeps_the_model_s_payload_configurations(spring_loop, tmp_path, capsys):
    """A model identified with payload configurations (a known load, an unknown one it weighed) keeps them through
    ``--apply``: the refit on the diagnosis' recordings does not drop what the file knows of its loads."""
    from identification.calibration.payload_fit import IdentifiedPayload, configurations_block
    from identification.data.configuration import PayloadConfiguration
    from identification.data.payload import Payload

    tool = Payload(mass=0.8, com=(0.03, 0.0, 0.06))
    weighed = IdentifiedPayload("tool", ("tool.csv",), 0.8, 0.02, tool.com, (0.003, 0.003, 0.008),
                                tuple(tool.dynamic_parameters()), True)  # fmt: skip
    configurations = [PayloadConfiguration("mass", payload=Payload(mass=0.6, com=(0.0, 0.02, 0.04)), stated=True),
                      PayloadConfiguration("tool", unknown=True, stated=True)]  # fmt: skip
    document = json.loads((spring_loop / "model.json").read_text())
    document["configurations"] = configurations_block(configurations, ["mass.csv", "tool.csv"], (weighed,))
    (tmp_path / "model.json").write_text(json.dumps(document))
    argv = ["diagnose", str(tmp_path / "model.json"), "--train", str(spring_loop / "train.csv"), "--validate",
            str(spring_loop / "valid.csv"), "--apply", str(tmp_path / "new.json")]  # fmt: skip
    assert main(argv) == 0
    written = load_calibrated_model(tmp_path / "new.json")
    assert written.configurations == document["configurations"]
    assert any(e["label"] == "spring[j2]" for e in written.document["findings"])
