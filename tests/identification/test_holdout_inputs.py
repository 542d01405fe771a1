"""``--holdout`` and the held-out parts under the mistakes a new user makes: a recording too short to cut, a recording
moved or changed after identify. Each must be a clear message (exit 2) naming the input and the fix, before any work.

Reference: the preparation itself (``prepare_recording``, the filter and the edge trim identify applies to each part):
the fractions the message offers must give two parts it prepares, the refused one a part it refuses.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.calibration.trajectory_data import prepare_recording
from identification.data.holdout import cut_recording
from identification.data.io import save_recording
from identification.data.recording import Recording
from psdm_casadi.cli import main
from psdm_casadi.errors import RecordingError
from tests.conftest import DENSO_FILE

RATE = 1000.0


def _recording(n_samples: int, n_dof: int = 6, name: str = "run.csv") -> Recording:
    """Slow sines of small amplitude (inside every joint's limits) and a torque that follows them."""
    t = np.arange(n_samples) / RATE
    q = 0.2 * np.sin(2 * np.pi * 0.5 * t[:, None] + np.arange(n_dof))
    return Recording(t=t, q=q, tau=3.0 * q + 0.1, name=name)


def test_a_part_too_short_to_prepare_is_refused_with_the_fractions_that_work(tmp_path):
    """RunTrajectory1 of the Kinova logs: 1942 samples at 1 kHz. ``--holdout 0.3`` leaves 0.58 s, which the 10 Hz
    filter with three periods trimmed at each end cannot keep: refused when cut (naming the part, its length and the
    fractions that work), not by the preparation after the fit as '0.582 s is too short ... record at least 1.2 s'
    of a recording that lasts 1.94 s."""
    recording, path = _recording(1942, n_dof=1), tmp_path / "RunTrajectory1.csv"
    save_recording(recording, path)
    with pytest.raises(RecordingError) as refused:
        cut_recording(recording, 0.3, path)
    message = str(refused.value)
    assert "leaves 0.583 s of RunTrajectory1.csv (1.94 s) as its held-out part (583 of 1942 samples)" in message
    assert "--validate instead of --data" in message
    low, high = (float(x) for x in message.split("Use --holdout between ")[1].split(" for it")[0].split(" and "))
    for fraction in (low, high):  # the offered bounds: both parts prepared
        train, held, _ = cut_recording(recording, fraction, path)
        prepare_recording(train)
        prepare_recording(held)
    short = recording.slice(int(round(1 - 0.3, 12) * 1942), None)  # the refused part: the preparation refuses it too
    with pytest.raises(RecordingError, match="too short to filter"):
        prepare_recording(short)
    with pytest.raises(RecordingError, match="No --holdout leaves two such parts"):
        cut_recording(_recording(1100, n_dof=1), 0.5, path)  # 1.1 s: no cut leaves two parts of 0.62 s


def test_identify_with_recordings_of_different_lengths_names_the_short_one_before_any_fit(tmp_path, capsys):
    """Several --data recordings, one too short for the cut: exit 2 naming it, no model written, no traceback."""
    long, short = tmp_path / "long.csv", tmp_path / "short.csv"
    save_recording(_recording(6000, name="long.csv"), long)
    save_recording(_recording(1942, name="short.csv"), short)
    out = tmp_path / "m.json"
    argv = ["identify", str(DENSO_FILE), "--data", str(long), str(short), "--holdout", "0.3", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--holdout 0.3 leaves 0.583 s of short.csv" in err and "long.csv" not in err
    assert "Traceback" not in err and "identify: choosing" not in err and not out.exists()
