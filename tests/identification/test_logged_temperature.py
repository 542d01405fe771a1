"""The joints' logged temperatures read with the recording (``data.temperature``, ``io``, ``csvfile``, ``table``).

Reference: the values written into the files (known synthetic truth). A controller logs temperatures slowly: the
readers keep them with the recording, NaN between readings, in every CSV spelling the project reads (UTF-16, a
semicolon with decimal commas, quoted names), in NPZ archives, and under ``--columns``; positions and torques keep
their strict NaN handling.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.data.io import load_recording, save_recording
from identification.data.layout import ColumnLayout
from identification.data.recording import Recording
from identification.data.temperature import logged_temperatures, temperature_joints
from psdm_casadi.errors import RecordingError

N = 40  # samples
EVERY = 10  # a temperature reading every EVERY samples (a slow logger)


def _columns():
    """(t, q (N, 2), tau (N, 2), temperature (N, 2) with NaN between its readings, its per-joint mean)."""
    t = np.arange(N) * 0.01
    q = np.column_stack([np.sin(t), np.cos(t)])
    tau = np.column_stack([0.5 + t, -1.25 + 2 * t])
    temperature = np.full((N, 2), np.nan)
    temperature[::EVERY] = np.column_stack([30.0 + np.arange(N // EVERY), 41.5 + 0.5 * np.arange(N // EVERY)])
    return t, q, tau, temperature, np.array([31.5, 42.25])


def _text(names, rows, delimiter=",", decimal=".", quoted=False, empty="") -> str:
    head = delimiter.join(f'"{n}"' if quoted else n for n in names)
    lines = [delimiter.join(empty if np.isnan(v) else f"{v:.6f}".replace(".", decimal) for v in row) for row in rows]
    return "\n".join([head, *lines]) + "\n"


@pytest.mark.parametrize(
    "names, delimiter, decimal, quoted, encoding",
    [
        pytest.param(("t", "q1", "q2", "tau1", "tau2", "Temp1", "Temp2"), ",", ".", False, "utf-8", id="Kinova names"),
        pytest.param(("t", "q1", "q2", "tau1", "tau2", "temp1", "temp2"), "\t", ".", False, "utf-16", id="UTF-16"),
        pytest.param(
            ("t", "q1", "q2", "tau1", "tau2", "temperature_1", "temperature_2"),
            ";",
            ",",
            False,
            "utf-8",
            id="semicolon, decimal comma",
        ),
        pytest.param(
            ("t", "q1", "q2", "tau1", "tau2", "joint_temperatures_0", "joint_temperatures_1"),
            ",",
            ".",
            True,
            "utf-8",
            id="quoted names numbered from 0",
        ),
    ],
)
def test_a_csv_file_keeps_its_sparse_temperature_columns_with_the_recording(tmp_path, names, delimiter, decimal,
                                                                            quoted, encoding):  # fmt: skip
    """Empty cells between the readings are NaN; each joint's mean is its readings' mean; q and tau as written."""
    t, q, tau, temperature, mean = _columns()
    path = tmp_path / "run.csv"
    path.write_text(_text(names, np.column_stack([t, q, tau, temperature]), delimiter, decimal, quoted),
                    encoding=encoding)  # fmt: skip
    recording = load_recording(path, n_dof=2)
    np.testing.assert_allclose(recording.q, q, atol=1e-6)
    np.testing.assert_allclose(recording.tau, tau, atol=1e-6)
    np.testing.assert_array_equal(np.isnan(recording.temperature), np.isnan(temperature))
    np.testing.assert_allclose(logged_temperatures(recording), mean, rtol=1e-9)
    halves = recording.split(0.5)  # the samples of each part keep their temperatures
    np.testing.assert_allclose(logged_temperatures(halves[1]), [32.5, 42.75], rtol=1e-9)


def test_a_temperature_column_with_nan_gaps_is_kept_where_a_nan_position_is_refused(tmp_path):
    """``nan`` written between readings (and a joint never logged) is kept; a NaN in q1 alone still is refused."""
    t, q, tau, temperature, mean = _columns()
    temperature[:, 1] = np.nan
    path = tmp_path / "gaps.csv"
    np.savetxt(path, np.column_stack([t, q, tau, temperature]), delimiter=",", comments="",
               header="t,q1,q2,tau1,tau2,Temp1,Temp2")  # fmt: skip
    recording = load_recording(path, n_dof=2)
    assert np.isnan(recording.temperature[:, 1]).all()
    assert np.nanmean(recording.temperature[:, 0]) == pytest.approx(mean[0])
    assert logged_temperatures(recording) is None  # joint 2 logs none: no mean for every joint
    bad = q.copy()
    bad[5, 0] = np.nan
    np.savetxt(path, np.column_stack([t, bad, tau, temperature]), delimiter=",", comments="",
               header="t,q1,q2,tau1,tau2,Temp1,Temp2")  # fmt: skip
    with pytest.raises(RecordingError, match="column q1 holds nan"):
        load_recording(path, n_dof=2)
    with pytest.raises(RecordingError, match="temperature must be finite or NaN"):
        Recording(t=t, q=q, tau=tau, temperature=np.where(np.isnan(temperature), np.inf, temperature))


def test_temperatures_round_trip_through_npz_and_csv_and_are_read_under_columns(tmp_path):
    """``save_recording`` writes ``temp1..tempn`` (NaN kept); NPZ reads them alike; ``--columns`` keeps them."""
    t, q, tau, temperature, mean = _columns()
    recording = Recording(t=t, q=q, tau=tau, temperature=temperature, name="run")
    for suffix in (".csv", ".npz"):
        back = load_recording(save_recording(recording, tmp_path / f"run{suffix}"), n_dof=2)
        np.testing.assert_array_equal(back.temperature, temperature)
    log = tmp_path / "log.csv"
    names = ("Time", "Position1", "Position2", "TorqueSm1", "TorqueSm2", "Temp1", "Temp2", "Ref1")
    rows = np.column_stack([t, q, tau, temperature, np.full(N, np.nan)])
    log.write_text(_text(names, rows, empty="nan"))
    layout = ColumnLayout.parse("t=Time,q=Position,tau=TorqueSm")
    np.testing.assert_allclose(logged_temperatures(load_recording(log, 2, layout=layout)), mean, rtol=1e-9)
    assert temperature_joints(("Temp0", "Temp1", "T_motor3")) == {"Temp0": 1, "Temp1": 2}
    assert load_recording(save_recording(Recording(t=t, q=q, tau=tau), tmp_path / "plain.csv"), 2).temperature is None


def test_temperatures_follow_the_samples_through_resampling_and_decimation():
    """An uneven recording resampled for the filter gets its readings interpolated at the new times (held beyond the
    ends); decimation keeps every step-th sample's reading; the prepared recording keeps its raw one's mean."""
    from identification.calibration.preparation import decimate
    from identification.data.preprocessing import PreprocessOptions, preprocess

    t = np.cumsum(np.r_[0.0, np.where(np.arange(299) % 7 == 0, 0.0125, 0.01)])
    q = np.column_stack([np.sin(t), np.cos(t)])
    temperature = np.full((300, 2), np.nan)
    temperature[::30] = np.column_stack([30.0 + 2.0 * t[::30], 40.0 - t[::30]])
    recording = Recording(t=t, q=q, tau=q, temperature=temperature)
    prepared = preprocess(recording, PreprocessOptions(cutoff_hz=5.0))
    assert prepared.n_samples != recording.n_samples and not np.isnan(prepared.temperature).any()
    last = t[::30][-1]
    expected = np.column_stack([30.0 + 2.0 * np.minimum(prepared.t, last), 40.0 - np.minimum(prepared.t, last)])
    np.testing.assert_allclose(prepared.temperature, expected, rtol=1e-12)
    halved = decimate(prepared, 0.5 / prepared.dt)
    np.testing.assert_array_equal(halved.temperature, prepared.temperature[::2])
