"""A model file's friction along the joints' logged temperature (``calibration.temperature_friction``).

Reference: known synthetic truth. The virtual Denso's joint 3 has 30 % less Coulomb and static friction warm (35 °C)
than cold (25 °C) (``test_friction_drift``'s recordings); identify reads the drift along the logged temperature and
the model file keeps the friction at the held-out 35 °C with the slopes. Judged on a cold recording that logs its
temperature, the slopes must predict better than the reference friction; the exported C must compute what
``CalibratedModel.predict`` computes at any temperature (the Python model, to 1e-9).
"""

from __future__ import annotations

import copy
import json
import shutil

import numpy as np
import pytest

from codegen.build import build_library
from codegen.calibrated import build_calibrated_functions
from codegen.export import export_c
from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.identify_route import identify_recordings
from identification.calibration.temperature_friction import TemperatureFriction
from identification.calibration.trajectory_data import drive_columns, file_shape
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.metrics import rmse
from psdm_casadi.cli import main
from psdm_casadi.errors import ModelFileError
from tests.conftest import DENSO_FILE
from tests.identification.test_friction_drift import COULOMB_FACTOR, JOINT, drift_recording

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
TOLERANCE = 1e-9
COLD, WARM = 25.0, 35.0


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # load_robot's copies of the robot texts


def _logging(recording, celsius: float, every: int = 50):
    """The recording with every joint's temperature logged every ``every``-th sample (NaN between)."""
    temperature = np.full((recording.n_samples, recording.n_dof), np.nan)
    temperature[::every] = celsius
    return recording.with_signals(temperature=temperature)


def _with_law(calibrated: CalibratedModel, slopes: dict, reference=30.0, reach=(20.0, 40.0)) -> CalibratedModel:
    document = copy.deepcopy(calibrated.document)
    document["drive"]["temperature"] = {"version": 1, "joints": [
        {"joint": JOINT + 1, "reference_c": reference, "range_c": list(reach), "slopes_per_c": slopes}]}  # fmt: skip
    return CalibratedModel(document)


@pytest.fixture(scope="module")
def handmade(denso, denso_model, tmp_path_factory):
    """A Denso model file (Coulomb, viscous, offsets fitted) with a law on joint 3 written by hand, and a recording."""
    recording = drift_recording(denso, 11, 1.0, "run.csv", duration=4.0)
    fit = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions(friction=("fc", "fv", "offset")))
    base = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    law = _with_law(base, {f"fc{JOINT + 1}": -0.05, f"fv{JOINT + 1}": -0.02})
    folder = tmp_path_factory.mktemp("law")
    law.save(folder / "model.json")
    return folder, law, base, recording


def test_the_law_moves_the_friction_by_its_slopes_within_its_reach(handmade, denso_model):
    """At 36 °C joint 3's torque moves by the slopes times 6 °C on its friction columns; beyond the reach it is read at
    the reach's edge; NaN (not logged), or no temperature, gives the reference friction; other joints do not move."""
    _, law, base, recording = handmade
    q, qd, qdd = recording.q[:300], np.gradient(recording.q, recording.t, axis=0)[:300], np.zeros((300, 6))
    reference = base.predict(denso_model, q, qd, qdd)
    drive = base.document["drive"]
    columns = drive_columns(qd, qdd, tuple(drive["friction_terms"]), (), drive["coulomb_velocity"], *file_shape(drive))
    fc, fv = (columns[:, JOINT, drive["names"].index(f"{n}{JOINT + 1}")] for n in ("fc", "fv"))
    for celsius, used in ((36.0, 36.0), (55.0, 40.0), (5.0, 20.0)):
        moved = law.predict(denso_model, q, qd, qdd, temperature=np.full((300, 6), celsius))
        expected = reference.copy()
        expected[:, JOINT] += (-0.05 * fc - 0.02 * fv) * (used - 30.0)
        np.testing.assert_allclose(moved, expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(law.predict(denso_model, q, qd, qdd), reference, rtol=1e-12)
    np.testing.assert_allclose(law.predict(denso_model, q, qd, qdd, temperature=np.full((300, 6), np.nan)), reference)


def test_a_model_file_reads_its_law_and_refuses_one_that_does_not_parse(handmade, tmp_path):
    folder, law, _, _ = handmade
    loaded = load_calibrated_model(folder / "model.json").temperature_friction
    assert loaded.joints[0].joint == JOINT and loaded.joints[0].reach == (20.0, 40.0)
    document = copy.deepcopy(law.document)
    document["drive"]["temperature"]["joints"][0]["slopes_per_c"] = {"fc99": 1.0}
    with pytest.raises(ModelFileError, match="drive.temperature"):
        TemperatureFriction.from_document(document)
    document["drive"]["temperature"]["version"] = 2
    (tmp_path / "bad.json").write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match="version 1"):
        load_calibrated_model(tmp_path / "bad.json")
    older = copy.deepcopy(law.document)
    del older["drive"]["temperature"]
    assert CalibratedModel(older).temperature_friction is None  # a file without the block: as before


