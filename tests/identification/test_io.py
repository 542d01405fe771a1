"""Loading and saving recordings: round trips, the fast reader against the former one, every refusal and its place."""

import gzip
import os

import numpy as np
import pytest

import identification.data.csvfile as csvfile
from identification.data.dataset import load_calibration_data
from identification.data.io import COLUMN_PREFIXES, load_recording, read_table, save_recording, time_column
from identification.data.recording import Recording
from identification.data.table import ColumnTable
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


def test_a_robot_with_more_joints_names_the_lock_that_fixes_it(tmp_path, capsys):
    from psdm_casadi.cli import main
    from psdm_casadi.robot import load_robot
    from tests.conftest import example_robot_urdf

    urdf = example_robot_urdf("panda_description/urdf/panda.urdf")
    panda = load_robot(urdf)  # 7 arm joints and 2 fingers
    columns = [f"{p}{j}" for p in ("q", "tau") for j in range(1, 8)]
    rows = np.random.default_rng(0).normal(size=(30, 14)) * 0.1
    text = (
        "t,"
        + ",".join(columns)
        + "\n"
        + "".join(f"{0.01 * k}," + ",".join(map(str, r)) + "\n" for k, r in enumerate(rows))
    )
    path = write(tmp_path, text)
    fix = "--lock panda_finger_joint1 --lock panda_finger_joint2"
    with pytest.raises(RecordingError, match="give 7 joints but the robot has n_dof=9") as caught:
        load_recording(path, panda.n_dof, panda.joint_names)
    assert "joints 8..9 (panda_finger_joint1, panda_finger_joint2)" in str(caught.value) and fix in str(caught.value)
    with pytest.raises(RecordingError, match="or remove the columns of joints 2..2"):
        load_recording(write(tmp_path, GOOD, "two.csv"), 1, ("j1",))  # fewer robot joints: no lock can fix it
    assert main(["validate", "no_model.json", str(path)]) == 2  # a missing model is named first
    capsys.readouterr()
    assert main(["diagnose", str(urdf), "--train", str(path), "--validate", str(path)]) == 2
    assert fix in capsys.readouterr().err


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
    with pytest.raises(RecordingError, match=r"Recording.current holds no measurement: every joint's column is NaN"):
        load_recording(tmp_path / "c.npz")


def test_missing_file_and_suffix(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_recording(tmp_path / "none.csv")
    with pytest.raises(RecordingError, match=r"\.csv or \.npz"):
        load_recording(write(tmp_path, GOOD, name="x.txt"))
    rec = load_recording(write(tmp_path, GOOD))
    with pytest.raises(RecordingError, match=r"\.csv or \.npz"):
        save_recording(rec, tmp_path / "x.txt")


# --- the vectorised reader gives exactly what the line-by-line reader gave -------------------------


def legacy_columns(path):
    """The former reader's parse (a Python loop over stripped lines, ``float`` per field), as the oracle."""
    header, rows = None, []
    for line in path.read_text().splitlines():
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        fields = [f.strip() for f in text.split(",")]
        if header is None:
            header = fields
        else:
            rows.append([float(f) for f in fields])
    data = np.array(rows, dtype=float)
    return {name: data[:, k] for k, name in enumerate(header)}


def assert_matches_legacy(path, n_dof):
    rec = load_recording(path, n_dof)
    columns = legacy_columns(path)
    np.testing.assert_array_equal(rec.t, columns["t"])
    for signal, prefix in COLUMN_PREFIXES.items():
        names = [f"{prefix}{j + 1}" for j in range(n_dof)]
        if names[0] in columns:
            np.testing.assert_array_equal(getattr(rec, signal), np.column_stack([columns[n] for n in names]))
        else:
            assert getattr(rec, signal) is None
    return rec


def random_csv(rng, n_rows, n_dof, style):
    """A recording's CSV text in one of the spellings the old reader accepted."""
    names = ["t"] + [f"{p}{j + 1}" for p in ("q", "qd", "tau", "i") for j in range(n_dof)]
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, n_rows))
    values = np.column_stack([t, rng.normal(scale=rng.choice([1e-6, 1.0, 1e4]), size=(n_rows, len(names) - 1))])
    fmt = {"exact": "%.17g", "short": "%.4g", "fixed": "%.6f", "sci": "%.8E"}[style]
    lines = ["# generated", ", ".join(names)]
    for k, row in enumerate(values):
        lines.append(",".join(fmt % v for v in row))
        if k % 7 == 3:
            lines.append("# a comment between samples")
        if k % 11 == 5:
            lines.append("")
    return "\n".join(lines) + "\n"


