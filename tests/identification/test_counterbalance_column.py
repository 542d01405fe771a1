"""Identify takes the counterbalance its envelope report names (``calibration.counterbalance_column``, issue 25).

Reference: the virtual Denso's hidden truth. A spring (or a cam counterbalance) on joint 2 pushes link 2 against its
envelope; identify then fits a spring on the named joint, keeps it where the held-out recording says so, with the
truth's stiffness and every link back inside. A payload, or nothing hidden, adds no spring.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json

import numpy as np
import pytest

from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from tests.identification.diagnosis_data import CAM, PAYLOAD, cli_json, saved_pair
from trajopt.experiments import sine_experiment

HIDDEN = {
    "spring": [xp.Spring(joint=1, stiffness=20.0, q0=0.3)],
    "cam": [CAM],
    "payload": [PAYLOAD],
    "nothing": [],
}


def _identify(denso, tmp_path, hidden, *flags, validate=True) -> tuple:
    """(the model file's document, identify's JSON) of 8 s training and 8 s held out with ``hidden`` effects (held
    out from identify unless ``validate``)."""
    (train, held_out), out = saved_pair(denso, HIDDEN[hidden], tmp_path), tmp_path / "model.json"
    shown = cli_json(["identify", denso.source, "--data", train, *(["--validate", held_out] if validate else []),
                      "--out", out, "--json", "--overwrite", *flags])  # fmt: skip
    return json.loads(out.read_text()), shown


@pytest.mark.slow  # 8 fits and their held-out checks: 20-40 s
@pytest.mark.parametrize(("hidden", "order"), [("spring", 1), ("cam", 3)])
def test_a_counterbalance_identify_names_is_taken_with_its_shape_and_the_links_come_back_inside(
    denso, tmp_path, hidden, order
):
    document, output = _identify(denso, tmp_path, hidden)
    choice = document["identification"]["counterbalance"]
    assert choice["kept"] and choice["joints"] == [2], choice["reason"]  # joint 2 only: no spring on joint 1
    springs = [f for f in document["findings"] if f["effect"] == "spring"]
    assert [(f["joints"], f["source"]) for f in springs] == [([2], "identify")]
    parameters = springs[0]["parameters"]
    assert parameters.get("order", 1) == order  # the linear spring as a line, the cam as a cubic
    if hidden == "spring":
        assert parameters["k"] == pytest.approx(20.0, rel=0.1)  # the truth's stiffness
    assert not [f for f in document["standard"]["envelope_findings"] if f.get("pressed", True)]  # none pushed
    rmse = output["validation"][0]["rmse"]
    assert rmse == pytest.approx(choice["rmse_with"], rel=1e-6)  # the written model is the one judged
    assert rmse[1] < 0.5 * choice["rmse_without"][1]
    worse = np.array(choice["rmse_with"]) - np.array(choice["rmse_without"])
    over = [j + 1 for j in np.flatnonzero(worse > np.array(choice["margin"]))]  # no joint worse beyond its margin,
    assert over == [int(j) for j in choice["cleared_by_refits"]]  # unless the refits without each block clear it
    assert all(choice["cleared_by_refits"][str(j)] <= choice["margin"][j - 1] for j in over)
    assert 2 not in over  # the other joints may rise at their noise floor only (joint 4: about 2 %)
    assert all(worse[j - 1] < 0.05 * choice["rmse_without"][j - 1] for j in over)


@pytest.mark.parametrize("hidden", ["payload", "nothing"])
def test_no_spring_on_a_robot_without_a_counterbalance(denso, tmp_path, hidden):
    document, _ = _identify(denso, tmp_path, hidden)
    assert document["identification"]["counterbalance"]["joints"] == []  # nothing named, nothing tried
    assert not [f for f in document.get("findings") or [] if f["effect"] == "spring"]


@pytest.mark.slow  # the spring judged by 4 folds (12 fits of the fold data) and the fit without it: 20-40 s
def test_without_a_held_out_recording_identify_takes_the_spring_by_block_cross_validation(denso, tmp_path):
    """``psdm identify ROBOT --data train.csv`` alone (issue 25): the spring on joint 2 the envelope report names is
    judged by a block cross-validation of the training recording and kept, with the truth's stiffness, every link
    back inside; on the recording identify never saw, joint 2 fits far better than the model that only names it."""
    document, _ = _identify(denso, tmp_path, "spring", validate=False)
    choice = document["identification"]["counterbalance"]
    assert choice["kept"] and choice["joints"] == [2], choice["reason"]
    assert choice["route"].startswith("block cross-validation over the training recordings")
    (spring,) = [f for f in document["findings"] if f["effect"] == "spring"]
    assert spring["joints"] == [2] and spring["parameters"]["k"] == pytest.approx(20.0, rel=0.1)  # the truth's
    assert not [f for f in document["standard"]["envelope_findings"] if f.get("pressed", True)]  # none pressed
    named, _ = _identify(denso, tmp_path, "spring", "--no-counterbalance", validate=False)
    assert named["identification"]["counterbalance"]["joints"] == [] and not named.get("findings")
    assert any(f["absorbs"] == "counterbalance" for f in named["standard"]["envelope_findings"])
    joint2 = []
    for model in (document, named):
        (tmp_path / "m.json").write_text(json.dumps(model))
        stdout = io.StringIO()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(io.StringIO()):
            assert main(["validate", str(tmp_path / "m.json"), str(tmp_path / "val.csv"), "--json"]) == 0
        joint2.append(json.loads(stdout.getvalue())["recordings"][0]["rmse"][1])
    assert joint2[0] < 0.5 * joint2[1]


@pytest.mark.slow  # the spring fitted twice (linear, cubic) and judged on two held-out recordings: 15-30 s
def test_a_spring_must_lower_its_joint_on_each_held_out_recording(denso, denso_model):
    """Issue 25, findings that hold: with ``--validate A B`` the spring is kept only if it lowers its joint's error
    on each recording. The arm's spring on joint 2 is in the training recording and in A; B was recorded after it was
    taken off (the truth without it): the spring improves A, fails on B, and is not taken, with B's numbers; judged on
    A alone (with the blocks as the second opinion) it is taken, with the truth's stiffness."""
    from identification.calibration.identify_route import identify_recordings

    rng = np.random.default_rng(3)
    reference = sine_experiment(denso, duration=16.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    recording, _ = simulate_recording(denso, reference, options, rng, extras=HIDDEN["spring"])
    without, _ = simulate_recording(denso, reference, options, rng)  # the same motion, the spring taken off
    train, with_spring = recording.time_slice(-np.inf, 8.0), recording.time_slice(8.0, np.inf)
    result = identify_recordings(denso, denso_model, [train], validation=[with_spring, without.time_slice(8.0, np.inf)])
    choice = result.counterbalance
    assert choice.joints == (1,) and not choice.kept and "recording 2 of 2" in choice.reason, choice.reason
    first, second = [p for p in choice.parts if p["joints"] == [2]]
    assert first["rmse_with"][0] < first["rmse_without"][0] and second["rmse_with"][0] > second["rmse_without"][0]
    assert not [f for f in result.calibrated.document.get("findings") or [] if f["effect"] == "spring"]
    taken = identify_recordings(denso, denso_model, [train], validation=[with_spring]).counterbalance
    assert taken.kept and taken.route == "held-out recordings and block cross-validation over the training " \
        "recordings (4 blocks)", taken.reason  # fmt: skip
    assert [p["part"] for p in taken.parts] == ["recording 1 of 1", *(f"block {k} of 4" for k in range(1, 5))]


@pytest.mark.slow  # the TX40's fit, and a spring judged by 4 blocks and on its held-out end: 30-90 s
def test_on_the_tx40_no_judge_takes_a_spring_on_joint_2(tx40_benchmark):
    """Issue 25 on the real TX40 recording (skipped without ../shared; the first 70 % trains). While its links absorbed
    the rotors of joints 1-2, its envelope named a counterbalance on joint 2 and the blocks taken together kept a cubic
    spring there that raised the held-out end's joint 2 from 3.80 to 4.22 N m (the first block rose too, within its
    noise). With the rotors fitted nothing is named; a spring on joint 2, tried as if it were, raises the blocks (each
    named in the reason) and the held-out end, and is not taken by either judge."""
    from types import SimpleNamespace

    from identification.calibration.calibrated_model import CalibratedModel
    from identification.calibration.counterbalance_column import try_counterbalance
    from identification.calibration.identify_route import identify_recordings
    from psdm_casadi.derive import derive_psdm

    robot, recording = tx40_benchmark.load_tx40(tx40_benchmark.TX40)
    train, validation = tx40_benchmark.split(recording)
    model = derive_psdm(robot)
    result = identify_recordings(robot, model, [train], validation=[validation])
    assert result.counterbalance.joints == ()  # nothing pushed, nothing named
    named = dataclasses.replace(
        result.fit, envelope=(SimpleNamespace(absorbs="counterbalance", pressed=True, joint=1, effect_joint=-1),)
    )

    def build(fit):
        return CalibratedModel.from_fit(
            robot, model, fit, robot_source=str(tx40_benchmark.TX40 / "tx40_mdh_modified.urdf")
        )

    for held_out in ([], [validation]):  # the blocks alone; the held-out end first, the blocks the second opinion
        choice = try_counterbalance(robot, model, [train], result.options, named, result.calibrated, held_out, build)
        assert choice.joints == (1,) and not choice.kept, choice.reason
        risen = [p["part"] for p in choice.parts if p["rmse_with"][0] >= p["rmse_without"][0]]
        assert risen and all(part in choice.reason for part in risen)
        # the held-out end judges first; the blocks give the second opinion unless it already refused the spring (with
        # the pull towards the file at its default, prior_pull, the held-out end alone does not refuse it)
        assert len(choice.parts) == 4 + len(held_out) or (held_out and len(choice.parts) == 1), choice.parts
        assert not held_out or choice.parts[0]["route"] == "held-out recordings"


def test_the_trial_line_numbers_the_joints_from_one_as_the_spring_it_keeps():
    """The Denso with a spring on joint 4 printed "trying the counterbalance the report names on [3]" and then "a
    spring on joint 4 (spring[j4,...])": the trial's joints are numbered from 1 as every other line numbers them."""
    from identification.calibration.counterbalance_column import trying_line

    assert "names on joint 4 (on each held-out recording)" in trying_line([3], True)
    assert "names on joints 2, 4 (by block cross-validation" in trying_line([1, 3], False)
