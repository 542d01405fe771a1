"""The bad-input catalogue for recordings (CSV and NPZ) and the calibration data folder, through the ``psdm`` command.

Most cases run ``psdm diagnose denso_vs6556g --train train.csv --validate validate.csv``, which reads
both recordings before it derives anything; the data-folder cases run ``psdm identify ... --data data``
and the reference cases ``psdm simulate ... --reference ref.csv``. Each refusal must exit with 2, print
no traceback, name the file and the fix, and leave every file as it was.
"""

from __future__ import annotations

import builtins
import gzip
import io
import os
import zipfile

import numpy as np
import pytest

import identification.data.csvfile as csvfile
from tests.catalogue.harness import BadInput, check_refusal

N_DOF = 6
HEADER = ["t"] + [f"q{j}" for j in range(1, N_DOF + 1)] + [f"tau{j}" for j in range(1, N_DOF + 1)]
N_ROWS = 12


def cells(n_rows: int = N_ROWS) -> list:
    """A smooth 6-joint recording at 1 kHz as strings, one list per row."""
    rows = []
    for k in range(n_rows):
        t = 1e-3 * k
        values = [t] + [0.1 * j * np.sin(t * j) for j in range(1, N_DOF + 1)] + [float(j) for j in range(1, 7)]
        rows.append([f"{v:.6g}" for v in values])
    return rows


def csv_text(header=None, rows=None, sep: str = ",", edit=None, end: str = "\n") -> str:
    """A recording's CSV text; ``edit`` maps (row, column name) to the text of that cell."""
    header = HEADER if header is None else header
    rows = cells() if rows is None else rows
    for (row, name), text in (edit or {}).items():
        rows[row][header.index(name)] = text
    return sep.join(header) + end + "".join(sep.join(r) + end for r in rows)


GOOD = csv_text()


def npz_bytes(**columns) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **columns)
    return buffer.getvalue()


def good_columns(n: int = N_ROWS) -> dict:
    rows = np.array(cells(n), dtype=float)
    return {name: rows[:, k] for k, name in enumerate(HEADER)}


def train(name: str, content, *expect, file: str = "train.csv", extra: dict | None = None) -> BadInput:
    """``psdm diagnose`` with a bad training recording ``file`` (none when ``content`` is None) and a good
    validation one; ``extra`` holds further files to write."""
    files = {"validate.csv": GOOD, **({} if content is None else {file: content}), **(extra or {})}
    return BadInput(
        name,
        ("diagnose", "denso_vs6556g", "--train", file, "--validate", "validate.csv"),
        expect=(file, *expect),
        files=files,
    )


def validate(name: str, content, *expect) -> BadInput:
    """``psdm diagnose`` with a good training recording and a bad validation one (none when ``content`` is None)."""
    return BadInput(
        name,
        ("diagnose", "denso_vs6556g", "--train", "train.csv", "--validate", "validate.csv"),
        expect=("validate.csv", *expect),
        files={"train.csv": GOOD, **({} if content is None else {"validate.csv": content})},
    )


def data_folder(name: str, files: dict, *expect) -> BadInput:
    """``psdm identify`` on a data folder holding payload.json and ``files``."""
    return BadInput(
        name,
        ("identify", "denso_vs6556g", "--data", "data", "--out", "out"),
        expect=expect,
        files={
            "data/payload.json": '{"mass": 2.0, "com": [0.05, 0.0, 0.05]}',
            **{f"data/{k}": v for k, v in files.items()},
        },
    )


def with_bytes(text: str, new: bytes) -> bytes:
    """``text`` encoded as UTF-8 with its one ``@`` replaced by raw bytes."""
    head, tail = text.split("@")
    return head.encode() + new + tail.encode()


