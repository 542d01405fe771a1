"""What the consistent fit holds back from the data (issue 25, item 1: the report says what it is not sure of).

References: the virtual robot's hidden truth (an inertia about joint 1 beyond what the robot file's links and drive
bounds allow: the data's own estimate must equal the true base parameter within its standard deviations, and the fit
must be named as holding it back), a clean virtual robot (nothing named), the model's own mass matrix and gravity
regressor for the words (an inertia about a joint enters only that joint's diagonal entry, constantly), and the
shared Kinova Gen3 recording (slow; its inertia about joint 1: least squares 3.2 +/- 0.65 against the fit's 1.16).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from identification.calibration.absorbed_effect import likely_effects
from identification.calibration.calibrated_model import load_calibrated_model
from identification.calibration.envelope_report import ABSORBED_EFFECTS
from identification.calibration.held_back import HELD_BACK_SIGMA, ROUGH_FILE, parameter_words, stored_held_back
from identification.calibration.identify_route import identify_recordings
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.robot import load_robot
from tests.conftest import DATASETS, ROOT
from tests.identification.diagnosis_data import rigid_recording
from trajopt.experiments import sine_experiment

HIDDEN = 3.0  # [kg m^2] on joint 1, whose drive inertia the bounds hold to 2 x the file's 1.0


def _hidden_inertia(robot):
    return [xp.ExtraRotorInertia(inertia=np.array([HIDDEN] + [0.0] * (robot.n_dof - 1)))]


def _true_theta(robot, model):
    truth = robot.nominal_dynamic_parameters().copy()
    truth[0, -1] += HIDDEN
    return model.base_parameters(truth)


def test_the_words_follow_the_mass_matrix_and_the_gravity_regressor(denso, denso_model):
    """The inertia about joint j holds joint j's rotor inertia (Im_j, about the joint's axis by definition); a
    parameter named a gravity torque is one of the model's gravity parameters, and no other is."""
    rotor = [f"Im{j + 1}" for j in range(denso.n_dof)]
    for k in range(denso_model.n_base):
        words, joint, kind = parameter_words(denso_model, denso, k)
        row = dict(zip(denso_model.standard_names, denso_model.parameter_map[k]))
        assert (kind == "gravity") == bool(denso_model.gravity_mask[k]), (k, words)
        if kind == "axis":
            assert words.startswith(f"the inertia about joint {joint + 1} ")
            assert abs(row[rotor[joint]]) == pytest.approx(1.0)
        with_rotor = [j for j in range(denso.n_dof) if abs(row[rotor[j]]) > 0]
        if with_rotor and not denso_model.gravity_mask[k]:
            assert kind == "axis" and joint == with_rotor[0], (k, words)


@pytest.fixture(scope="module")
def hidden(denso, denso_model):
    """``(recording, fit)``: the 8 s recording of the Denso with the hidden inertia and its default fit."""
    recording = rigid_recording(denso, _hidden_inertia(denso))
    return recording, identify_trajectories(denso, denso_model, [recording], TrajectoryOptions())


def test_a_hidden_inertia_beyond_the_files_links_is_named_with_the_datas_value(denso, denso_model, hidden):
    fit = hidden[1]
    held = stored_held_back(fit.envelope_bounds)
    assert len(held) == 1, [h.message for h in held]  # the links' gravity terms it moved are side effects, not named
    item = held[0]
    k = denso_model.base_names.index(item.parameter)
    assert item.words.startswith("the inertia about joint 1 ") and item.joint == 0
    assert item.absorbs == "drive_inertia" and item.absorbs in ABSORBED_EFFECTS
    truth = _true_theta(denso, denso_model)[k]
    assert abs(item.data - truth) <= 3 * item.data_std, (item.data, truth, item.data_std)
    assert item.fitted < truth - HELD_BACK_SIGMA * item.data_std  # the fit keeps it below what the data want
    assert item.holder == "envelope"  # joint 1's drive inertia is on its upper bound (the envelope report says so)
    assert any(f.link == 0 and "drive inertia upper" in f.bounds for f in fit.envelope)
    assert "the data want" in item.message and "psdm diagnose" in item.message
    assert "extra inertia on joint 1" in item.message