def test_existing_fixtures_read_as_before(tmp_path):
    assert_matches_legacy(write(tmp_path, GOOD), n_dof=2)
    assert_matches_legacy(write(tmp_path, "t,q1,i1\n0,0,1\n1,0,2\n2,0,3\n", "currents.csv"), n_dof=1)


@pytest.mark.parametrize("style", ["exact", "short", "fixed", "sci"])
def test_random_files_read_bit_for_bit_as_before(tmp_path, style):
    rng = np.random.default_rng(len(style))
    for k, (n_rows, n_dof) in enumerate([(3, 1), (50, 2), (400, 6)]):
        assert_matches_legacy(write(tmp_path, random_csv(rng, n_rows, n_dof, style), f"r{k}.csv"), n_dof)


def test_round_trip_through_save_is_bit_exact_for_many_rows(tmp_path):
    rng = np.random.default_rng(5)
    n = 20_000
    rec = Recording(t=np.arange(n) * 1e-3, q=rng.normal(size=(n, 6)), tau=rng.normal(size=(n, 6)) * 50)
    back = assert_matches_legacy(save_recording(rec, tmp_path / "long.csv"), n_dof=6)
    np.testing.assert_array_equal(back.q, rec.q)
    np.testing.assert_array_equal(back.tau, rec.tau)


def test_a_well_formed_file_takes_the_fast_path_only(tmp_path, monkeypatch):
    """One numpy parse, no Python pass over the lines (filter, scan or line lookup)."""

    def refuse(*args, **kwargs):
        raise AssertionError("the slow path ran on a well-formed file")

    monkeypatch.setattr(csvfile, "_data_lines", refuse)
    monkeypatch.setattr(csvfile, "_is_data_line", refuse)
    rng = np.random.default_rng(0)
    text = random_csv(rng, 2000, 6, "exact").replace("\n\n", "\n")  # blank lines are fine, too
    rec = load_recording(write(tmp_path, text), n_dof=6)
    assert rec.n_samples == 2000


def test_recording_keeps_the_arrays_the_reader_made(tmp_path):
    """The reader's arrays become the Recording's (read-only, owning their data): no second copy."""
    rec = load_recording(write(tmp_path, GOOD), n_dof=2)
    for array in (rec.t, rec.q, rec.tau):
        assert array.base is None and not array.flags.writeable and array.flags.c_contiguous
    assert rec.with_signals(name="again").q is rec.q


# --- spellings of CSV that are read ------------------------------------------------------------------

PLAIN = "t,q1,tau1\n0,0.5,1\n0.1,0.6,2\n0.2,0.7,3\n"


@pytest.mark.parametrize(
    "content",
    [
        pytest.param(b"\xef\xbb\xbf" + PLAIN.encode(), id="Excel UTF-8 BOM"),
        pytest.param(PLAIN.replace(",", ";").encode(), id="semicolons"),
        pytest.param(PLAIN.replace(",", "\t").encode(), id="tabs"),
        pytest.param(PLAIN.replace(",", "   ").encode(), id="blanks"),
        pytest.param(PLAIN.replace(",", "\t").encode("utf-16"), id="Excel Unicode text (UTF-16, tabs)"),
        pytest.param(b"# recorded at 20 \xb0C\n" + PLAIN.encode(), id="Latin-1 byte in a comment"),
        pytest.param(PLAIN.replace("\n", "\r\n").encode(), id="CRLF"),
        pytest.param(PLAIN.replace("\n0.1", "\n   \n  # indented\n0.1").encode(), id="blank-only line and indented"),
        pytest.param(PLAIN.replace(",1\n", ",1  # first\n").encode(), id="comment after a sample"),
        pytest.param(b'"t","q1","tau1"\n' + PLAIN.split("\n", 1)[1].encode(), id="quoted header"),
        pytest.param(PLAIN.replace(",", " , ").encode(), id="blanks around commas"),
        pytest.param(PLAIN.rstrip("\n").encode(), id="no newline at the end"),
    ],
)
def test_spellings_read_as_the_plain_file(tmp_path, content):
    expected = load_recording(write(tmp_path, PLAIN, "plain.csv"), n_dof=1)
    path = tmp_path / "variant.csv"
    path.write_bytes(content)
    rec = load_recording(path, n_dof=1)
    for key in ("t", "q", "tau"):
        np.testing.assert_array_equal(getattr(rec, key), getattr(expected, key))


