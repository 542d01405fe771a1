"""Recordings in the formats users have: ROS 2 bags (sqlite3, mcap, one .mcap file) and MATLAB files, read back."""

from __future__ import annotations

import logging
import sys

import numpy as np
import pytest
from scipy.io import savemat

from identification.data.io import load_recording, read_table
from identification.data.matfile import read_mat_table
from identification.data.rosbag import is_rosbag, read_rosbag_table
from psdm_casadi.errors import RecordingError
from tests.identification.recording_formats import (
    joint_state_bag,
    matlab_v73_bytes,
    mcap_file,
    smooth_signals,
)

ROBOT = ("shoulder", "elbow", "wrist")  # the robot's joint order
BAG_JOINTS = ("wrist", "gripper", "shoulder", "elbow")  # what the bag publishes (shuffled in every message)


def expected(signals, names, field):
    return np.column_stack([signals[name][field] for name in names])


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """A sqlite3 bag folder, an mcap bag folder and the single .mcap file, with the signals they hold."""
    folder = tmp_path_factory.mktemp("bags")
    signals = smooth_signals(BAG_JOINTS)
    sqlite = joint_state_bag(folder / "sqlite_bag", BAG_JOINTS, signals, storage="sqlite3")
    mcap = joint_state_bag(folder / "mcap_bag", BAG_JOINTS, signals, storage="mcap")
    return {"sqlite3": sqlite, "mcap": mcap, "file": mcap_file(mcap, folder / "run.mcap")}, signals


@pytest.mark.parametrize("kind", ["sqlite3", "mcap", "file"])
def test_bag_joints_follow_the_robot_order(bags, kind):
    paths, signals = bags
    rec = load_recording(paths[kind], n_dof=3, joint_names=ROBOT)
    np.testing.assert_allclose(rec.t, signals["t"], atol=1e-12)
    np.testing.assert_array_equal(rec.q, expected(signals, ROBOT, 0))
    np.testing.assert_array_equal(rec.qd, expected(signals, ROBOT, 1))
    np.testing.assert_array_equal(rec.tau, expected(signals, ROBOT, 2))
    assert rec.qdd is None and rec.current is None
    assert is_rosbag(paths[kind])


def test_bag_without_a_robot_keeps_the_first_message_order(bags):
    paths, signals = bags
    table = read_table(paths["file"])
    first = read_rosbag_table(paths["file"], joint_names=None)
    assert table.names == first.names and table.names[:5] == ("t", "q1", "q2", "q3", "q4")
    # the first message's order, read back by matching its positions at sample 1 (sample 0 is all zeros)
    q1 = table.column("q1")[1]
    name = next(n for n in BAG_JOINTS if signals[n][0][1] == q1)
    np.testing.assert_array_equal(table.column("q1"), signals[name][0])


def test_bag_log_time_when_stamps_are_zero_and_no_velocity(tmp_path, caplog):
    signals = smooth_signals(ROBOT)
    bag = joint_state_bag(tmp_path / "bag", ROBOT, signals, stamps=False, velocity=False, shuffle_seed=None)
    with caplog.at_level(logging.INFO, logger="identification.data.rosbag"):
        rec = load_recording(bag, 3, ROBOT)
    np.testing.assert_allclose(rec.t, signals["t"], atol=1e-12)
    assert rec.qd is None
    assert "log time" in caplog.text


def test_bag_topic_is_chosen_and_checked(tmp_path):
    signals = smooth_signals(ROBOT)
    bag = joint_state_bag(tmp_path / "bag", ROBOT, signals, topics=("/left/joint_states", "/right/joint_states"))
    with pytest.raises(RecordingError, match="2 sensor_msgs/msg/JointState topics.*--topic /left/joint_states"):
        load_recording(bag, 3, ROBOT)
    rec = load_recording(bag, 3, ROBOT, topic="/right/joint_states")
    np.testing.assert_array_equal(rec.q, expected(signals, ROBOT, 0))
    with pytest.raises(RecordingError, match="topic '/nope' must be a sensor_msgs/msg/JointState topic"):
        load_recording(bag, 3, ROBOT, topic="/nope")


def test_bag_refusals(tmp_path):
    signals = smooth_signals(ROBOT)
    no_effort = joint_state_bag(tmp_path / "no_effort", ROBOT, signals, effort=False)
    with pytest.raises(RecordingError, match="JointState.effort of topic /joint_states must hold every joint"):
        load_recording(no_effort, 3, ROBOT)
    with pytest.raises(RecordingError, match="must hold the robot's joints J1, elbow; J1 is missing"):
        load_recording(no_effort, 2, ("J1", "elbow"))
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "metadata.yaml").write_text("not: [a bag")
    with pytest.raises(RecordingError, match="broken: not a readable ROS 2 bag"):
        load_recording(tmp_path / "broken", 3)