NOT_TEXT = [
    train("gzip data named .csv", gzip.compress(GOOD.encode(), mtime=0), "gzip", "gunzip"),
    train("xlsx workbook named .csv", npz_bytes(t=np.zeros(3))[:4] + b"\x14\x00" * 40, "zip archive", "save the sheet"),
    train("npy array named .csv", b"\x93NUMPY\x01\x00v\x00{'descr': '<f8'}" + b"\x00" * 40, ".npy", "numpy.savez"),
    train("binary bytes", bytes(range(256)) * 4, "binary data", "export the recording as csv"),
    train("hdf5 (MATLAB v7.3) named .csv", b"\x89HDF\r\n\x1a\n" + b"\x00" * 64, "hdf5", "export"),
    train("MATLAB 5 file named .csv", b"MATLAB 5.0 MAT-file, Platform: GLNXA64" + b"\x00" * 90, "mat", "export"),
    train("empty file", "", "no header row", "is empty", "start it with a header"),
    train("only comments", "# recorded on Monday\n\n# nothing else\n", "only comments", "start it with a header"),
    train("a folder named train.csv", None, "is a folder", "pass one .csv", extra={"train.csv/part1.csv": GOOD}),
    train("wrong suffix", GOOD, "must end in .csv or .npz", "convert", file="train.txt"),
    train(
        "a payload manifest as a recording",
        '[[configuration]]\nname = "tool"\nrecordings = ["validate.csv"]\n',
        "is a TOML file, not a recording",
        "identify's --data",
        "A.payload.json",
        file="configurations.toml",
    ),
    validate("missing validation file", None, "does not exist", "check the path"),
]

ENCODING_AND_LAYOUT = [
    train(
        "Latin-1 byte in a column name",
        with_bytes(csv_text(header=HEADER[:2] + ["q2@"] + HEADER[3:]), b"\xb0"),
        "column 'q2",
        "is not a recording column",
        "rename",
    ),
    train(
        "Latin-1 byte in a number",
        with_bytes(csv_text(edit={(2, "q3"): "0.1@"}), b"\xb5"),
        "column q3",
        "line 4",
        "not a number",
    ),
    train(
        "semicolons with decimal commas and a cell that is not a number",  # decimal commas alone are read
        csv_text(sep=";", rows=[[c.replace(".", ",") for c in r] for r in cells()], edit={(5, "tau1"): "n/a"}),
        "line 3",
        "decimal comma",
        "0.5, not 0,5",
    ),
    train(
        "comma header, semicolon rows",
        ",".join(HEADER) + "\n" + "".join(";".join(r) + "\n" for r in cells()),
        "line 2 has 1 field but",
        "separated by ';'",
        "fix that line",
    ),
    train("trailing comma on every line", csv_text(end=",\n"), "empty column name", "trailing ','", "remove"),
    train("trailing comma on the rows only", GOOD.replace("\n0.001,", ",\n0.001,", 1), "line 2 has 14 fields"),
    train("short row", GOOD.replace(",6\n", "\n", 3), "line 2 has 12 fields", "header (line 1) has 13"),
    train("long row", GOOD.replace(",6\n", ",6,7\n", 5), "line 2 has 14 fields", "fix that line"),
    train("duplicate column", csv_text(header=HEADER[:-1] + ["q1"]), "column q1 appears twice", "rename or remove"),
    train("no header row", "".join(",".join(r) + "\n" for r in cells()), "holds numbers", "add a header line"),
    train("header only", GOOD.splitlines()[0] + "\n", "0 samples", "at least 3", "record a longer experiment"),
    train("two samples", csv_text(rows=cells(2)), "2 samples", "at least 3"),
    validate("validation of one sample", csv_text(rows=cells(1)), "1 sample;", "at least 3"),
]

NUMBERS = [
    train("text in a cell", csv_text(edit={(5, "tau3"): "abc"}), "column tau3 holds 'abc' at line 7", "fix or remove"),
    train("empty cell", csv_text(edit={(2, "q4"): ""}), "column q4", "line 4", "an empty cell"),
    train("quoted number", csv_text(edit={(3, "q1"): '"0.5"'}), "column q1", "line 5", "not a number"),
    train("digit group separator", csv_text(edit={(3, "tau1"): "1_000"}), "column tau1 holds '1_000'", "line 5"),
    train("hex number", csv_text(edit={(4, "tau2"): "0x1F"}), "column tau2", "line 6", "not a number"),
    train(
        "1e300 in a position", csv_text(edit={(4, "q2"): "1e300"}), "column q2", "1e+300", "line 6", "check the units"
    ),
    train("1e300 in time", csv_text(edit={(11, "t"): "1e300"}), "column t", "line 13", "check the units"),
    train("time in nanoseconds", csv_text(edit={(11, "t"): "1.7e18"}), "column t", "line 13", "t [s]"),
    train("number beyond double range", csv_text(edit={(3, "tau5"): "1e400"}), "column tau5 holds inf", "line 5"),
    train("inf", csv_text(edit={(6, "tau6"): "inf"}), "column tau6 holds inf at line 8", "remove or interpolate"),
    train("-inf", csv_text(edit={(6, "q6"): "-inf"}), "column q6 holds -inf at line 8", "remove or interpolate"),
    train("nan", csv_text(edit={(7, "q3"): "nan"}), "column q3 holds nan at line 9", "remove or interpolate"),
    validate("NaN in validation", csv_text(edit={(9, "tau1"): "NaN"}), "column tau1 holds nan at line 11"),
    train("repeated time stamp", csv_text(edit={(5, "t"): "0.004"}), "strictly increasing", "line 7", "drop repeated"),
    train("time going back", csv_text(edit={(8, "t"): "0.001"}), "strictly increasing", "line 10", "sort the samples"),
    train(
        "time repeated after a comment",
        GOOD.replace("\n0.003,", "\n# pause\n0.002,", 1),
        "strictly increasing",
        "line 6",
    ),
]