def test_validate_uses_the_logged_temperatures_and_says_so(handmade, tmp_path, capsys):
    """A recording logged at 38 °C is judged with the friction there; one without temperatures at the reference."""
    folder, law, _, recording = handmade
    warm = save_recording(_logging(recording, 38.0), tmp_path / "warm.csv")
    plain = save_recording(recording, tmp_path / "plain.csv")
    assert main(["validate", str(folder / "model.json"), str(warm), str(plain), "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["recordings"]
    assert "logged 38.0-38.0 °C" in rows[0]["friction_temperature"]
    assert "reference 30.0 °C (none logged)" in rows[1]["friction_temperature"]
    assert rows[0]["rmse"][JOINT] != pytest.approx(rows[1]["rmse"][JOINT], rel=1e-6)  # the friction moved
    assert rows[0]["rmse"][0] == pytest.approx(rows[1]["rmse"][0], rel=1e-9)  # a joint without a law did not


@pytest.mark.needs_cc
@needs_cc
def test_the_exported_c_computes_the_python_model_at_any_temperature(handmade, denso, denso_model, tmp_path, rng):
    """``psdm_inverse_dynamics_at_temperature`` equals ``predict(..., temperature)`` at 24 and 37 °C, beyond the
    reach, at the reference and at NaN (not measured: the reference's friction, not the reach's end); mixed per
    joint too; ``psdm_inverse_dynamics`` stays the reference's."""
    _, law, _, _ = handmade
    library = build_library(export_c(build_calibrated_functions(law, denso_model, denso), tmp_path / "out"),
                            flags=("-O1",))  # fmt: skip
    at = library.function("psdm_inverse_dynamics_at_temperature")
    q, qd, qdd = rng.uniform(-2, 2, (3, 50, denso.n_dof))
    mixed = np.where(rng.random((50, denso.n_dof)) < 0.5, np.nan, rng.uniform(10.0, 60.0, (50, denso.n_dof)))
    for temperature in [*(np.full((50, denso.n_dof), celsius) for celsius in (24.0, 37.0, 70.0, 30.0, np.nan)), mixed]:
        got = np.array(at.map(50)(q.T, qd.T, qdd.T, temperature.T), dtype=float).T
        want = law.predict(denso_model, q, qd, qdd, temperature=temperature)
        np.testing.assert_allclose(got, want, rtol=TOLERANCE, atol=TOLERANCE * np.abs(want).max())
    reference = np.array(library.function("psdm_inverse_dynamics").map(50)(q.T, qd.T, qdd.T), dtype=float).T
    np.testing.assert_allclose(reference, law.predict(denso_model, q, qd, qdd), rtol=TOLERANCE, atol=1e-9)
    assert "psdm_inverse_dynamics_at_temperature" in (tmp_path / "out" / "psdm_dynamics.h").read_text()


@pytest.mark.slow
def test_identify_writes_the_law_and_the_slopes_beat_the_reference_on_a_cold_recording(denso, denso_model):
    """Cold (25 °C) and warm (35 °C) training recordings, a warm held-out one: the file keeps joint 3's friction at
    35 °C with a falling Coulomb slope; on a cold recording that logs 25 °C the slopes predict joint 3 better than the
    friction at the reference (the warm one), and no joint worse."""
    cold = _logging(drift_recording(denso, 1, 1.0, "cold.csv"), COLD)
    warm = _logging(drift_recording(denso, 2, COULOMB_FACTOR, "warm.csv"), WARM)
    held = _logging(drift_recording(denso, 3, COULOMB_FACTOR, "held_warm.csv", duration=6.0), WARM)
    temperatures = ([np.full(6, COLD), np.full(6, WARM)], [np.full(6, WARM)])
    result = identify_recordings(denso, denso_model, [cold, warm], validation=[held], temperatures=temperatures)
    block = result.calibrated.document["drive"]["temperature"]
    (joint,) = block["joints"]
    assert joint["joint"] == JOINT + 1 and joint["reference_c"] == WARM and joint["range_c"] == [20.0, 40.0]
    assert joint["slopes_per_c"][f"fc{JOINT + 1}"] < 0
    calibrated = result.calibrated
    check = _logging(drift_recording(denso, 4, 1.0, "check_cold.csv", duration=6.0), COLD)
    prepared, with_law = calibrated.predict_recording(denso_model, check)
    _, without = calibrated.predict_recording(denso_model, check.with_signals(temperature=None))
    better, before = rmse(prepared.tau, with_law), rmse(prepared.tau, without)
    assert better[JOINT] < 0.8 * before[JOINT], (better, before)
    assert np.all(better <= before + 1e-9)


@pytest.mark.slow
@pytest.mark.needs_cc
@needs_cc
def test_the_warming_cobot_s_law_beats_the_reference_while_it_warms_and_exports_it(benchmark_modules, tmp_path,
                                                                                   capsys):  # fmt: skip
    """The warming cobot (``unseen_warm_cobot``: friction ``1 + 0.35 exp(-t / 200 s)`` times the warm arm's, the
    joints' temperature ``45 - 20 exp(-t / 200 s)`` °C logged every 0.5 s), identified on defaults: the file keeps a
    law in temperature; validated on a recording of the warm-up (100-120 s into the session, 32-34 °C, none in
    training or validation) with the logged temperatures it is closer to the truth's torque than at the reference on
    the joints with a law, and no joint worse; the exported C equals the Python model at 28 and 41 °C."""
    import unseen_arms
    from unseen_warm_cobot import session_recording

    from identification.calibration.calibrated_model import read_calibrated_model
    from psdm_casadi.robot import load_robot

    case = unseen_arms.build("cobot_warming_currents", tmp_path, 0)
    model_file, layout = tmp_path / "model.json", list(case.extra)
    command = ["identify", case.robot, "--data", *case.train, "--validate", case.validate, *layout, "--out"]
    assert main([str(c) for c in command] + [str(model_file), "--json"]) == 0
    capsys.readouterr()
    document = json.loads(model_file.read_text())
    laws = document["drive"]["temperature"]["joints"]
    assert laws and all(law["slopes_per_c"] for law in laws)
    plain = copy.deepcopy(document)
    del plain["drive"]["temperature"]
    (tmp_path / "plain.json").write_text(json.dumps(plain))
    truth = load_robot(tmp_path / "truth" / "truth.toml")
    warming, _ = session_recording(tmp_path, truth, "session_0100s", 100.0, 20.0, None, np.random.default_rng(7))
    errors, said = {}, {}
    for name in ("model.json", "plain.json"):
        assert main(["validate", str(tmp_path / name), str(warming), *map(str, layout), "--json"]) == 0
        row = json.loads(capsys.readouterr().out)["recordings"][0]
        errors[name], said[name] = np.array(row["rmse"]), row["friction_temperature"]
    assert "at its logged 3" in said["model.json"] and said["plain.json"] is None
    joints = [law["joint"] - 1 for law in laws]
    assert np.all(errors["model.json"][joints] < errors["plain.json"][joints]), errors
    assert np.all(errors["model.json"] <= errors["plain.json"] * 1.001 + 1e-9), errors

    loaded = read_calibrated_model(model_file)
    library = build_library(export_c(build_calibrated_functions(loaded.calibrated, loaded.model, loaded.robot),
                                     tmp_path / "c_code"), flags=("-O1",))  # fmt: skip
    at = library.function("psdm_inverse_dynamics_at_temperature")
    rng = np.random.default_rng(3)
    q, qd, qdd = rng.uniform(-1.5, 1.5, (3, 40, 7))
    for celsius in (28.0, 41.0):
        temperature = np.full((40, 7), celsius)
        got = np.array(at.map(40)(q.T, qd.T, qdd.T, temperature.T), dtype=float).T
        want = loaded.calibrated.predict(loaded.model, q, qd, qdd, temperature=temperature)
        np.testing.assert_allclose(got, want, rtol=TOLERANCE, atol=TOLERANCE * np.abs(want).max())


def test_diagnose_reports_where_the_file_s_law_was_read_in_its_json(handmade, tmp_path, capsys):
    """``psdm diagnose MODEL --json`` carries validate's ``friction_temperature`` for its validation recording, and its
    note on stderr names that recording (it printed the list of every validation path); the report.json written to
    ``--out`` carries it as well (it had none)."""
    folder, _, _, recording = handmade
    warm = save_recording(_logging(recording, 38.0), tmp_path / "warm.csv")
    plain = save_recording(recording, tmp_path / "plain.csv")
    assert main(["diagnose", str(folder / "model.json"), "--train", str(plain), "--validate", str(warm), "--json",
                 "--out", str(tmp_path / "diagnosis")]) == 0  # fmt: skip
    out, err = capsys.readouterr()
    said = json.loads(out)["friction_temperature"]
    assert "logged 38.0-38.0 °C" in said
    assert json.loads((tmp_path / "diagnosis" / "report.json").read_text())["friction_temperature"] == said
    assert f"psdm diagnose: note: {warm}: the model file's" in err, err  # the recording, not a list of them