def test_the_gravity_departure_the_held_back_inertia_makes_names_no_counterbalance(denso, denso_model, hidden):
    """The links' first moments take part of the held-back inertia's torque, so joint 1's fitted gravity torque
    leaves the file's (the truth's gravity is the file's: Pinocchio-free, the hidden effect is an inertia). The data's
    own least squares keep the file's gravity there: the departure is stored as the held-back inertia's, with the
    data's value, no link is named a counterbalance on joint 1 and identify's route names no joint to try a spring."""
    from identification.calibration.counterbalance_sources import named_counterbalances, named_joints
    from identification.calibration.gravity_departure import gravity_departures
    from identification.calibration.inertia_departure import stored_inertia_departures

    recording, fit = hidden
    assert 0 in gravity_departures(denso, denso_model, [recording], fit)  # the fit's links do depart on joint 1
    stored = stored_inertia_departures(fit.envelope_bounds)
    assert list(stored) == [0]
    item = stored[0]
    truth = _true_theta(denso, denso_model)[denso_model.base_names.index(item.parameter)]
    assert abs(item.data - truth) <= 3 * item.data_std and item.fitted < item.data
    assert not [f for f in fit.envelope if f.pressed and f.absorbs == "counterbalance"]
    assert named_joints(fit) == {}
    naming = named_counterbalances(denso, denso_model, [recording], TrajectoryOptions(), fit, None)
    assert naming.named == {} and "not a counterbalance" in naming.said and f"{item.data:.4g}" in naming.said


def test_a_tool_at_the_flange_is_named_a_payload_where_it_moves_an_inertia_about_a_wrist_joint(denso, denso_model):
    """An unstated 2 kg tool 0.16 m off the flange: beside link 5's gravity and inertia (the last body of the model,
    the old rule's payload too), the fit holds back the inertia about joint 4, which the old rule named extra inertia
    on joint 4 (a rotor). The tool's torque is on every wrist and arm joint, and a body at the flange raises that
    inertia: a payload first, the rotor as the alternative; no item names a counterbalance first."""
    tool = xp.Payload(mass=2.0, com=np.array([0.05, 0.0, 0.15]))
    fit = identify_trajectories(denso, denso_model, [rigid_recording(denso, [tool])], TrajectoryOptions())
    held = stored_held_back(fit.envelope_bounds)
    assert held and all(h.absorbs == "payload" for h in held), [(h.words, h.absorbs) for h in held]
    wrist = [h for h in held if h.words.startswith("the inertia about joint 4")]
    assert wrist and wrist[0].data > wrist[0].fitted and "drive_inertia" in wrist[0].alternatives
    assert "a payload or tool at the flange" in wrist[0].message and "its torque over joints" in wrist[0].message
    assert "a body at the flange can give it" in wrist[0].message


