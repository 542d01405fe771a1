"""Each thing a command says, said once: what a new user saw repeated on the Kinova Gen3's shared logs with the vendor
URDF alone (``benchmarks/kinova_gen3.py``'s ``vendor_urdf``: its kinematics, inertials and the example's torque
constants).

``psdm identify`` printed its preparation line ("identify: 461 samples of 1 recording(s), cutoff 10 Hz") once per fit
of its route (4 times here, 8 on the example's two training recordings), the link pushed against its mass bound on
stderr and again in the envelope section (``PUSHED``); ``psdm diagnose MODEL --apply`` printed identify's line of each
refit (the report states its preparation once). Counted here in stdout + stderr of one identify and one diagnose
``--apply`` (the file's warnings, the URDF's unusable inertias among them, once per command: each is a process of its
own, and a later command repeats what the model file stores). The reference is the output itself: each line counted.
"""

from __future__ import annotations

import pytest

from psdm_casadi.cli import main
from tests.conftest import DATASETS

pytestmark = pytest.mark.real_data

KINOVA = DATASETS / "kinova_gen3_dynid"
COLUMNS = ("--columns", "t=Time,q=Position,tau=TorqueSm")
KT = (9.13,) * 4 + (5.852,) * 3  # the example's nominal torque constants (benchmarks/kinova_gen3.py)
UNUSABLE = ("the inertia of link 'shoulder_link' (joint 1) is unusable",
            "the inertia of link 'spherical_wrist_1_link' (joint 5) is unusable")  # fmt: skip


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """(identify's output, diagnose --apply's output, the model file): one run each, stdout + stderr."""
    import contextlib
    import io

    if not (KINOVA / "opti_traj_testing1.csv").exists():
        pytest.skip(f"Kinova Gen3 data absent in {KINOVA}")
    folder = tmp_path_factory.mktemp("said_once")
    robot = folder / "kinova_gen3_vendor.toml"
    drives = "".join(f"[[drive]]\nkt = {kt}\n\n" for kt in KT)
    robot.write_text(f'format = "psdm-robot/1"\nname = "kinova_gen3_vendor"\n\n[urdf]\npath = "{KINOVA / "gen3.urdf"}"'
                     f"\n\n[recording]\nsample_rate = 1000.0\n\n{drives}")  # fmt: skip
    train, held = str(KINOVA / "opti_traj_testing1.csv"), str(KINOVA / "opti_traj_testing2.csv")
    model = folder / "model.json"
    outputs = []
    for argv in (["identify", str(robot), "--data", train, "--validate", held, *COLUMNS, "--out", str(model),
                  "--no-html"],
                 ["diagnose", str(model), "--train", train, "--validate", held, *COLUMNS, "--max-effects", "1",
                  "--no-sparse", "--apply", str(folder / "applied.json")]):  # fmt: skip
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            assert main(argv) == 0, err.getvalue()
        outputs.append(out.getvalue() + err.getvalue())
    return outputs[0], outputs[1], model


def _count(text: str, start: str) -> int:
    return sum(line.startswith(start) for line in text.splitlines())


def test_identify_says_its_preparation_once_and_a_pushed_link_in_its_envelope_section(runs):
    identify, _, _ = runs
    assert _count(identify, "identify: 461 samples of 1 recording(s), cutoff 10 Hz") == 1, identify
    pushed = [line for line in identify.splitlines() if "link 7 is pushed against its mass upper bound" in line]
    assert len(pushed) == 1 and pushed[0].startswith("  PUSHED: "), pushed  # the envelope section, not stderr too
    for inertia in UNUSABLE:
        assert identify.count(inertia) == 1, inertia


def test_diagnose_apply_prints_none_of_identifys_lines_and_each_warning_once(runs):
    import json

    _, diagnose, model = runs
    assert _count(diagnose, "identify: ") == 0, diagnose
    assert "written to" in diagnose  # the refit ran and wrote its model
    for inertia in UNUSABLE:
        assert diagnose.count(inertia) == 1, inertia
    stored = json.loads(model.read_text())["warnings"]  # the model file's warnings, repeated once by diagnose
    pushed = [w for w in stored if "link 7 is pushed against its mass upper bound" in w]
    assert len(pushed) == 1 and diagnose.count(pushed[0]) == 1