# --- refusals of the readers --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "content, match",
    [
        (gzip.compress(PLAIN.encode(), mtime=0), r"rec.csv is gzip-compressed.*gunzip"),
        (b"PK\x03\x04" + b"\x00" * 30, r"ZIP archive.*Save the sheet as CSV"),
        (b"\x93NUMPY\x01\x00", r"\.npy array.*numpy.savez"),
        (b"t,q1\x00,tau1\n", r"binary data \(a NUL byte at byte 4\)"),
        (b"\x89HDF\r\n\x1a\n", "HDF5"),
        (b"MATLAB 5.0 MAT-file", "MATLAB"),
        (b"", "no header row found; the file is empty"),
        (b"# c\n\n  \n", "holds only comments and blank lines"),
        (b"0,1,2\n1,2,3\n", "line 1 holds numbers where the header"),
        (b"t,q1,tau1,\n0,0,0,\n", r"empty column name at position 4 of 4 \(a trailing ','\?\)"),
        (b"t;q1;tau1\n0;0,5;1\n", r"1 sample"),  # a decimal comma beside ';' is read (test_vendor_logs)
        (b"t,q1,tau1\n0;0;1\n", r"line 2 has 1 field but.*separated by ';', the header by ','"),
        (b"t,q1,tau1\n0,,1\n1,0,0\n2,0,0\n", r"column q1 holds '' at line 2.*an empty cell"),
        (b"t,q1,tau1\n0,1_0,1\n1,0,0\n2,0,0\n", "column q1 holds '1_0' at line 2"),
        (b"t,q1,tau1\n0,0,1\n1,1e300,0\n2,0,0\n", r"column q1 holds 1e\+300 at line 3.*Check the units"),
        (b"t,q1,tau1\n0,0,1\n1,0,0\n1.7e18,0,0\n", r"column t holds 1.7e\+18 at line 4"),
        (b"t,q1,tau1\n0,0,1\n# x\n\n1,0,0\n0.5,0,0\n", r"t=0.5 at line 6 after t=1.0"),
        (b"t,q1,tau1\n0,0,1\n1,0,0\n2,0,0\n", None),
    ],
)
def test_csv_refusals_name_file_place_and_fix(tmp_path, content, match):
    path = tmp_path / "rec.csv"
    path.write_bytes(content)
    if match is None:
        assert load_recording(path).n_samples == 3
        return
    with pytest.raises(RecordingError, match=match):
        load_recording(path)


def test_folder_pipe_and_unreadable_file(tmp_path, monkeypatch):
    (tmp_path / "folder.csv").mkdir()
    with pytest.raises(RecordingError, match="'.*folder.csv' is a folder, not a file"):
        load_recording(tmp_path / "folder.csv")
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "pipe.csv")
        with pytest.raises(RecordingError, match="not a regular file"):
            load_recording(tmp_path / "pipe.csv")
    path = write(tmp_path, PLAIN, "locked.csv")

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(csvfile, "open", denied, raising=False)
    with pytest.raises(RecordingError, match=r"'locked.csv' cannot be read \(Permission denied\).*permissions"):
        load_recording(path)


def npz_file(tmp_path, name="rec.npz", **columns):
    path = tmp_path / name
    np.savez(path, **columns)
    return path


def test_npz_refusals(tmp_path):
    good = dict(t=np.arange(5.0), q1=np.zeros(5), tau1=np.zeros(5))
    with pytest.raises(RecordingError, match="array 'q1' holds Python objects.*Save plain numbers"):
        load_recording(npz_file(tmp_path, **{**good, "q1": np.array([None] * 5, dtype=object)}))
    with pytest.raises(RecordingError, match="array 'q1' has dtype <U1; a column must hold real numbers"):
        load_recording(npz_file(tmp_path, **{**good, "q1": np.array(["a"] * 5)}))
    with pytest.raises(RecordingError, match="column q1 holds 1e\\+300 at row 2"):
        load_recording(npz_file(tmp_path, **{**good, "q1": np.array([0, 0, 1e300, 0, 0])}))
    path = npz_file(tmp_path, **good)
    (tmp_path / "cut.npz").write_bytes(path.read_bytes()[:200])
    with pytest.raises(RecordingError, match="cut.npz: not a readable NPZ archive"):
        load_recording(tmp_path / "cut.npz")
    for content, match in [
        (PLAIN.encode(), r"is text, not an NPZ archive.*Rename it to .csv"),
        (gzip.compress(b"x", mtime=0), "gzip"),
        (b"", "is empty"),
        (b"\x93NUMPY\x01\x00", "single .npy array"),
        (bytes(range(256)), r"not an NPZ archive \(no ZIP signature\)"),
    ]:
        (tmp_path / "odd.npz").write_bytes(content)
        with pytest.raises(RecordingError, match=match):
            load_recording(tmp_path / "odd.npz")
    np.save(tmp_path / "single.npy", np.zeros(3))
    (tmp_path / "single.npz").write_bytes((tmp_path / "single.npy").read_bytes())
    with pytest.raises(RecordingError, match="single .npy array"):
        load_recording(tmp_path / "single.npz")


