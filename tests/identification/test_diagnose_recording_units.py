"""``diagnose()`` refuses recordings in the wrong units as ``psdm diagnose`` does: the check is in the library.

A Python user who passes positions in degrees or a time column in milliseconds gets the same
``RecordingError`` (the command line's exit 2) naming the recording and the likely unit, before any fit.
The same recordings in SI units pass that check and reach the next one (a joint held still is refused by
the motion check), which shows that the refusal is about the units.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.data.recording import Recording
from identification.diagnosis import diagnose
from psdm_casadi.errors import InsufficientExcitationError, RecordingError
from tests.identification.diagnosis_data import recording_pair


@pytest.fixture(scope="module")
def pair(denso):
    train, validation = recording_pair(denso, [], seed=7, train_s=4.0, val_s=3.0)
    return train.with_signals(name="train.csv"), validation.with_signals(name="valid.csv")


def test_positions_in_degrees_are_refused_by_the_python_api(denso, denso_model, pair):
    train, validation = pair
    degrees = train.with_signals(q=np.degrees(train.q))
    with pytest.raises(RecordingError, match=r"train\.csv.*positions in degrees\? Convert q1 to radians"):
        diagnose(denso, degrees, validation, model=denso_model)
    with pytest.raises(RecordingError, match=r"valid\.csv.*positions in degrees\?"):
        diagnose(denso, train, validation.with_signals(q=np.degrees(validation.q)), model=denso_model)


def test_a_time_column_in_milliseconds_is_refused_by_the_python_api(denso, denso_model, pair):
    train, validation = pair
    millis = Recording(t=1000.0 * validation.t, q=validation.q, tau=validation.tau, name="valid_ms.csv")
    with pytest.raises(RecordingError, match=r"valid_ms\.csv.*milliseconds.*divide it by 1000"):
        diagnose(denso, train, millis, model=denso_model)


def test_the_same_recordings_in_si_units_pass_the_unit_check(denso, denso_model, pair):
    train, validation = pair
    q = validation.q.copy()
    q[:, 5] = q[0, 5]  # the next check, the motion check, refuses it: the units were accepted
    with pytest.raises(InsufficientExcitationError, match=r"valid\.csv.*joint 6") as caught:
        diagnose(denso, train, validation.with_signals(q=q), model=denso_model)
    assert "degrees" not in str(caught.value) and "milliseconds" not in str(caught.value)
