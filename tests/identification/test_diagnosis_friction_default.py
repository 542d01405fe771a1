"""``psdm diagnose`` of a robot file whose drives state torque constants but no friction: Coulomb + viscous by default.

Such a file (the Kinova example: the vendor's torque constants only) has no Stribeck velocity to take;
the steady-state LuGre default would guess vs = 0.01 rad/s, whose column is zero on a joint that never
slows down (the Kinova's joint 5: the diagnosis refused the recording). A robot file with a friction
prior keeps its LuGre shape.
"""

from __future__ import annotations

import importlib
import re

from identification.data.io import save_recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.errors import ParameterError
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment


def test_a_robot_file_without_friction_is_diagnosed_with_coulomb_viscous(denso, tmp_path, monkeypatch, capsys, rng):
    diagnose_module = importlib.import_module("identification.diagnosis.diagnose")
    paths = []
    for name, duration in (("train", 2.0), ("validate", 2.0)):
        rec, _ = simulate_recording(
            denso, sine_experiment(denso, duration=duration, rng=rng).reference(), SimulationOptions(), rng
        )
        paths.append(str(save_recording(rec, tmp_path / f"{name}.npz")))
    kt_only = re.sub(r"(?m)^(fc|fs|vs|fv|dv|sigma0|sigma1) = .*\n", "", DENSO_FILE.read_text())
    (tmp_path / "kt_only.toml").write_text(kt_only)
    seen = []

    def spy(robot, train, validation, options, model=None, derive=None):  # records the choice, stops there
        seen.append(options.friction)  # "auto": the library chooses (as diagnose() resolves it)
        seen.append(options.for_recording(train, robot).friction)
        raise ParameterError("stopped by the test")

    monkeypatch.setattr(diagnose_module, "diagnose", spy)
    quick = ["--train", paths[0], "--validate", paths[1]]
    assert main(["diagnose", str(tmp_path / "kt_only.toml"), *quick]) == 2
    assert "drives state no friction: nominal friction Coulomb + viscous" in capsys.readouterr().err
    assert main(["diagnose", str(DENSO_FILE), *quick]) == 2
    assert seen == ["auto", "coulomb_viscous", "auto", "lugre"]