@pytest.fixture
def arrays():
    rng = np.random.default_rng(3)
    n = 30
    return {
        "t": np.cumsum(rng.uniform(0.5e-3, 1.5e-3, n)),
        "q": rng.normal(size=(n, 2)),
        "qd": rng.normal(size=(n, 2)),
        "tau": rng.normal(size=(n, 2)),
    }


def test_mat_matrix_layout_round_trip(tmp_path, arrays):
    path = tmp_path / "rec.mat"
    savemat(path, {"t": arrays["t"][:, None], "q": arrays["q"], "qd": arrays["qd"], "tau": arrays["tau"]})
    rec = load_recording(path, n_dof=2)
    for key in ("t", "q", "qd", "tau"):
        np.testing.assert_array_equal(getattr(rec, key), arrays[key])
    savemat(tmp_path / "currents.mat", {"t": arrays["t"], "q": arrays["q"], "current": arrays["tau"]})
    np.testing.assert_array_equal(load_recording(tmp_path / "currents.mat", 2).current, arrays["tau"])


def test_mat_column_layout_round_trip(tmp_path, arrays):
    path = tmp_path / "rec.mat"
    columns = {"t": arrays["t"]}  # savemat writes 1-D arrays as row vectors
    for j in range(2):
        columns |= {f"q{j + 1}": arrays["q"][:, j], f"tau{j + 1}": arrays["tau"][:, j][:, None]}
    savemat(path, columns)
    rec = load_recording(path, n_dof=2)
    np.testing.assert_array_equal(rec.q, arrays["q"])
    np.testing.assert_array_equal(rec.tau, arrays["tau"])


@pytest.mark.parametrize(
    "content, match",
    [
        (
            lambda a: {"t": a["t"], "q": a["q"].T, "tau": a["tau"]},
            r"'q' has shape \(2, 30\): one joint per row.*q.'",
        ),
        (lambda a: {"t": a["t"], "q": a["q"], "tau1": a["tau"][:, 0]}, "holds both matrix variables"),
        (lambda a: {"q": a["q"], "tau": a["tau"]}, "variable t is missing"),
        (lambda a: {"t": a["t"], "q": a["q"][:20], "tau": a["tau"]}, "variable 'q' has 20 rows but t has 30"),
        (lambda a: {"t": a["t"], "q": a["q"], "tau": a["tau"], "robot": "panda"}, "variable 'robot' is text"),
        (lambda a: {"t": a["t"], "q": a["q"], "tau": {"a": 1.0}}, "variable 'tau' is a struct"),
        (lambda a: {"t": a["q"], "q": a["q"], "tau": a["tau"]}, "variable 't' has shape .30, 2.; it must be a vector"),
    ],
    ids=["transposed", "mixed", "no t", "length", "text", "struct", "t matrix"],
)
def test_mat_refusals(tmp_path, arrays, content, match):
    path = tmp_path / "bad.mat"
    savemat(path, content(arrays))
    with pytest.raises(RecordingError, match=match):
        read_mat_table(path)


def test_mat_v73_needs_h5py(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "h5py", None)  # refused even where h5py is installed
    path = tmp_path / "big.mat"
    path.write_bytes(matlab_v73_bytes())
    with pytest.raises(RecordingError, match="big.mat is a MATLAB v7.3 file .HDF5., which needs the h5py package"):
        load_recording(path)


def test_mat_v73_read_with_h5py(tmp_path, arrays):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "v73.mat"

    def write(extra=None):
        with h5py.File(path, "w", userblock_size=512) as handle:
            for name in ("t", "q", "tau"):
                value = arrays[name][:, None] if name == "t" else arrays[name]
                handle.create_dataset(name, data=value.T)  # MATLAB stores its column-major arrays transposed
                handle[name].attrs["MATLAB_class"] = np.bytes_("double")
            if extra is not None:
                handle.create_dataset(extra, data=np.array([[112, 97]], dtype=np.uint16))
                handle[extra].attrs["MATLAB_class"] = np.bytes_("char")
        with open(path, "r+b") as raw:
            raw.write(matlab_v73_bytes()[:128])

    write()
    rec = load_recording(path, 2)
    np.testing.assert_array_equal(rec.q, arrays["q"])
    np.testing.assert_array_equal(rec.t, arrays["t"])
    write(extra="robot")
    with pytest.raises(RecordingError, match="variable 'robot' is text"):
        load_recording(path, 2)