def test_npz_reads_integer_columns_as_floats(tmp_path):
    rec = load_recording(npz_file(tmp_path, t=np.arange(4), q1=np.arange(4, dtype=np.int16), i1=np.ones(4, np.float32)))
    assert rec.t.dtype == np.float64 and rec.q.dtype == np.float64
    np.testing.assert_array_equal(rec.q[:, 0], [0, 1, 2, 3])


# --- the table between reader and Recording -------------------------------------------------------------


def test_column_table_checks_and_time_column(tmp_path):
    with pytest.raises(RecordingError, match="column q1 appears twice"):
        ColumnTable(source="x.csv", names=("t", "q1", "q1"), data=np.zeros((3, 3)))
    with pytest.raises(RecordingError, match=r"ColumnTable.data must have shape \(n_samples, 2\)"):
        ColumnTable(source="x.csv", names=("t", "q1"), data=np.zeros((3, 3)))
    with pytest.raises(RecordingError, match="column 2 has no name"):
        ColumnTable(source="x.csv", names=("t", ""), data=np.zeros((3, 2)))
    table = read_table(write(tmp_path, "t,q1,q2\n0,0,0\n# x\n1,0,0\n1,0,0\n"))
    assert table.names == ("t", "q1", "q2") and table.n_samples == 3
    with pytest.raises(RecordingError, match="t=1.0 at line 5 after t=1.0"):
        time_column(table)
    np.testing.assert_array_equal(time_column(read_table(write(tmp_path, "t\n0\n2\n", "t.csv"))), [0.0, 2.0])


# --- the calibration data folder -----------------------------------------------------------------------


def data_folder(tmp_path, files):
    folder = tmp_path / "data"
    folder.mkdir(parents=True)
    (folder / "payload.json").write_text('{"mass": 2.0, "com": [0.05, 0.0, 0.05]}')
    for name, text in files.items():
        (folder / name).write_text(text)
    return folder


def test_data_folder_refusals(tmp_path):
    rec = "t,q1,q2,tau1,tau2\n0,0,0,0,0\n1,0,0,0,0\n2,0,0,0,0\n"
    with pytest.raises(RecordingError, match="'.*rec.csv' is a file, not a folder.*--data"):
        load_calibration_data(write(tmp_path, rec))
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_calibration_data(tmp_path / "nowhere")
    with pytest.raises(RecordingError, match="friction_j0.csv: the joint number .* must be 1 or more.*friction_j1.csv"):
        load_calibration_data(data_folder(tmp_path / "a", {"friction_j0.csv": rec}), n_dof=2)
    with pytest.raises(RecordingError, match=r"friction_j3.csv: .* must be 1..2 \(the robot has 2 joints"):
        load_calibration_data(data_folder(tmp_path / "b", {"friction_j3.csv": rec}), n_dof=2)
    with pytest.raises(RecordingError, match="motor_j0_nominal.csv"):
        load_calibration_data(data_folder(tmp_path / "c", {"motor_j0_nominal.csv": rec}), n_dof=2)
    with pytest.raises(RecordingError, match="friction_j01.csv and friction_j1.csv .* Keep one"):
        load_calibration_data(data_folder(tmp_path / "d", {"friction_j1.csv": rec, "friction_j01.csv": rec}), 2)


def test_column_table_leaves_a_writable_input_alone():
    data = np.zeros((3, 2))
    table = ColumnTable(source="x.csv", names=("t", "q1"), data=data)
    assert data.flags.writeable and table.data is not data and not table.data.flags.writeable
    frozen = np.zeros((3, 2))
    frozen.setflags(write=False)
    assert ColumnTable(source="x.csv", names=("t", "q1"), data=frozen).data is frozen
