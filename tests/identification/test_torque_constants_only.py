"""Recordings of motor currents with a robot file whose drives give torque constants alone (no friction prior).

A real controller's drive table often states ``kt`` and nothing about friction. Every command must then read
the currents through ``kt`` and identify the friction from the recordings (it used to refuse: "LuGreParameters.fc
must be finite and > 0; got 0.0").
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from identification.data.io import save_recording
from identification.data.recording import Recording
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.robot import load_robot
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment


@pytest.fixture(scope="module")
def kt_only(tmp_path_factory, denso):
    """(robot file with kt-only drives, training and validation recordings of currents with a hidden spring)."""
    folder = tmp_path_factory.mktemp("kt_only")
    text = re.sub(r"(?m)^(fc|fs|vs|fv|dv|sigma0|sigma1) = .*\n", "", DENSO_FILE.read_text())
    robot_file = folder / "denso_kt.toml"
    robot_file.write_text(text)
    assert all(d.fc == 0 for d in load_robot(robot_file).drives)
    paths = []
    for k, duration in enumerate((8.0, 4.0)):
        rng = np.random.default_rng(60 + k)
        reference = sine_experiment(denso, duration=duration, rng=rng).reference()
        options = SimulationOptions(record_tau=False, record_current=True, current_noise_std=0.002)
        recording, _ = simulate_recording(denso, reference, options, rng, extras=[xp.Spring(joint=1, stiffness=40.0)])
        currents = Recording(t=recording.t, q=recording.q, current=recording.current, name=f"run{k}")
        paths.append(save_recording(currents, folder / f"run{k}.csv"))
    return robot_file, paths


def test_currents_with_torque_constants_alone_go_through_diagnose(kt_only, capsys):
    robot_file, (train, validate) = kt_only
    args = ["diagnose", str(robot_file), "--train", str(train), "--validate", str(validate), "--json"]
    assert main([*args, "--max-effects", "1", "--no-sparse"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["findings"][0]["effect"] == "spring" and out["findings"][0]["joints"] == [2]
    assert out["findings"][0]["parameters"]["k"] == pytest.approx(40.0, rel=0.2)


@pytest.mark.slow
def test_currents_with_torque_constants_alone_go_through_identify_and_validate(kt_only, tmp_path, capsys):
    robot_file, (train, validate) = kt_only
    model = tmp_path / "model.json"
    assert main(["identify", str(robot_file), "--data", str(train), "--out", str(model), "--json"]) == 0
    capsys.readouterr()
    assert main(["validate", str(model), str(validate), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert max(out["recordings"][0]["r2"]) > 0.9 and min(out["recordings"][0]["r2"]) > 0.5
