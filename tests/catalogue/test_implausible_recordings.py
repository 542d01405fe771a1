"""Recordings that cannot give a right model: refused (exit 2) or flagged, never silently a "consistent" model.

A new user's recordings with a wrong sign, unit or scale all gave ``psdm identify`` exit 0 and a model
marked consistent: positions in degrees, a time column in milliseconds, torques in mN m or of the
wrong sign, ``--offset`` on a joint that never reverses (offset and Coulomb friction of 6400 N m
cancelling), and a validation on the training file itself. Here the first kind is refused naming the
file, the column and the likely cause; the second kind writes the model but warns on stderr and in
its ``warnings`` list. Inputs: a 3-joint arm (robot file below) on the virtual robot, with its true
torques, then edited as the user's files were; the unedited recording is the control (no warning).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from identification.data.io import load_recording, save_recording
from identification.data.recording import Recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.robot import load_robot
from tests.catalogue.harness import BadInput, check_refusal
from trajopt.experiments import sine_experiment

ARM = """format = "psdm-robot/1"
name = "Arm 3R"
convention = "standard"
gravity = [0.0, 0.0, -9.81]

[[joint]]
name = "J1"
a = 0.05
alpha = "-pi/2"
d = 0.20
theta = 0.0
q_min = -2.9
q_max = 2.9
qd_max = 3.0
qdd_max = 10.0

[[joint]]
name = "J2"
a = 0.35
alpha = 0.0
d = 0.0
theta = "-pi/2"
q_min = -1.7
q_max = 1.7
qd_max = 3.0
qdd_max = 10.0

[[joint]]
name = "J3"
a = 0.30
alpha = 0.0
d = 0.0
theta = 0.0
q_min = -2.0
q_max = 2.0
qd_max = 3.5
qdd_max = 12.0

[[link]]
mass = 5.0
com = [-0.02, 0.05, 0.01]
inertia = [0.04, 0.03, 0.035, 0.002, -0.001, 0.002]

[[link]]
mass = 4.0
com = [-0.17, 0.0, 0.02]
inertia = [0.01, 0.05, 0.05, 0.001, 0.001, 0.0]

[[link]]
mass = 2.0
com = [-0.15, 0.0, 0.0]
inertia = [0.004, 0.02, 0.02, 0.0, 0.0, 0.0]

[[drive]]
kt = 30.0
fc = 5.0
fs = 6.5
vs = 0.02
fv = 10.0
dv = 0.6
sigma0 = 200000.0
sigma1 = 20.0

[[drive]]
kt = 30.0
fc = 4.0
fs = 5.0
vs = 0.02
fv = 8.0
dv = 0.6
sigma0 = 150000.0
sigma1 = 18.0