COLUMNS = [
    train("no time column", csv_text(header=["clock"] + HEADER[1:]), "column t is missing", "add a time column"),
    train(
        "BOM, semicolons and a NaN (read up to the NaN)",
        "\ufeff" + csv_text(sep=";", edit={(2, "q3"): "nan"}),
        "column q3 holds nan at line 4",
    ),
    train("missing q3", csv_text(header=HEADER[:3] + ["x3"] + HEADER[4:]), "column 'x3'", "rename or remove"),
    train("two joints for a 6-joint robot", "t,q1,q2,tau1,tau2\n0,0,0,0,0\n1,0,0,0,0\n2,0,0,0,0\n", "n_dof=6"),
    train("no torques or currents", csv_text(header=HEADER[:7], rows=[r[:7] for r in cells()]), "both missing"),
    train("tau7 on a 6-joint robot", csv_text(header=HEADER[:-1] + ["tau7"]), "column tau7 has no matching q7"),
    train("upper-case names", csv_text(header=[h.upper() for h in HEADER]), "column t is missing", "named 't'"),
]

NPZ = [
    train("truncated NPZ", npz_bytes(**good_columns())[:300], "not a readable npz", "numpy.savez", file="train.npz"),
    train("CSV text named .npz", GOOD, "is text", "rename it to .csv", file="train.npz"),
    train("gzip named .npz", gzip.compress(GOOD.encode(), mtime=0), "gzip", "decompress", file="train.npz"),
    train("single .npy array", b"\x93NUMPY\x01\x00" + b" " * 40, "single .npy array", "numpy.savez", file="train.npz"),
    train("empty .npz", b"", "is empty", "numpy.savez", file="train.npz"),
    train(
        "object array (pickle)",
        npz_bytes(**{**good_columns(), "q1": np.array([None] * N_ROWS, dtype=object)}),
        "'q1'",
        "python objects",
        "save plain numbers",
        file="train.npz",
    ),
    train("text column", npz_bytes(**{**good_columns(), "tau2": np.array(["a"] * N_ROWS)}), "dtype", file="train.npz"),
    train(
        "complex column",
        npz_bytes(**{**good_columns(), "tau2": np.ones(N_ROWS, dtype=complex)}),
        "'tau2'",
        "real numbers",
        file="train.npz",
    ),
    train(
        "2-D column",
        npz_bytes(**{**good_columns(), "q5": np.zeros((N_ROWS, 2))}),
        "'q5'",
        "one array per column",
        file="train.npz",
    ),
    train(
        "columns of unequal length",
        npz_bytes(**{**good_columns(), "q2": np.zeros(N_ROWS - 1)}),
        "column q2 has 11 samples but t has 12",
        "equal length",
        file="train.npz",
    ),
    train(
        "NaN in an NPZ column",
        npz_bytes(**{**good_columns(), "tau4": np.where(np.arange(N_ROWS) == 0, np.nan, 1.0)}),
        "column tau4 holds nan at row 0",  # NaN throughout is a joint without torque: test_missing_torque
        file="train.npz",
    ),
]

DATA_FOLDER = [
    BadInput(
        "--data is a file",
        ("identify", "denso_vs6556g", "--data", "data.csv", "--protocol", "four-step", "--out", "out"),
        expect=("data.csv", "folder"),
        files={"data.csv": GOOD},
    ),
    data_folder("friction file numbered 0", {"friction_j0.csv": GOOD}, "friction_j0.csv", "numbered from 1", "rename"),
    data_folder("friction file of joint 7", {"friction_j7.csv": GOOD}, "friction_j7.csv", "must be 1..6"),
    data_folder("motor sweep numbered 0", {"motor_j0_nominal.csv": GOOD, "motor_j0_payload.csv": GOOD}, "motor_j0"),
    data_folder("gzip gravity recording", {"gravity.csv": gzip.compress(GOOD.encode())}, "gravity.csv", "gunzip"),
    data_folder(
        "two friction recordings of joint 1",
        {"friction_j1.csv": GOOD, "friction_j1.npz": npz_bytes(**good_columns())},
        "friction_j1.csv",
        "friction_j1.npz",
        "keep one",
    ),
    data_folder("NaN in a friction recording", {"friction_j2.csv": csv_text(edit={(3, "q2"): "nan"})}, "line 5"),
    data_folder("a folder named gravity.csv", {"gravity.csv/x.csv": GOOD}, "gravity.csv", "is a folder"),
]

