"""The edge trim: one definition (``filter_choice.EDGE_PERIODS``), stored in the model file, older files as before.

The zero-phase filter starts from a recording's first and last samples as if the motion had been still before them;
the differentiated acceleration carries that start-up transient about three filter periods in. A recording cut out
of a motion (as real logs are) checks it against the virtual robot's truth; a model file stores its trim
(``identification.preparation`` version 2), and a version-1 file, or one written before the block, is judged with
the one period it was written with.
"""

import contextlib
import copy
import io
import json
import math

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.lugre_recordings import bristle_force_at
from identification.calibration.model_preparation import EDGE_PERIODS, PREPARATION_VERSION, model_preparation
from identification.calibration.preparation import trim_filter_edges
from identification.calibration.trajectory_data import prepare_recording
from identification.data.io import load_recording, save_recording
from identification.data.preprocessing import PreprocessOptions, central_difference, preprocess, zero_phase_filter
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

RATE = 500.0  # Hz
CUTOFF = 10.0  # identify's default at this rate


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def cut_motion(denso):
    """A noise-free, frictionless recording of the virtual Denso cut out of a longer motion (it starts and ends
    moving, as a real log does), with the simulation's truth."""
    rng = np.random.default_rng(5)
    reference = sine_experiment(denso, duration=8.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.0, rate=RATE, friction=False)
    recording, truth = simulate_recording(denso, reference, options, rng)
    return recording.time_slice(2.0, 6.0), truth


def test_the_trim_removes_the_filter_s_start_up_transient(cut_motion, denso_model):
    """Against the truth: the true rigid-body model on the prepared (filtered, differentiated) state predicts the
    prepared torque to within the start-up transient; three periods trimmed leave a fifth of one period's error (and
    of its acceleration error) on every joint."""
    cut, truth = cut_motion
    theta = denso_model.base_parameters(truth.standard_parameters)
    torque, acceleration = {}, {}
    for edge in (1, EDGE_PERIODS):
        ready, cutoff, _ = prepare_recording(cut, None, None, edge)
        assert cutoff == CUTOFF
        assert ready.t[0] - cut.t[0] == pytest.approx(edge / CUTOFF, abs=1.5 / RATE)  # ceil of rate / cutoff
        error = ready.tau - denso_model.inverse_dynamics(ready.q, ready.qd, ready.qdd, theta)
        torque[edge] = np.sqrt(np.mean(error**2, axis=0))
        true_qdd = np.column_stack([np.interp(ready.t, truth.t, truth.qdd[:, j]) for j in range(cut.n_dof)])
        acceleration[edge] = np.sqrt(np.mean((ready.qdd - true_qdd) ** 2, axis=0))
    assert np.all(torque[EDGE_PERIODS] < 0.2 * torque[1]), (torque[1], torque[EDGE_PERIODS])
    assert np.all(acceleration[EDGE_PERIODS] < 0.2 * acceleration[1]), (acceleration[1], acceleration[EDGE_PERIODS])


@pytest.mark.parametrize("rate", [500.0, 1000.0, 5000.0])
def test_the_edge_transient_decays_as_the_filter_s_slowest_pole(rate):
    """What a trim leaves, against the Butterworth's theory: the acceleration a motion at 1 rad/s through the cut (a
    ramp, its true acceleration 0) gets from the filter is about 2 cutoff x the speed at the edge (21 rad/s^2 at
    10 Hz), decays by the least damped pole pair's ``exp(-2 pi sin(pi / 16))`` = 0.29 per filter period, and
    ``EDGE_PERIODS`` leave 1-5 % of it (filter_choice's comment)."""
    t = np.arange(0.0, 4.0, 1.0 / rate)
    error = np.abs(central_difference(t, zero_phase_filter(t - 2.0, rate, CUTOFF))[1])
    periods = np.minimum(t - t[0], t[-1] - t) * CUTOFF  # from the nearer end
    envelope = [error[(periods >= k) & (periods < k + 1)].max() for k in range(2, 8)]
    decay = np.exp(np.diff(np.log(envelope)))
    assert decay == pytest.approx(np.exp(-2.0 * np.pi * np.sin(np.pi / 16.0)), rel=0.15), decay
    assert error.max() == pytest.approx(2.0 * CUTOFF, rel=0.1)
    assert 0.01 < error[periods >= EDGE_PERIODS].max() / error.max() < 0.05