def test_a_counterbalance_is_named_a_counterbalance_and_the_motion_decides_it_against_a_drive(denso, denso_model):
    """A cam counterbalance of 15 N m on joint 4 on a sine experiment (its acceleration follows its angle): the data
    want less inertia about joint 4, its torque on joint 4 alone; no body at the flange or rotor gives less inertia,
    a torque of the angle on a periodic motion does: a counterbalance on joint 4, a drive's dynamics the alternative.
    The same evidence on moves between rests (no periodic motion to pass a torque of the angle for an inertia) puts
    the drive's dynamics first."""
    cam = xp.CamCounterbalance(joint=3, amplitude=15.0)
    fit = identify_trajectories(denso, denso_model, [rigid_recording(denso, [cam])], TrajectoryOptions())
    (item,) = stored_held_back(fit.envelope_bounds)
    assert item.words.startswith("the inertia about joint 4") and item.data < item.fitted
    assert item.absorbs == "counterbalance" and item.effect_joint == 3 and item.alternatives == ("drive_dynamics",)
    assert "a counterbalance or spring on joint 4" in item.message and "periodic" in item.message
    k = denso_model.base_names.index(item.parameter)
    wanted = np.zeros(denso_model.n_base + 6)
    wanted[k] = item.data - item.fitted
    shares = np.eye(denso.n_dof)[3]
    evidence = {"kind": "axis", "joint": 3, "wanted": wanted, "shares": shares, "drives": {}, "distal": [3, 4]}
    periodic, _, _ = likely_effects(denso_model, denso, k, {**evidence, "following": np.ones(6)})
    at_rest, at, words = likely_effects(denso_model, denso, k, {**evidence, "following": np.zeros(6)})
    assert periodic == ("counterbalance", "drive_dynamics") and at_rest == ("drive_dynamics", "counterbalance")
    assert at == 3 and "moves between rests" in words and "its torque on joint 4 (100%)" in words
    more, _, words = likely_effects(denso_model, denso, k, {**evidence, "wanted": -wanted, "following": None})
    assert more[0] == "drive_inertia" and "counterbalance" not in more and "more inertia" in words


def test_a_clean_robot_says_nothing(denso, denso_model):
    fit = identify_trajectories(denso, denso_model, [rigid_recording(denso, [])], TrajectoryOptions())
    assert dict(fit.envelope_bounds)["held_back"] == []
    assert stored_held_back(fit.envelope_bounds) == ()


def test_a_significant_but_tiny_difference_is_not_named(denso, denso_model):
    """The clean Denso with its LuGre friction, which the fitted Coulomb-viscous friction only approximates (seed 1):
    the data's least squares put an inertia of link 2 4.4 standard deviations from the fit, but its torque is 0.6 of
    the joint's noise, below the envelope check's refused-torque size (``MIN_REFUSED_SIGMA``): nothing is named."""
    rng = np.random.default_rng(1)
    reference = sine_experiment(denso, duration=8.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=True)
    recording, _ = simulate_recording(denso, reference, options, rng)
    fit = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions())
    assert np.max(np.abs(fit.theta - fit.theta_ols) / fit.theta_std) > 4.0  # significant on its own
    assert stored_held_back(fit.envelope_bounds) == ()


def test_a_strong_pull_alone_holding_the_data_back_is_named_with_the_weaker_pull_as_route(denso, denso_model):
    """No envelope, a pull 2000 times the default's (u = 0.001): no bound is active, the pull alone keeps a small
    hidden inertia (0.5 kg m^2 on joint 1) out, and the route suggests a weaker pull beside the diagnosis."""
    recording = rigid_recording(denso, [xp.ExtraRotorInertia(inertia=np.array([0.5, 0, 0, 0, 0, 0]))])
    fit = identify_trajectories(
        denso, denso_model, [recording], TrajectoryOptions(envelope=False, prior_uncertainty=0.001)
    )
    held = stored_held_back(fit.envelope_bounds)
    assert held and held[0].words.startswith("the inertia about joint 1 ") and held[0].holder == "pull"
    assert "--prior-uncertainty" in held[0].message and "pull towards the robot file" in held[0].message


#: The two identify runs below take the default route: the links the envelope keeps from the hidden inertia move joint
#: 1's gravity torque, which the data's own least squares leave as the file has it, so no counterbalance is named and
#: no spring tried (``inertia_departure``; it was tried by block cross-validation, three shapes, four blocks, and
#: refused, most of each run).


