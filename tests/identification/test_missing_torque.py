"""A recording's joint without a torque measurement (a dead sensor channel) leaves only that joint's rows out.

The Kinova Gen3's RunTrajectory1 has TorqueSm1 zero throughout while joints 2-7 are measured. Checked on the
virtual Denso: the normal equations of a recording with joint 1 missing are those of the full recording for
joints 2-6 and nothing for joint 1 (built from the full recordings, joint by joint); the fit does not depend on
the dead column's values (zero, found by itself; or noise, stated by the user); the output names the joint, the
recording and why; the validation leaves that joint of that recording out.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.trajectory_data import (
    NormalEquations,
    drive_columns,
    prepare_recording,
    prepare_recordings,
)
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.data.missing_torque import find_missing_torque, parse_missing_torque, stated_missing_torque
from identification.data.recording import Recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.errors import ParameterError, RecordingError
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

OPTIONS = TrajectoryOptions(friction=("fc", "fv"), offset_joints=(), drive_inertia="off")


def _recording(robot, seed, name):
    rng = np.random.default_rng(seed)
    reference = sine_experiment(robot, duration=6.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    recording, _ = simulate_recording(robot, reference, options, rng)
    return Recording(t=recording.t, q=recording.q, tau=recording.tau, name=name)


@pytest.fixture(scope="module")
def recordings(denso):
    return _recording(denso, 1, "a.csv"), _recording(denso, 2, "b.csv")


def _dead(recording, joint, values):
    tau = np.array(recording.tau)
    tau[:, joint] = values
    return Recording(t=recording.t, q=recording.q, tau=tau, name=recording.name)


def _equations(model, recording):
    ready = prepare_recording(recording)[0]
    columns = np.concatenate([model.regressor(ready.q, ready.qd, ready.qdd),
                              drive_columns(ready.qd, ready.qdd, ("fc", "fv"), [], 0.01)], axis=2)  # fmt: skip
    equations = NormalEquations(ready.n_dof, columns.shape[2])
    equations.add(columns, ready.tau)
    return equations


def test_a_zero_column_is_found_and_only_its_joints_rows_are_left_out(denso, denso_model, recordings):
    a, b = recordings
    dead = find_missing_torque(_dead(b, 0, 0.0))
    assert dead.missing_torque == ((0, "zero in every sample"),) and np.all(np.isnan(dead.tau[:, 0]))
    full, without = _equations(denso_model, b), _equations(denso_model, dead)
    assert without.count[0] == 0 and np.all(without.count[1:] == full.count[1:])
    np.testing.assert_array_equal(without.gram[0], 0.0)
    np.testing.assert_allclose(without.gram[1:], full.gram[1:], rtol=1e-12)
    np.testing.assert_allclose(without.moment[1:], full.moment[1:], rtol=1e-12)


def test_the_fit_does_not_depend_on_the_dead_columns_values_and_names_it(denso, denso_model, recordings):
    a, b = recordings
    found = identify_trajectories(denso, denso_model, [a, _dead(b, 0, 0.0)], OPTIONS)
    noise = np.random.default_rng(0).normal(0, 50.0, b.n_samples)  # a broken sensor the user names
    stated = Recording(t=b.t, q=b.q, tau=_dead(b, 0, noise).tau, name="b.csv", missing_torque=((0, "stated"),))
    named = identify_trajectories(denso, denso_model, [a, stated], OPTIONS)
    np.testing.assert_allclose(found.theta_ols, named.theta_ols, rtol=1e-9, atol=1e-12)
    # the samples stated are the fit's (both recordings'), not the dead joint's rows (the Kinova said "461 samples"
    # with RunTrajectory1 added, for 611: joint 1's count)
    _, _, prepared = prepare_recordings(denso, [a, b], None, OPTIONS.cutoff_hz, OPTIONS.edge_periods)
    assert found.n_samples == sum(r.n_samples for r in prepared)
    np.testing.assert_allclose(found.theta, named.theta, rtol=1e-6, atol=1e-8)
    assert found.sigma[0] == pytest.approx(named.sigma[0], rel=1e-9)
    assert any(w.startswith("b.csv: joint 1 (J1) has no torque measurement (zero in every sample)") and
               "left out of the fit" in w for w in found.warnings)  # fmt: skip
    # the zero column fitted as data (a hair of noise keeps it from being found) pulls joint 1's parameters
    unchecked = replace(OPTIONS, consistency=False)
    poisoned = identify_trajectories(denso, denso_model, [a, _dead(b, 0, 1e-9 * noise)], unchecked)
    truth = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    assert np.linalg.norm(found.theta_ols - truth) < 0.5 * np.linalg.norm(poisoned.theta_ols - truth)
    with pytest.raises(RecordingError, match=r"b\.csv: no joint's torque is measured"):
        find_missing_torque(Recording(t=b.t, q=b.q, tau=0 * b.tau, name="b.csv"))


def test_identify_names_the_dead_joint_and_leaves_it_out_of_the_validation(denso, recordings, tmp_path, capsys):
    a, b = recordings
    save_recording(a, tmp_path / "full.csv")
    save_recording(_dead(b, 0, 0.0), tmp_path / "train.csv")
    save_recording(_dead(_recording(denso, 3, "c"), 1, 0.0), tmp_path / "check.csv")
    argv = ["identify", str(DENSO_FILE), "--data", str(tmp_path / "full.csv"), str(tmp_path / "train.csv"),
            "--validate", str(tmp_path / "check.csv"), "--out", str(tmp_path / "m.json"), "--json"]  # fmt: skip
    assert main(argv) == 0
    payload = json.loads(capsys.readouterr().out)
    warnings = payload["warnings"]
    assert any(
        w.startswith("train.csv: joint 1 (J1) has no torque measurement (zero in every sample)") for w in warnings
    )
    assert any(w.startswith("check.csv: joint 2 (J2)") and "left out of the validation" in w for w in warnings)
    rmse = payload["validation"][0]["rmse"]
    assert rmse[1] is None and all(v is not None and v > 0 for v in rmse[:1] + rmse[2:])  # joint 2: no rows
    assert main([*argv[:-1], "--overwrite", "--missing-torque", "nowhere.csv:1"]) == 2
    assert "--missing-torque names ['nowhere.csv']" in capsys.readouterr().err
    assert main(["validate", str(tmp_path / "m.json"), str(tmp_path / "check.csv"), "--json"]) == 0
    captured = capsys.readouterr()
    (row,) = json.loads(captured.out)["recordings"]
    assert row["rmse"][1] is None and row["r2"][1] is None and row["rmse"][0] == pytest.approx(rmse[0], rel=1e-6)
    assert "check.csv: joint 2 (J2) has no torque measurement (zero in every sample)" in captured.err
    assert main(["validate", str(tmp_path / "m.json"), str(tmp_path / "check.csv")]) == 0
    assert re.search(r"\n  J2 +- +-\n", capsys.readouterr().out)  # the table: no number for joint 2
    diagnose = ["diagnose", str(tmp_path / "m.json"), "--train", str(tmp_path / "full.csv"), "--validate",
                str(tmp_path / "check.csv"), "--no-sparse", "--rigid-body", "prior", "--max-effects", "1",
                "--json"]  # fmt: skip
    assert main(diagnose) == 0  # joint 2 left out, the others diagnosed
    captured = capsys.readouterr()
    assert "check.csv: joint 2 (J2) has no torque measurement (zero in every sample)" in captured.err
    assert "left out of the diagnosis" in captured.err and json.loads(captured.out)["left_out"]


def test_the_option_names_joints_by_number_or_name(recordings):
    a, _ = recordings
    stated = parse_missing_torque(["runs/a.csv:1,J3", "b.csv:6"], ("J1", "J2", "J3", "J4", "J5", "J6"))
    assert stated == {"a.csv": {0, 2}, "b.csv": {5}}
    marked = stated_missing_torque(a, "elsewhere/a.csv", stated)
    assert [j for j, _ in marked.missing_torque] == [0, 2] and np.all(np.isnan(marked.tau[:, [0, 2]]))
    assert marked.missing_torque[0][1] == "stated by --missing-torque" and np.all(np.isfinite(marked.tau[:, 1]))
    for bad, message in (("a.csv", "takes FILE:JOINTS"), ("a.csv:7", "'7' is not a joint"), ("a.csv:J9", "'J9'")):
        with pytest.raises(ParameterError, match=message):
            parse_missing_torque([bad], ("J1", "J2", "J3", "J4", "J5", "J6"))


def test_diagnose_leaves_a_dead_joint_out_and_diagnoses_the_others(denso, denso_model):
    """Joint 3's torque is zero throughout the training recording and NaN throughout the validation recording: the
    diagnosis leaves joint 3 out of both (no term on it, not judged on it), says so, and still finds the spring hidden
    on joint 2, as on the recordings with every joint measured."""
    from identification.diagnosis import DiagnosisOptions, SpringTerm, TorqueOffsetTerm, diagnose
    from identification.virtual import effects as xp
    from tests.identification.diagnosis_data import recording_pair

    train, valid = recording_pair(denso, [xp.Spring(joint=1, stiffness=40.0, q0=0.2)], seed=7)
    options = DiagnosisOptions(library=SpringTerm() + TorqueOffsetTerm(), rigid_body="prior", sparse=False)
    full = diagnose(denso, train, valid, options, model=denso_model)
    dead_train = replace(train, tau=np.where(np.arange(6) == 2, 0.0, train.tau), name="train.csv")
    dead_valid = replace(valid, tau=np.where(np.arange(6) == 2, np.nan, valid.tau), name="valid.csv")
    report = diagnose(denso, dead_train, dead_valid, options, model=denso_model)
    assert [f.label for f in full.findings][:1] == [f.label for f in report.findings][:1] == ["spring[j2]"]
    assert all(2 not in f.joints for f in report.findings)
    ours, theirs = report.findings[0].parameters["k"], full.findings[0].parameters["k"]
    assert ours == pytest.approx(theirs, rel=0.05) and ours == pytest.approx(40.0, rel=0.1)
    assert len(report.left_out) == 2 and all("joint 3 (J3) has no torque measurement" in s for s in report.left_out)
    assert "train.csv" in report.left_out[0] and "zero in every sample" in report.left_out[0]
    assert "Not diagnosed (no torque measurement)" in report.to_markdown()
    assert np.isnan(report.rmse_after[2]) and np.all(np.isfinite(np.delete(report.rmse_after, 2)))  # no number: j3
    assert report.to_dict()["rmse_after"][2] is None
