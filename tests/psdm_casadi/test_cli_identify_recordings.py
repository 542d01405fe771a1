"""``psdm identify`` on exciting recordings, ``psdm validate`` on its file: the everyday route end to end."""

import json
import re

import numpy as np
import pytest

from identification.calibration.calibrated_model import load_calibrated_model
from identification.data.io import save_recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.errors import ModelFileError
from trajopt.experiments import sine_experiment


@pytest.fixture(scope="module")
def recordings(tmp_path_factory, denso):
    folder = tmp_path_factory.mktemp("recordings")
    for k, name in enumerate(("train.csv", "valid.csv")):
        rng = np.random.default_rng(10 + k)
        reference = sine_experiment(denso, duration=12.0, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
        recording, _ = simulate_recording(denso, reference, options, rng)
        save_recording(recording, folder / name)
    return folder


def test_identify_writes_a_consistent_model_that_validate_reproduces(recordings, tmp_path, capsys):
    out = tmp_path / "model.json"
    argv = ["identify", "denso_vs6556g", "--data", str(recordings / "train.csv")]
    assert main([*argv, "--validate", str(recordings / "valid.csv"), "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["consistent"] and summary["min_mass_eigenvalue"] > 0 and summary["min_pseudo_inertia_eigenvalue"] > 0
    assert summary["cutoff_hz"] == [10.0] and set(summary["drive"]) >= {"fc1", "fv6"}
    reported = summary["validation"][0]
    assert min(reported["r2"]) > 0.98
    # the model identify replaces, per joint the file with its friction fitted or the file alone (robot_file_check)
    check = summary["robot_file_check"]
    assert reported["rmse_robot_file_baseline"] == pytest.approx(check["validation_rmse_before"], rel=1e-9)
    for j, baseline in enumerate(check["baselines"]):
        if baseline == "alone":
            assert reported["rmse_robot_file_baseline"][j] == pytest.approx(reported["rmse_prior"][j], rel=1e-9)
    assert "rmse_prior_friction" not in reported  # named for what it holds since the baseline may be the file alone
    assert main(["validate", str(out), str(recordings / "valid.csv"), "--json"]) == 0
    validated = json.loads(capsys.readouterr().out)["recordings"][0]
    np.testing.assert_allclose(
        validated["rmse"], reported["rmse"], rtol=1e-9
    )  # what the report claims, the file computes
    assert main([*argv, "--out", str(out)]) == 2  # an existing model is not replaced without --overwrite
    assert "--overwrite" in capsys.readouterr().err


def test_without_consistency_the_file_says_it_was_not_checked(recordings, tmp_path, capsys):
    out = tmp_path / "model.json"
    # the friction shape stated: the default's LuGre trial (the virtual Denso's friction is LuGre) is most of the run
    argv = ["identify", "denso_vs6556g", "--data", str(recordings / "train.csv"), "--out", str(out), "--no-consistency",
            "--friction", "coulomb-viscous"]  # fmt: skip
    assert main([*argv, "--validate", str(recordings / "valid.csv")]) == 0
    text, err = capsys.readouterr()
    assert "NOT checked" in err and "smallest mass-matrix eigenvalue not checked)" in text
    assert re.search(r"\(RMSE \[N m\] per joint; R\^2\):\n  joint +1 +2 +3 +4 +5 +6\n  identified ", text), text
    document = json.loads(out.read_text())
    assert document["standard"]["consistent"] is False and document["standard"]["checked"] is False
    assert main(["validate", str(out), str(recordings / "valid.csv")]) == 0
    assert "NOT physically consistent" in capsys.readouterr().out


def test_a_folder_and_files_pick_their_protocol_or_say_which_to_pass(recordings, tmp_path, capsys):
    argv = ["identify", "denso_vs6556g", "--out", str(tmp_path / "m.json")]
    assert main([*argv, "--data", str(recordings), "--protocol", "recordings"]) == 2
    assert "--protocol four-step" in capsys.readouterr().err
    assert main([*argv, "--data", str(recordings / "train.csv"), "--protocol", "four-step"]) == 2
    assert "one --data folder" in capsys.readouterr().err
    # a folder of a robot's logs that is not the paper's experiments (the Panda's one-number-per-line .txt files):
    # named with what it holds and what to pass, before any derivation, not asked for a calibration payload
    logs = tmp_path / "logs"
    logs.mkdir()
    for name in ("exciting_traj_positions.txt", "exciting_traj_torques.txt"):
        (logs / name).write_text("0.1\n0.2\n")
    assert main([*argv, "--data", str(logs)]) == 2
    err = capsys.readouterr().err
    assert "not one of the paper's calibration experiments" in err and "exciting_traj_torques.txt" in err, err
    assert "--data run1.csv" in err and "[recording]" in err and "payload.json is missing" not in err
    assert "deriving" not in err and "Traceback" not in err
    assert main([*argv, "--data", str(logs / "exciting_traj_torques.txt")]) == 2
    err = capsys.readouterr().err
    assert "exciting_traj_torques.txt" in err and "convert it to a CSV with the columns t, q1..qn" in err, err
    assert not (tmp_path / "m.json").exists()


def test_a_recording_with_a_still_joint_is_refused_naming_it(recordings, tmp_path, capsys):
    from identification.data.io import load_recording

    recording = load_recording(recordings / "train.csv")
    q = recording.q.copy()
    q[:, 2] = q[0, 2]  # joint 3 held still
    save_recording(recording.with_signals(q=q), tmp_path / "still.csv")
    out = tmp_path / "m.json"
    assert main(["identify", "denso_vs6556g", "--data", str(tmp_path / "still.csv"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "still.csv" in err and "J3" in err and "psdm excite" in err and not out.exists()


def test_sigma_percent_is_relative_to_the_printed_estimate(recordings, tmp_path, capsys):
    from psdm_casadi.cli.identify_text import sigma_percent, sigma_percent_cell

    np.testing.assert_allclose(sigma_percent([-2.0, 0.5, 0.0], [0.5, 0.01, 1.0]), [25.0, 2.0, np.inf])
    assert float(sigma_percent_cell(25.0)) == 25.0 and float(sigma_percent_cell(100.0)) == 100.0
    for beyond in (100.5, 293901.0, np.inf):  # an estimate near zero: no relative figure, the absolute sigma is read
        assert "not identifiable" in sigma_percent_cell(beyond) and "293901" not in sigma_percent_cell(beyond)
    out = tmp_path / "model.json"
    assert main(["identify", "denso_vs6556g", "--data", str(recordings / "train.csv"), "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    # the meaning is said once below the table, not on each such row (the Kinova's 35 rows each carried it)
    assert sum("read its absolute sigma" in line for line in lines) == 1
    assert not [line for line in lines if "not identifiable" in line and "read" in line and line.startswith("theta")]
    start = next(k for k, line in enumerate(lines) if line.startswith("parameter ")) + 1
    rows = [line.split() for line in lines[start:] if line.startswith(("theta", "fc", "fv"))]
    document = json.loads(out.read_text())
    estimates = dict(zip(document["base"]["names"] + document["drive"]["names"],
                         document["base"]["values"] + document["drive"]["values"]))  # fmt: skip
    assert len(rows) > 30
    assert any(row[3] == ">" for row in rows)  # parameters near zero: both kinds of row are checked
    for name, estimate, sigma, percent in (row[:4] for row in rows):
        assert float(estimate) == pytest.approx(estimates[name], rel=1e-3, abs=1e-12)  # the file's (consistent) value
        if percent == ">":  # sigma above the estimate: said in words, never as a percentage of a value near zero
            assert float(sigma) >= 0.98 * abs(float(estimate))
        elif abs(float(estimate)) > 1e-6:
            assert float(percent) == pytest.approx(100 * float(sigma) / abs(float(estimate)), rel=0.02, abs=0.1)
            assert float(percent) <= 100.0


def test_validate_writes_the_prepared_samples_and_the_model_torques(recordings, tmp_path, capsys):
    from identification.calibration.calibrated_model import read_calibrated_model
    from identification.data.io import load_recording
    from identification.metrics import rmse

    out, predictions = tmp_path / "model.json", tmp_path / "predictions.csv"
    assert main(["identify", "denso_vs6556g", "--data", str(recordings / "train.csv"), "--out", str(out)]) == 0
    capsys.readouterr()
    valid = recordings / "valid.csv"
    assert main(["validate", str(out), str(valid), "--predictions", str(predictions), "--json"]) == 0
    reported = json.loads(capsys.readouterr().out)["recordings"][0]
    lines = [line for line in predictions.read_text().splitlines() if not line.startswith("#")]
    table = np.genfromtxt(lines, delimiter=",", names=True)
    assert predictions.read_text().startswith(f"# recording 1: {valid}\nrecording,t,q1,")
    n = 6
    q, qd, qdd, tau, model_tau = (np.column_stack([table[f"{s}{j}"] for j in range(1, n + 1)])
                                  for s in ("q", "qd", "qdd", "tau", "tau_model"))  # fmt: skip
    loaded = read_calibrated_model(out)
    np.testing.assert_allclose(model_tau, loaded.calibrated.predict(loaded.model, q, qd, qdd), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rmse(tau, model_tau), reported["rmse"], rtol=1e-12)  # the samples validate judged
    raw = load_recording(valid, n)
    assert np.all(np.diff(table["t"]) > 0) and raw.t[0] <= table["t"][0] and table["t"][-1] <= raw.t[-1]
    np.testing.assert_allclose(
        q, np.column_stack([np.interp(table["t"], raw.t, raw.q[:, j]) for j in range(n)]), atol=1e-3
    )  # fmt: skip  (the positions filtered, not moved)
    before = predictions.read_bytes()
    assert main(["validate", str(out), str(valid), "--predictions", str(predictions)]) == 2
    assert "--overwrite" in capsys.readouterr().err and predictions.read_bytes() == before
    assert main(["validate", str(out), str(valid), "--predictions", str(predictions), "--overwrite"]) == 0
    assert "written to" in capsys.readouterr().out and not list(tmp_path.glob(".predictions*"))


def test_validate_prints_urdf_joint_names_whole():
    from psdm_casadi.cli.validate import validation_table
    from psdm_casadi.robot import load_robot
    from tests.conftest import example_robot_urdf

    names = load_robot(example_robot_urdf("panda_description/urdf/panda.urdf")).joint_names
    text = validation_table("run.csv", names, np.linspace(0.1, 0.9, len(names)), np.full(len(names), 0.99))
    rows = text.splitlines()[2:]
    assert [row.split()[0] for row in rows] == list(names) and "panda_finger_joint2" in text
    assert [float(row.split()[1]) for row in rows] == pytest.approx(np.linspace(0.1, 0.9, len(names)), rel=1e-3)


def test_commands_after_identify_read_the_model_from_the_cache(recordings, tmp_path, monkeypatch, capsys):
    import psdm_casadi.model_cache as model_cache

    calls = []
    derive = model_cache.derive_psdm
    monkeypatch.setattr(
        model_cache, "derive_psdm", lambda robot, options=None: calls.append(1) or derive(robot, options)
    )
    out = tmp_path / "model.json"
    assert main(["identify", "denso_vs6556g", "--data", str(recordings / "train.csv"), "--out", str(out)]) == 0
    assert calls == [1]
    assert main(["validate", str(out), str(recordings / "valid.csv")]) == 0
    assert main(["codegen", str(out), "--out", str(tmp_path / "c"), "--json"]) == 0
    assert calls == [1]  # the model file's robot is the same robot: the same cache entry
    capsys.readouterr()


def test_the_drive_columns_are_chosen_from_the_data_stated_and_stored_and_options_override(
    recordings, tmp_path, capsys
):
    argv = ["identify", "denso_vs6556g", "--data", str(recordings / "train.csv")]
    out = tmp_path / "auto.json"
    assert main([*argv, "--out", str(out)]) == 0
    columns = json.loads(out.read_text())["identification"]["column_choice"]
    assert columns["request"] == {"friction": "auto", "offset": "auto", "drive_inertia": "auto", "drive_loss": "auto",
                                  "coulomb_velocity": None}  # fmt: skip
    assert columns["coulomb_velocity"] == 0.05 and "Coulomb smoothing: tanh(qd / 0.05 rad/s)" in columns["smoothing"]
    assert columns["friction"] in ("coulomb-viscous", "stribeck") and "cross-validation" in columns["check"]
    assert {e["term"] for e in columns["evidence"]} >= {"stribeck", "offset"}
    text, err = capsys.readouterr()
    assert "drive columns: friction shape: " in text
    # the choice stated once, in the report (its log line is DEBUG); the Stribeck trial's velocities on one line, named
    # a trial (the shape may not be chosen)
    assert (text + err).count("friction shape: ") == 1, err
    assert re.search(r"Stribeck shape tried for the column choice \(kept only if it is chosen\): velocities "
                     r"([0-9.e+-]+, ){5}[0-9.e+-]+ rad/s after", err), err  # fmt: skip
    # the mass-matrix eigenvalue with as many digits as the pseudo-inertia's
    value = re.search(r"smallest mass-matrix eigenvalue ([0-9.e+-]+)\)", text).group(1)
    assert value == f"{float(value):.3g}", value
    document = json.loads(out.read_text())
    assert load_calibrated_model(out).document["identification"]["column_choice"] == columns
    document["identification"]["column_choice"]["offset_joints"] = [7]  # the Denso has six joints
    (tmp_path / "bad.json").write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match="identification.column_choice"):
        load_calibrated_model(tmp_path / "bad.json")
    del document["identification"]["column_choice"]  # a file of an earlier version: read as it was
    (tmp_path / "old.json").write_text(json.dumps(document))
    assert "column_choice" not in load_calibrated_model(tmp_path / "old.json").document["identification"]
    # the options override the choice: plain --offset is every joint's offset, --no-drive-inertia none
    out = tmp_path / "asked.json"
    asked = ["--offset", "--friction", "coulomb-viscous", "--no-drive-inertia", "--coulomb-velocity", "0.02"]
    assert main([*argv, *asked, "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["columns"]["request"] == {
        "friction": "coulomb-viscous",
        "offset": "on",
        "drive_inertia": "off",
        "drive_loss": "auto",
        "coulomb_velocity": 0.02,
    }
    assert summary["columns"]["smoothing"] == "Coulomb smoothing: tanh(qd / 0.02 rad/s) (as asked)"
    assert load_calibrated_model(out).document["drive"]["coulomb_velocity"] == 0.02
    assert main([*argv, "--coulomb-velocity", "-0.1", "--out", str(tmp_path / "no.json")]) == 2
    assert "--coulomb-velocity must be a velocity > 0" in capsys.readouterr().err
    assert summary["columns"]["evidence"] == [] and {f"offset{j}" for j in range(1, 7)} <= set(summary["drive"])
    assert not any(name.startswith("fs") for name in summary["drive"])


def test_a_vendor_log_is_read_by_validate_as_identify_read_it(recordings, tmp_path, capsys):
    """A controller's log (``Time``, ``Position1..6``, ``TorqueSm1..6`` and a model torque ``TorqueCmptd1..6``) read
    with ``--columns`` by identify: validate reads the next log the same way without the option, says so, and gives
    the numbers of the same file written with the standard columns; an older file (no ``provenance.columns``) and a
    standard file with ``--columns q=q`` read as before."""

    def vendor(name):
        lines = [line for line in (recordings / name).read_text().splitlines() if not line.startswith("#")]
        renamed = {"t": "Time", **{f"q{j}": f"Position{j}" for j in range(1, 7)},
                   **{f"tau{j}": f"TorqueSm{j}" for j in range(1, 7)}}  # fmt: skip
        header = [renamed.get(c, c) for c in lines[0].split(",")] + [f"TorqueCmptd{j}" for j in range(1, 7)]
        rows = [line + ",0" * 6 for line in lines[1:]]  # a controller's model torque beside the measured one
        (tmp_path / name).write_text("\n".join([",".join(header), *rows]) + "\n")
        return str(tmp_path / name)

    out = tmp_path / "m.json"
    argv = ["--quiet", "identify", "denso_vs6556g", "--data", vendor("train.csv"), "--out", str(out)]
    assert main([*argv, "--columns", "t=Time,q=Position,tau=TorqueSm"]) == 0
    assert load_calibrated_model(out).document["provenance"]["columns"] == {
        "columns": "t=Time,q=Position,tau=TorqueSm", "rate": None}  # fmt: skip
    capsys.readouterr()
    assert main(["validate", str(out), vendor("valid.csv"), "--json"]) == 0
    out_text, err = capsys.readouterr()
    assert "read as identify read the model's (--columns t=Time,q=Position,tau=TorqueSm" in err
    vendor_rmse = json.loads(out_text)["recordings"][0]["rmse"]
    assert main(["validate", str(out), str(recordings / "valid.csv"), "--columns", "q=q", "--json"]) == 0
    np.testing.assert_allclose(json.loads(capsys.readouterr().out)["recordings"][0]["rmse"], vendor_rmse, rtol=1e-12)
    document = json.loads(out.read_text())
    del document["provenance"]["columns"]  # a model file of before
    (tmp_path / "old.json").write_text(json.dumps(document))
    assert main(["validate", str(tmp_path / "old.json"), vendor("valid.csv")]) == 2
    assert "--columns q=Position,tau=<one of TorqueSm, TorqueCmptd>" in capsys.readouterr().err  # as before


def test_a_merged_rotor_held_near_its_reference_is_printed_with_the_value_fitted(tmp_path, capsys, monkeypatch):
    """Motor currents of a 3R arm whose robot file states no rotors: joints 1 and 2's drive inertias lie inside the
    base parameters and are held near what the training data give them. The pull is weak: joint 2's ended at about
    half its reference (0.156 against 0.282, truth 0.3), yet the text said only 'held near 0.282 kg m^2'; it now
    prints the model file's value beside the reference."""
    import dataclasses

    from psdm_casadi.robot import load_robot
    from tests.catalogue.test_implausible_recordings import ARM

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    (tmp_path / "arm.toml").write_text(ARM)
    robot = load_robot(tmp_path / "arm.toml")
    truth = dataclasses.replace(robot, rotor_inertia=np.array([0.4, 0.3, 0.1]), drive_inertia=(True, True, True))
    rng = np.random.default_rng(5)
    options = SimulationOptions(record_tau=False, record_current=True, current_noise_std=0.002, friction=True)
    for name in ("train.csv", "valid.csv"):
        reference = sine_experiment(truth, duration=8.0, rng=rng).reference()
        recording, _ = simulate_recording(truth, reference, options, rng)
        save_recording(recording, tmp_path / name)
    out = tmp_path / "model.json"
    argv = ["identify", str(tmp_path / "arm.toml"), "--data", str(tmp_path / "train.csv"), "--validate"]
    assert main([*argv, str(tmp_path / "valid.csv"), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    stored = json.loads(out.read_text())["standard"]
    fitted = np.array(stored["values"]).reshape(-1, 11)[:, 10]  # the model file's Ia of each link
    references = stored["envelope"]["drive_inertia_reference"]
    assert [entry["joint"] for entry in references] == [1, 2]
    for entry in references:
        line = next(x for x in text.splitlines() if x.strip().startswith(f"joint {entry['joint']}'s drive inertia"))
        assert f"held near {entry['kg_m2']:.3g} kg m^2" in line
        assert f"(fitted: {fitted[entry['joint'] - 1]:.3g} kg m^2)" in line
