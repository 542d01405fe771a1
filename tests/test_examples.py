"""The examples run as scripts and end with their own assertions."""

import runpy
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize(
    "name",
    [
        "min_torque_motion.py",
        "mpc_tracking.py",
        pytest.param("mpc_rti_calibrated.py", marks=[pytest.mark.slow, pytest.mark.needs_cc]),  # identifies first
    ],
)
def test_example_runs(name, monkeypatch):
    monkeypatch.setattr("sys.argv", [name])
    runpy.run_path(str(EXAMPLES / name), run_name="__main__")