def test_the_four_step_route_trims_what_identify_trims(cut_motion):
    """One definition: ``trim_filter_edges`` (the four-step route) keeps the same first and last instants as
    identify's ``prepare_recording`` (``filter_choice.kept_samples``), within a sample and identify's grid step."""
    cut, _ = cut_motion
    ready, _, _ = prepare_recording(cut, None, CUTOFF)
    trimmed = trim_filter_edges(preprocess(cut, PreprocessOptions(cutoff_hz=CUTOFF)), CUTOFF)
    step = RATE // (10 * CUTOFF)  # identify keeps every 5th sample: its last one is up to 4 samples earlier
    assert (trimmed.t[0], trimmed.t[-1]) == pytest.approx((ready.t[0], ready.t[-1]), abs=(step + 1.5) / RATE)


@pytest.fixture(scope="module")
def model_files(tmp_path_factory, denso):
    """``psdm identify --validate --json`` on a virtual Denso recording: the folder with the model, the recordings,
    a hand-made version-1 file and a file without the preparation block, and identify's summary."""
    folder = tmp_path_factory.mktemp("edge_trim")
    for k, name in enumerate(("train.csv", "valid.csv")):
        rng = np.random.default_rng(40 + k)
        reference = sine_experiment(denso, duration=8.0, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=RATE)
        save_recording(simulate_recording(denso, reference, options, rng)[0], folder / name)
    argv = ["identify", str(DENSO_FILE), "--data", str(folder / "train.csv"), "--validate", str(folder / "valid.csv"),
            "--out", str(folder / "model.json"), "--json"]  # fmt: skip
    with contextlib.redirect_stdout(io.StringIO()) as out:
        assert main(argv) == 0
    summary = json.loads(out.getvalue())
    document = json.loads((folder / "model.json").read_text())
    version1 = copy.deepcopy(document)  # as the code before the versioned trim wrote it
    block = version1["identification"]["preparation"]
    block["version"] = 1
    del block["edge_periods"]
    block["edge"] = "ceil(rate / cutoff) samples (one filter period) trimmed at each end"
    (folder / "version1.json").write_text(json.dumps(version1))
    older = copy.deepcopy(document)
    del older["identification"]["preparation"]
    (folder / "older.json").write_text(json.dumps(older))
    return folder, summary


def _validate(capsys, model, recording) -> tuple:
    assert main(["validate", str(model), str(recording), "--json"]) == 0
    captured = capsys.readouterr()
    return json.loads(captured.out), captured.err


def test_a_new_file_stores_three_periods_and_validate_repeats_identify(model_files, capsys):
    folder, summary = model_files
    block = load_calibrated_model(folder / "model.json").document["identification"]["preparation"]
    assert block["version"] == PREPARATION_VERSION == 2 and block["edge_periods"] == EDGE_PERIODS == 3
    preparation = model_preparation(load_calibrated_model(folder / "model.json").document)
    assert preparation.edge_periods == 3 and preparation.note == "" and "3 filter periods" in preparation.text()
    validated, err = _validate(capsys, folder / "model.json", folder / "valid.csv")
    assert "note:" not in err and validated["preparation"]["edge_periods"] == 3
    np.testing.assert_allclose(validated["recordings"][0]["rmse"], summary["validation"][0]["rmse"], rtol=1e-9)