REFERENCE = [
    BadInput(
        "reference without a time column",
        ("simulate", "denso_vs6556g", "--reference", "ref.csv", "--out", "out"),
        expect=("ref.csv", "column t is missing"),
        files={"ref.csv": "q1,q2,q3,q4,q5,q6\n" + "0,0,0,0,0,0\n" * 3},
    ),
    BadInput(
        "reference with text in a cell",
        ("simulate", "denso_vs6556g", "--reference", "ref.csv", "--out", "out"),
        expect=("ref.csv", "column q2 holds 'abc' at line 3", "fix or remove"),
        files={"ref.csv": "t,q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0,0\n0.1,0,abc,0,0,0,0\n0.2,0,0,0,0,0,0\n"},
    ),
]

CASES = NOT_TEXT + ENCODING_AND_LAYOUT + NUMBERS + COLUMNS + NPZ + DATA_FOLDER + REFERENCE


def reference(name: str, content, *expect) -> BadInput:
    return BadInput(
        name,
        ("simulate", "denso_vs6556g", "--reference", "ref.csv", "--out", "out", "--duration", "0.05"),
        expect=("ref.csv", *expect),
        files={"ref.csv": content},
    )


REF = "t,q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0,0\n0.1,0,0,0,0,0,0\n0.2,0,0,0,0,0,0\n"
# ``psdm simulate`` reads --reference with a reader of its own (psdm_casadi/cli/simulate.py, _read_reference);
# these pass once it reads the file with identification.data.io.read_table and time_column.
BAD_REFERENCES = [
    reference("gzip reference", gzip.compress(REF.encode(), mtime=0), "gzip"),
    reference("reference with a BOM and NaN", "\ufeff" + REF.replace("0.1,0,", "0.1,nan,"), "column q1 holds nan"),
    reference("reference with a repeated time", REF.replace("0.1,", "0,"), "strictly increasing", "line 3"),
    reference("reference with 1e300", REF.replace("0.1,0,", "0.1,1e300,"), "column q1", "check the units"),
]


@pytest.mark.parametrize("case", BAD_REFERENCES, ids=str)
def test_bad_reference_is_refused(tmp_path, capsys, monkeypatch, case):
    check_refusal(case, tmp_path, capsys, monkeypatch)


@pytest.mark.parametrize("case", CASES, ids=str)
def test_bad_recording_is_refused(tmp_path, capsys, monkeypatch, case):
    check_refusal(case, tmp_path, capsys, monkeypatch)


def test_the_catalogue_is_complete():
    assert len(CASES) >= 45
    assert len({case.name for case in CASES}) == len(CASES)


def test_unreadable_recording(tmp_path, capsys, monkeypatch):
    """A file the user may not read (faked: the tests may run as root, who reads everything)."""

    def guarded_open(file, *args, **kwargs):
        if str(file).endswith("train.csv"):
            raise PermissionError(13, "Permission denied", str(file))
        return builtins.open(file, *args, **kwargs)

    monkeypatch.setattr(csvfile, "open", guarded_open, raising=False)
    case = train("unreadable", GOOD, "cannot be read", "permission denied", "check its permissions")
    check_refusal(case, tmp_path, capsys, monkeypatch)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes need POSIX")
def test_named_pipe_as_recording(tmp_path, capsys, monkeypatch):
    """A pipe would block the reader forever; it is refused before it is opened."""
    os.mkfifo(tmp_path / "train.csv")
    check_refusal(
        train("a named pipe", None, "not a regular file", "save the recording to a file"), tmp_path, capsys, monkeypatch
    )


def test_zip_of_other_files_named_npz(tmp_path, capsys, monkeypatch):
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("[Content_Types].xml", "<Types/>")
    case = train("xlsx named .npz", buffer.getvalue(), "not a numpy array", "numpy.savez", file="train.npz")
    check_refusal(case, tmp_path, capsys, monkeypatch)
