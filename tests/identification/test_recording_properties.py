"""Property: whatever bytes a recording file holds, reading it gives a Recording or a clean error, nothing else.

The clean errors are :class:`RecordingError`, :class:`ParameterError` and :class:`ShapeError` (whose
messages the command prints in one line); any other exception would reach the user as a traceback.
Bytes are drawn three ways: arbitrary, CSV-like text built from the tokens of the format (so the
draws reach the parser and the column checks), and real NPZ archives with corrupted bytes.
"""

from __future__ import annotations

import io
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from identification.data.io import load_recording
from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, RecordingError, ShapeError

SETTINGS = settings(
    max_examples=200, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow], database=None
)
CLEAN = (RecordingError, ParameterError, ShapeError)

TOKENS = st.sampled_from(
    ["t", "q1", "q2", "tau1", "tau2", "i1", "qd1", "qdd1", "x", "q0", "tau3", "T", '"t"']
    + ["0", "1", "2", "-1", "0.5", "1e3", "1e300", "1e400", "nan", "inf", "-inf", "abc", "", " ", "1_0", "0,5"]
    + [",", ",", ",", ";", "\t", "#", "\n", "\n", "\r\n", "\ufeff", "\xb0", "\x00"]
)
CSV_LIKE = st.lists(TOKENS, max_size=60).map("".join)
ENCODINGS = st.sampled_from(["utf-8", "latin-1", "utf-16"])


def read(content: bytes, suffix: str, n_dof=None):
    """Write ``content`` to a fresh file and read it; the Recording or the exception it raised."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"rec{suffix}"
        path.write_bytes(content)
        try:
            return load_recording(path, n_dof)
        except CLEAN as exc:
            assert str(exc), "an error without a message"
            return exc


def check(outcome) -> None:
    if isinstance(outcome, Recording):
        assert outcome.n_samples >= 3 and np.all(np.diff(outcome.t) > 0)
        assert np.all(np.isfinite(outcome.q))
    else:
        assert isinstance(outcome, CLEAN)


@SETTINGS
@given(content=st.binary(max_size=400))
def test_any_bytes_as_csv(content):
    check(read(content, ".csv"))


@SETTINGS
@given(text=CSV_LIKE, encoding=ENCODINGS, n_dof=st.sampled_from([None, 1, 2]))
def test_csv_like_text(text, encoding, n_dof):
    check(read(text.encode(encoding, errors="replace"), ".csv", n_dof))


@SETTINGS
@given(rows=st.integers(0, 6), extra=st.lists(TOKENS, max_size=6).map(",".join), seed=st.integers(0, 2**16))
def test_valid_header_with_mangled_rows(rows, extra, seed):
    rng = np.random.default_rng(seed)
    lines = ["t,q1,tau1"] + [f"{k * 1e-3},{rng.normal():.6g},{rng.normal():.6g}" for k in range(rows)]
    lines.insert(int(rng.integers(1, len(lines) + 1)), extra)
    check(read(("\n".join(lines) + "\n").encode(), ".csv", 1))


@SETTINGS
@given(content=st.binary(max_size=400))
def test_any_bytes_as_npz(content):
    check(read(content, ".npz"))


COLUMN = hnp.arrays(
    dtype=st.sampled_from([np.float64, np.float32, np.int16, np.uint8, np.bool_, np.complex64, np.dtype("<U2")]),
    shape=hnp.array_shapes(min_dims=0, max_dims=2, max_side=5),
)


@SETTINGS
@given(
    columns=st.dictionaries(st.sampled_from(["t", "q1", "tau1", "i1", "x"]), COLUMN, max_size=4),
    cut=st.integers(0, 2000),
    flips=st.lists(st.tuples(st.integers(0, 2000), st.integers(0, 255)), max_size=3),
)
def test_corrupted_npz_archives(columns, cut, flips):
    buffer = io.BytesIO()
    np.savez(buffer, **columns)
    content = bytearray(buffer.getvalue())
    for position, value in flips:
        if position < len(content):
            content[position] = value
    if cut < len(content) and flips:
        content = content[:cut]
    check(read(bytes(content), ".npz"))


@SETTINGS
@given(
    n=st.integers(3, 8),
    values=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=3, max_size=8),
)
def test_npz_with_any_float_values(n, values):
    q = np.resize(np.asarray(values), n)
    buffer = io.BytesIO()
    np.savez(buffer, t=np.arange(n) * 1e-3, q1=q, tau1=q[::-1].copy())
    check(read(buffer.getvalue(), ".npz", 1))