[[drive]]
kt = 20.0
fc = 2.0
fs = 2.6
vs = 0.03
fv = 4.0
dv = 0.7
sigma0 = 80000.0
sigma1 = 12.0
"""


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """(folder, robot file, good recording): 8 s of sines on the virtual arm, joint torques with friction."""
    folder = tmp_path_factory.mktemp("arm")
    robot_file = folder / "arm.toml"
    robot_file.write_text(ARM)
    robot = load_robot(robot_file)
    rng = np.random.default_rng(3)
    reference = sine_experiment(robot, duration=8.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.05, friction=True)
    recording, _ = simulate_recording(robot, reference, options, rng)
    save_recording(recording, folder / "good.csv")
    return folder, robot_file, load_recording(folder / "good.csv")


def _variant(arm, name, **signals) -> str:
    """The good recording with ``signals`` replaced, as CSV text (a file the case writes)."""
    folder, _, good = arm
    save_recording(good.with_signals(**signals), folder / name, overwrite=True)
    return (folder / name).read_text()


def _identify(arm, name, text, expect, *extra):
    argv = ("identify", str(arm[1]), "--data", name, "--out", "m.json", *extra)
    return BadInput(name, argv, expect, files={name: text})


def test_positions_in_degrees_are_refused_by_identify_validate_and_diagnose(arm, tmp_path, capsys, monkeypatch):
    text = _variant(arm, "degrees.csv", q=np.degrees(arm[2].q))
    expect = ("degrees.csv", "column q1", "beyond the joint limits", "degrees?", "radians")
    check_refusal(_identify(arm, "degrees.csv", text, expect), tmp_path, capsys, monkeypatch)
    argv = ("diagnose", str(arm[1]), "--train", "good.csv", "--validate", "degrees.csv")
    files = {"good.csv": (arm[0] / "good.csv").read_text(), "degrees.csv": text}
    check_refusal(BadInput("diagnose degrees", argv, expect, files=files), tmp_path, capsys, monkeypatch)
    model = tmp_path.parent / f"{tmp_path.name}_model.json"
    assert main(["identify", str(arm[1]), "--data", str(arm[0] / "good.csv"), "--out", str(model)]) == 0
    argv = ("validate", str(model), "degrees.csv")
    check_refusal(BadInput("validate degrees", argv, expect), tmp_path, capsys, monkeypatch)


def test_a_time_column_in_milliseconds_is_refused_with_the_unit_named(arm, tmp_path, capsys, monkeypatch):
    good = arm[2]
    millis = Recording(t=1000.0 * good.t, q=good.q, tau=good.tau, name="millis.csv")
    save_recording(millis, arm[0] / "millis.csv", overwrite=True)
    expect = ("millis.csv", "milliseconds", "divide it by 1000")
    check_refusal(_identify(arm, "millis.csv", (arm[0] / "millis.csv").read_text(), expect), tmp_path, capsys,
                  monkeypatch)  # fmt: skip


def test_offset_on_a_joint_that_never_reverses_is_refused(arm, tmp_path, capsys, monkeypatch):
    good = arm[2]
    q = good.q.copy()
    q[:, 0] = -2.5 + 4.5 * (good.t - good.t[0]) / (good.t[-1] - good.t[0])  # joint 1 sweeps one way at 0.6 rad/s
    text = _variant(arm, "oneway.csv", q=q)
    expect = ("oneway.csv", "joint 1 (J1)", "both ways", "100 % of the samples positive", "drop --offset")
    case = _identify(arm, "oneway.csv", text, expect, "--offset")
    check_refusal(case, tmp_path, capsys, monkeypatch)
    # without --offset there is nothing to confuse its Coulomb friction with: the same file is identified
    monkeypatch.chdir(tmp_path)
    assert main(["identify", str(arm[1]), "--data", "oneway.csv", "--out", "plain.json"]) == 0


def _identified(arm, tmp_path, capsys, name, *extra, **signals):
    """exit code, stderr and the written document of ``psdm identify`` (options ``extra``) on the good recording with
    ``signals``."""
    path = tmp_path / name
    path.write_text(_variant(arm, name, **signals) if signals else (arm[0] / "good.csv").read_text())
    capsys.readouterr()
    code = main(["identify", str(arm[1]), "--data", str(path), "--out", str(tmp_path / f"{name}.json"), *extra])
    err = capsys.readouterr().err
    document = json.loads((tmp_path / f"{name}.json").read_text()) if code == 0 else None
    return code, err, document


def test_the_good_recording_is_identified_without_warnings(arm, tmp_path, capsys):
    code, err, document = _identified(arm, tmp_path, capsys, "good.csv")
    assert code == 0 and "warning" not in err and document["warnings"] == []
    assert document["standard"]["consistent"]


def test_torques_of_the_wrong_sign_are_flagged_in_stderr_and_the_file(arm, tmp_path, capsys):
    """The fit's check of its friction (``trajectory_checks``) warns. Without the counterbalance trial: the flipped
    gravity has the envelope report name a spring on joints 2 and 3, whose trial over the blocks was most of the run
    and is not what is read here (test_counterbalance_column tries the route)."""
    code, err, document = _identified(arm, tmp_path, capsys, "signflip.csv", "--no-counterbalance", tau=-arm[2].tau)
    assert code == 0
    assert "negative friction" in err and "Torque sign or joint mapping wrong?" in err and "tau1" in err
    assert any("negative friction" in w and "joint 1" in w for w in document["warnings"])


def test_torques_of_two_joints_swapped_are_flagged(arm, tmp_path, capsys):
    tau = arm[2].tau[:, [1, 0, 2]]
    code, err, document = _identified(arm, tmp_path, capsys, "swapped.csv", tau=tau)
    assert code == 0 and "mapping wrong" in err and "tau1" in err and "tau2" in err
    assert any("mapping wrong" in w and "joint 1" in w for w in document["warnings"])


def test_torques_in_milli_newton_metres_are_refused_before_any_fit(arm, tmp_path, capsys):
    """Every joint's torque about 1000x what the robot file predicts for the motion: refused naming the unit
    (``plausibility.check_torque_magnitude``), not fitted into link masses an order of magnitude off."""
    code, err, document = _identified(arm, tmp_path, capsys, "mNm.csv", tau=1000.0 * arm[2].tau)
    assert code == 2 and document is None and "Traceback" not in err
    assert "mNm.csv" in err and "mN m?" in err and "--columns t=t,q=q,tau=tau:mNm" in err  # the file's own names
    factor = float(err.split("the recorded torque is about ")[1].split(" times")[0])
    assert factor == pytest.approx(1000.0, rel=0.3)
    assert "pushed against" not in err  # the unit, not a payload, is named


def test_validating_on_the_training_file_warns_that_it_is_not_held_out(arm, tmp_path, capsys, monkeypatch):
    """identify warns; Coulomb-viscous friction asked: the arm's LuGre friction lags at the validation recording's
    reversals, and the LuGre trial that opens was most of each run (test_held_out_load's identify runs it)."""
    good = arm[0] / "good.csv"
    out = tmp_path / "same.json"
    shape = ("--friction", "coulomb-viscous")
    assert main(["identify", str(arm[1]), "--data", str(good), "--validate", str(good), "--out", str(out), *shape]) == 0
    err = capsys.readouterr().err
    assert "NOT held out" in err and any("NOT held out" in w for w in json.loads(out.read_text())["warnings"])
    copy = tmp_path / "copy.csv"  # a byte-identical copy is the same recording too
    copy.write_bytes(good.read_bytes())
    out2 = tmp_path / "copy.json"
    argv = ["identify", str(arm[1]), "--data", str(good), "--validate", str(copy), "--out", str(out2), *shape]
    assert main(argv) == 0
    assert "NOT held out" in capsys.readouterr().err
    # diagnose warns as soon as it has read the pair (here it then refuses the still joint 3, which is quicker)
    q = arm[2].q.copy()
    q[:, 2] = q[0, 2]
    text = _variant(arm, "still.csv", q=q)
    argv = ("diagnose", str(arm[1]), "--train", "still.csv", "--validate", "still.csv")
    case = BadInput("diagnose on one file", argv, ("NOT held out", "joint 3"), files={"still.csv": text})
    (tmp_path / "diagnose").mkdir()
    check_refusal(case, tmp_path / "diagnose", capsys, monkeypatch)