def test_an_older_file_is_judged_with_one_period_as_before(model_files, denso_model, capsys):
    """A version-1 block and a file without the block are judged on the samples the code before the versioned trim
    kept: ``ceil(rate / cutoff)`` samples off each end, computed here by hand from the raw recording."""
    folder, _ = model_files
    raw = load_recording(folder / "valid.csv", 6)
    calibrated = CalibratedModel(json.loads((folder / "version1.json").read_text()))
    rate = 1.0 / raw.dt  # as read from the file (500.00000000006 Hz): 51 samples trimmed
    edge = math.ceil(rate / CUTOFF)
    keep = slice(edge, raw.n_samples - edge, int(rate // (10 * CUTOFF)))  # samples at ten times the cutoff
    q = np.column_stack([zero_phase_filter(raw.q[:, j], RATE, CUTOFF) for j in range(6)])
    tau = np.column_stack([zero_phase_filter(raw.tau[:, j], RATE, CUTOFF) for j in range(6)])
    qd, qdd = central_difference(raw.t, q)
    lugre = calibrated.lugre_parameters  # identify may keep LuGre on some joints: its bristles carried to the start
    bristle = None if lugre is None else bristle_force_at(lugre, raw, CUTOFF, raw.t[keep][0])
    by_hand = calibrated.predict(denso_model, q[keep], qd[keep], qdd[keep], t=raw.t[keep], bristle=bristle)
    expected = np.sqrt(np.mean((tau[keep] - by_hand) ** 2, axis=0))
    for name, words in (("version1.json", "version 1"), ("older.json", "written before its preparation")):
        preparation = model_preparation(json.loads((folder / name).read_text()))
        assert preparation.edge_periods == 1 and "one filter period" in preparation.text()
        validated, err = _validate(capsys, folder / name, folder / "valid.csv")
        assert "note:" in err and words in err and "one filter period" in err
        np.testing.assert_allclose(validated["recordings"][0]["rmse"], expected, rtol=1e-9)
    new, _ = _validate(capsys, folder / "model.json", folder / "valid.csv")
    assert not np.allclose(new["recordings"][0]["rmse"], expected, rtol=1e-3)  # three periods judge other samples


def test_a_diagnosis_of_an_older_file_keeps_its_trim(model_files):
    from identification.diagnosis.model_file import model_file_options

    folder, _ = model_files
    for name, periods in (("model.json", 3), ("version1.json", 1), ("older.json", 1)):
        options = model_file_options(CalibratedModel(json.loads((folder / name).read_text())))
        assert options.edge_periods == periods and options.samples == "identify"


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"version": 3}, "identification.preparation.version"),
        ({"edge_periods": -1}, "edge_periods"),
        ({"edge_periods": None}, "edge_periods"),
    ],  # fmt: skip
)
def test_a_bad_preparation_block_is_refused_naming_the_field(model_files, tmp_path, capsys, change, field):
    folder, _ = model_files
    document = json.loads((folder / "model.json").read_text())
    document["identification"]["preparation"].update(change)
    (tmp_path / "bad.json").write_text(json.dumps(document))
    assert main(["validate", str(tmp_path / "bad.json"), str(folder / "valid.csv")]) == 2
    err = capsys.readouterr().err
    assert field in err and "Traceback" not in err


def _nominal_rmse(robot, train, validation, edge_periods) -> np.ndarray:
    """Validation RMSE per joint [N m] of the robot file's rigid body (Pinocchio) with a Coulomb, viscous and offset
    friction per joint fitted on ``train``, both prepared as identify prepares them with ``edge_periods``."""
    from psdm_casadi.oracle import PinocchioOracle

    oracle = PinocchioOracle(robot)
    ready = [prepare_recording(r, None, None, edge_periods)[0] for r in (train, validation)]
    rest = [r.tau - oracle.rnea(r.q, r.qd, r.qdd) for r in ready]
    columns = [np.stack([np.tanh(r.qd / 0.05), r.qd, np.ones_like(r.qd)], axis=2) for r in ready]
    out = []
    for j in range(robot.n_dof):
        x = np.linalg.lstsq(columns[0][:, j], rest[0][:, j], rcond=None)[0]
        out.append(np.sqrt(np.mean((rest[1][:, j] - columns[1][:, j] @ x) ** 2)))
    return np.array(out)


def test_the_panda_s_real_recording_validates_the_nominal_model_without_the_edge_transient():
    """Gaz et al.'s Panda recording (../shared, 21 s), the first 70 % training, the next 15 % validation (as
    ``benchmarks/real_data_diagnosis.py`` splits it): the robot file's model validated joint 1 at 1.9 N m with one
    filter period trimmed, the filter's start-up transient at both cuts; with identify's trim, below 0.8 N m."""
    from identification.data.recording import Recording
    from psdm_casadi import from_urdf
    from tests.conftest import DATASETS, example_robot_urdf

    folder = DATASETS / "panda_gaz2019"
    if not folder.exists():
        pytest.skip(f"Panda data absent in {folder}")

    t = np.loadtxt(folder / "exciting_traj_time.txt")
    q = np.loadtxt(folder / "exciting_traj_positions.txt").reshape(-1, 7)
    tau = np.loadtxt(folder / "exciting_traj_torques.txt").reshape(-1, 7)
    keep = np.concatenate([[True], np.diff(t) > 0])
    recording = Recording(t=t[keep], q=q[keep], tau=tau[keep])
    locked = ("panda_finger_joint1", "panda_finger_joint2")
    robot = from_urdf(example_robot_urdf("panda_description/urdf/panda.urdf"), locked_joints=locked)
    cut = int(0.7 * recording.n_samples)
    train, validation = recording.slice(0, cut), recording.slice(cut, cut + int(0.15 * recording.n_samples))
    one, ours = (_nominal_rmse(robot, train, validation, edge) for edge in (1, EDGE_PERIODS))
    assert one[0] > 1.5 and ours[0] < 0.8 and ours[0] < 0.5 * one[0], (one, ours)  # measured 1.89 -> 0.69
    assert np.all(ours <= one * 1.1), (one, ours)  # no joint worse beyond the samples' change