def test_identify_states_it_in_describe_the_text_and_the_model_file(denso, denso_model, tmp_path, capsys):
    """Default settings: the departure of joint 1's gravity torque the held-back inertia makes tries no spring
    (``inertia_departure``), and the choice says why."""
    recording = rigid_recording(denso, _hidden_inertia(denso))
    result = identify_recordings(denso, denso_model, [recording])
    assert not result.counterbalance.joints and "not a counterbalance" in result.counterbalance.reason
    assert any(line.startswith("held back from the data: the inertia about joint 1") for line in result.describe())
    stored = result.calibrated.document["standard"]["envelope"]["held_back"]
    assert stored and stored[0]["words"].startswith("the inertia about joint 1 ")
    assert stored_held_back(result.calibrated.document["standard"]["envelope"]) == result.held_back
    old = {k: v for k, v in result.calibrated.document["standard"]["envelope"].items() if k != "held_back"}
    assert stored_held_back(old) == ()  # a file written before: none


def test_the_cli_prints_it(denso, tmp_path, capsys):
    from identification.data.io import save_recording

    path = tmp_path / "train.npz"
    save_recording(rigid_recording(denso, _hidden_inertia(denso)), path)
    out = tmp_path / "model.json"
    assert main(["identify", str(denso.source), "--data", str(path), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "HELD BACK: the inertia about joint 1" in text
    assert json.loads(out.read_text())["standard"]["envelope"]["held_back"][0]["parameter"] == "theta10"
    loaded = load_calibrated_model(out)  # the file reads back, its held-back parameters with it
    assert stored_held_back(loaded.document["standard"]["envelope"])[0].words.startswith("the inertia about joint 1")


KINOVA = DATASETS / "kinova_gen3_dynid"


@pytest.mark.slow
@pytest.mark.real_data
def test_the_kinova_sensor_fit_names_the_tools_inertia_the_pull_holds_back(tmp_path, capsys):
    """The Kinova Gen3 on its joint-torque sensors (the example's command): no bound is active, but the data want an
    inertia of link 7 several times the robot file's (the undocumented tool at the flange, README), 4.8 standard
    deviations above what the pull keeps; it is named, as a payload or tool, with the diagnosis as the route. Its
    inertia about joint 1 (the least squares 2.3 +/- 0.77 against the fit's 1.14 on these columns) is not: 1.6
    standard deviations, within what the data allow."""
    if not (KINOVA / "opti_traj_testing1.csv").exists():
        pytest.skip(f"Kinova Gen3 data absent in {KINOVA}")
    text = (ROOT / "examples" / "kinova_gen3.toml").read_text()
    (tmp_path / "kinova_gen3.toml").write_text(
        text.replace("../../shared/datasets/kinova_gen3_dynid/gen3.urdf", str(KINOVA / "gen3.urdf"))
    )
    robot = load_robot(tmp_path / "kinova_gen3.toml")
    out = tmp_path / "sensor.json"
    argv = ["identify", robot.source, "--data", str(KINOVA / "opti_traj_testing1.csv"),
            str(KINOVA / "RunTrajectory1.csv"), "--validate", str(KINOVA / "opti_traj_testing2.csv"),
            "--columns", "t=Time,q=Position,tau=TorqueSm", "--out", str(out), "--json"]  # fmt: skip
    assert main(argv) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    held = report["envelope"]["held_back"]
    assert held and not report["envelope_findings"], held  # the pull alone holds it: no bound is active
    item = held[0]
    assert item["words"] == "an inertia of link 7" and item["absorbs"] == "payload" and item["holder"] == "pull"
    assert item["data"] > item["fitted"] + HELD_BACK_SIGMA * item["data_std"]
    assert abs(item["fitted"] - item["file"]) < item["data_std"]  # kept at the robot file's
    # the data ask for many times its size in the file: a weaker pull is not the route (at --prior-uncertainty 5 the
    # fit moved it from 0.357 to 0.403 only), the diagnosis is
    assert item["file_sizes"] > ROUGH_FILE and "more than a rough file explains" in item["message"]
    assert "--prior-uncertainty" not in item["message"] and "psdm diagnose" in item["message"]
    assert "theta1" not in {h["parameter"] for h in held}
