"""A fleet worker's memory: what a robot-day task imports, and a preparation that holds one joint at full rate."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from identification.calibration.trajectory_data import prepare_recording
from identification.data.filter_choice import choose_filter, kept_samples
from identification.data.preprocessing import central_difference, zero_phase_filter
from identification.data.recording import Recording


def test_a_robot_day_task_does_not_import_the_client_side_libraries():
    """A Dask worker imports the task's module only: no DuckDB (the client writes), no plotting (the report), no
    Dask client, and MuJoCo only when an MJCF file is read (a lazy module until then)."""
    code = (
        "import sys, identification.fleet.session as s\n"
        "loaded = sorted({m.split('.')[0] for m in sys.modules})\n"
        "print(' '.join(loaded))\n"
        "print(' '.join(m for m in sys.modules if m.startswith('mujoco.')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.splitlines()
    loaded = set(out[0].split())
    assert {"identification", "casadi", "numpy"} <= loaded  # the probe sees the task's own imports
    assert not loaded & {"duckdb", "plotly", "matplotlib", "pandas"}, loaded
    assert out[1:] == [""] or out[1:] == [], out  # mujoco's submodules (its compiled library) not loaded


def test_the_preparation_joint_by_joint_equals_filtering_the_whole_arrays(rng):
    """prepare_recording filters, differentiates and decimates one joint at a time; the values are exactly those of
    filtering the whole arrays and keeping every step-th sample (the former code, written out here)."""
    t = np.arange(6000) / 1000.0
    q = np.column_stack([np.sin(2.0 * t + k) + 0.01 * rng.standard_normal(t.size) for k in range(3)])
    current = np.column_stack([np.cos(3.0 * t * (k + 1)) + 0.05 * rng.standard_normal(t.size) for k in range(3)])
    kt = np.array([0.5, 0.7, 0.9])
    recording = Recording(t=t, q=q, current=current, name="probe")
    prepared, cutoff, step = prepare_recording(recording, kt)
    rate = 1.0 / recording.dt  # as the preparation takes it
    assert (cutoff, step) == choose_filter(rate)
    keep = kept_samples(t.size, rate, cutoff, step)
    q_f = zero_phase_filter(q, rate, cutoff)
    qd, qdd = central_difference(t, q_f)
    tau = zero_phase_filter(current * kt, rate, cutoff)
    for name, whole in (("q", q_f), ("qd", qd), ("qdd", qdd), ("tau", tau)):
        assert np.array_equal(getattr(prepared, name), whole[keep]), name
    assert np.array_equal(prepared.t, t[keep])
    assert np.array_equal(recording.joint_torque(kt, 1), (current * kt)[:, 1])
