"""Loading and saving recordings: round trips and every refusal naming its column."""

import numpy as np
import pytest

from identification.data.io import load_recording, save_recording
from identification.data.recording import Recording
from psdm_casadi.errors import RecordingError


def write(tmp_path, text, name="rec.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD = "# a comment\nt,q1,q2,tau1,tau2\n0,0,1,5,6\n# inside\n0.1,0.1,1.1,5.1,6.1\n0.25,0.2,1.2,5.2,6.2\n"


def test_csv_with_comments_and_uneven_steps(tmp_path):
    rec = load_recording(write(tmp_path, GOOD), n_dof=2)
    np.testing.assert_allclose(rec.t, [0, 0.1, 0.25])
    np.testing.assert_allclose(rec.q[:, 1], [1, 1.1, 1.2])
    np.testing.assert_allclose(rec.tau[:, 0], [5, 5.1, 5.2])
    assert rec.current is None


@pytest.mark.parametrize("suffix", ["csv", "npz"])
def test_round_trip(tmp_path, suffix):
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, 50))
    rec = Recording(
        t=t,
        q=rng.normal(size=(50, 3)),
        tau=rng.normal(size=(50, 3)),
        current=rng.normal(size=(50, 3)),
        qd=rng.normal(size=(50, 3)),
    )
    path = save_recording(rec, tmp_path / f"r.{suffix}")
    back = load_recording(path, n_dof=3)
    for key in ("t", "q", "tau", "current", "qd"):
        np.testing.assert_array_equal(getattr(back, key), getattr(rec, key))
    assert back.qdd is None


def test_save_refuses_overwrite_and_is_atomic(tmp_path):
    rec = load_recording(write(tmp_path, GOOD))
    path = tmp_path / "out.csv"
    save_recording(rec, path)
    with pytest.raises(FileExistsError, match="overwrite"):
        save_recording(rec, path)
    save_recording(rec, path, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv", "rec.csv"]  # no temporary left


@pytest.mark.parametrize(
    "text, column",
    [
        ("q1,tau1\n0,1\n1,2\n2,3\n", "column t is missing"),
        ("t,q2,tau1,tau2\n0,0,0,0\n1,0,0,0\n2,0,0,0\n", "column q1 is missing"),
        ("t,q1,q3,tau1,tau2,tau3\n0,0,0,0,0,0\n1,0,0,0,0,0\n2,0,0,0,0,0\n", "column q2 is missing"),
        ("t,q1,q2,tau1\n0,0,0,0\n1,0,0,0\n2,0,0,0\n", "column tau2 is missing"),
        ("t,q1,q1,tau1\n0,0,0,0\n1,0,0,0\n2,0,0,0\n", "column q1 appears twice"),
        ("t,q1\n0,0\n1,0\n2,0\n", "columns tau1.* and i1.* are both missing"),
        ("t,q1,tau1,foo\n0,0,0,0\n1,0,0,0\n2,0,0,0\n", "column 'foo'"),
        ("t,q1,tau1,tau2\n0,0,0,0\n1,0,0,0\n2,0,0,0\n", "column tau2 has no matching q2"),
        ("t,q1,tau1\n0,0,0\n1,nan,0\n2,0,0\n", "column q1 holds nan at line 3"),
        ("t,q1,tau1\n0,0,0\n1,0,inf\n2,0,0\n", "column tau1 holds inf at line 3"),
        ("t,q1,tau1\n0,0,0\n1,0,abc\n2,0,0\n", "column tau1 holds 'abc' at line 3"),
        ("t,q1,tau1\n0,0,0\n1,0,0\n1,0,0\n", "column t must be strictly increasing.*line 4"),
        ("t,q1,tau1\n0,0,0\n1,0,0\n", "2 samples"),
        ("t,q1,tau1\n0,0,0\n1,0\n2,0,0\n", "line 3 has 2 fields"),
        ("# only comments\n", "no header"),
    ],
)
def test_bad_csv(tmp_path, text, column):
    with pytest.raises(RecordingError, match=column):
        load_recording(write(tmp_path, text))


def test_joint_count_must_match_robot(tmp_path):
    with pytest.raises(RecordingError, match=r"q1..q2 give 2 joints but the robot has n_dof=6"):
        load_recording(write(tmp_path, GOOD), n_dof=6)


def test_currents_only(tmp_path):
    rec = load_recording(write(tmp_path, "t,q1,i1\n0,0,1\n1,0,2\n2,0,3\n"), n_dof=1)
    np.testing.assert_allclose(rec.current[:, 0], [1, 2, 3])


def test_npz_errors(tmp_path):
    np.savez(tmp_path / "a.npz", t=np.arange(5.0), q1=np.zeros(4), tau1=np.zeros(5))
    with pytest.raises(RecordingError, match="column q1 has 4 samples"):
        load_recording(tmp_path / "a.npz")
    np.savez(tmp_path / "b.npz", t=np.arange(5.0), q1=np.zeros(5), tau1=np.zeros((5, 1)))
    with pytest.raises(RecordingError, match="tau1"):
        load_recording(tmp_path / "b.npz")
    np.savez(tmp_path / "c.npz", t=np.arange(5.0), q1=np.zeros(5), i1=np.full(5, np.nan))
    with pytest.raises(RecordingError, match="column i1 holds nan"):
        load_recording(tmp_path / "c.npz")


def test_missing_file_and_suffix(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_recording(tmp_path / "none.csv")
    with pytest.raises(RecordingError, match=r"\.csv or \.npz"):
        load_recording(write(tmp_path, GOOD, name="x.txt"))
    rec = load_recording(write(tmp_path, GOOD))
    with pytest.raises(RecordingError, match=r"\.csv or \.npz"):
        save_recording(rec, tmp_path / "x.txt")
