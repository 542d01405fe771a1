"""Identify takes a counterbalance that a held-back parameter names (``counterbalance_column.named_joints``, issue 25).

Reference: the heavy virtual arm's hidden truth (``benchmarks/heavy_arm.py``: a cam counterbalance on joint 2 of about
2 kN m, a 100-200 kg tool at the flange, the links' inertias 10-20 % off the robot file's). At seed 0 no bound is
pressed for the cam: the pull towards the robot file holds link 2's gravity torque inside its envelope, and identify
only named it as held back ("counterbalance (joint 2)"), leaving it to ``psdm diagnose``. Its counterbalance route now
takes it, judged as an envelope-named one (every held-out part, never worse on any joint); where the judges refuse it
(seed 1) the report suggests the diagnose command with the run's own files. An arm with only a tool, or a held-back
inertia (not a gravity term), gets no spring.
"""

from __future__ import annotations

import contextlib
import io
import json
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.counterbalance_column import (
    BY_ENVELOPE,
    BY_HELD_BACK,
    BY_OFFSET,
    counterbalance_joints,
    named_joints,
)
from identification.calibration.held_back import HeldBack, held_note
from identification.calibration.identify_route import identify_recordings
from psdm_casadi import derive_psdm


@pytest.fixture
def heavy_case(benchmark_modules, monkeypatch):
    """``case(seed, effects) -> (robot file's robot, the truth's robot, training, held-out recording)`` of the heavy
    arm as ``benchmarks/heavy_arm.py`` simulates it (the truth: the robot file with CAD-off inertias)."""
    import diagnosis
    from heavy_arm import heavy_industrial_arm

    truths, cad_error = [], diagnosis.cad_error
    monkeypatch.setattr(diagnosis, "cad_error", lambda robot, rng: truths.append(cad_error(robot, rng)) or truths[-1])

    def case(seed, effects):
        robot = heavy_industrial_arm()
        hidden, train, validation = diagnosis._scenario(
            "heavy", robot, tuple(effects), np.random.default_rng(seed), seed
        )
        case.hidden = {name: parameters for name, _, _, parameters in hidden}  # each hidden effect's true parameters
        return robot, truths[-1], train, validation

    return case


def _held(absorbs, kind, effect_joint, alternatives=()) -> dict:
    item = HeldBack("theta4", "words", 1, 0.0, 1.0, 0.1, 0.0, 10.0, 5.0, 50.0, absorbs, "pull",
                    alternatives=tuple(alternatives), effect_joint=effect_joint, kind=kind)  # fmt: skip
    return item.to_dict()


def test_only_a_held_back_gravity_term_whose_likeliest_effect_is_a_counterbalance_names_its_joint():
    def fit(*entries, envelope=()):
        return SimpleNamespace(envelope=envelope, envelope_bounds=(("prior", {}), ("held_back", list(entries))))

    assert named_joints(fit(_held("counterbalance", "gravity", 1))) == {1: BY_HELD_BACK}
    assert named_joints(fit(_held("counterbalance", "gravity", -1))) == {1: BY_HELD_BACK}  # the parameter's joint
    assert named_joints(fit(_held("counterbalance", "inertia", 3, ["drive_dynamics"]))) == {}  # less inertia
    assert named_joints(fit(_held("payload", "gravity", 4, ["counterbalance"]))) == {}  # an alternative only
    old = {k: v for k, v in _held("counterbalance", "gravity", 1).items() if k != "kind"}  # a file written before
    assert named_joints(fit(old)) == {}
    pushed = SimpleNamespace(absorbs="counterbalance", pressed=True, joint=1, effect_joint=-1)
    assert named_joints(fit(_held("counterbalance", "gravity", 1), envelope=(pushed,))) == {1: BY_ENVELOPE}
    assert dict(held_note([HeldBack(**_held("counterbalance", "gravity", 1))]))["held_back"][0]["kind"] == "gravity"


@pytest.mark.slow  # the heavy arm's fit, the spring's three shapes on the held-out recording and 4 blocks: 20-40 s
def test_the_heavy_arms_counterbalance_is_taken_in_the_offsets_place_and_link_2_keeps_its_mass(heavy_case):
    """Written on the old cam, which a held-back gravity term of link 2 named; the physical balancer, nearly constant
    over the recorded range, is taken by joint 2's torque offset instead and named by it (``BY_OFFSET``). The spring
    in the offset's place spans the same torque there (the report: the data cannot tell a balancer from a constant over
    the recorded swing), so it need not lower joint 2, only leave every joint no worse; and it does not pull link 2's
    mass: that stays where the fit with the offset and the same payload puts it. (Link 2's mass alone is not
    identifiable: it lies on a null direction of the base parameters with its first moment and the other links'
    masses, so the pull and the envelope place it; the fit before the payload, with the links absorbing the tool, put
    it at 237 kg, the payload's fit at the robot file's 292.5, the truth's is 246.)"""
    from heavy_arm import EFFECTS

    from identification.calibration.carried_payload import carrying_payloads
    from identification.calibration.trajectory_fit import identify_trajectories

    robot, _, train, validation = heavy_case(0, EFFECTS)
    model = derive_psdm(robot)
    result = identify_recordings(robot, model, [train], validation=[validation])
    assert counterbalance_joints(result.start) == ()  # no bound pressed for the cam: the envelope does not name it
    assert named_joints(result.start) == {}  # no held-back gravity term: the offset takes the balancer
    choice = result.counterbalance
    assert choice.kept and choice.joints == (1,), choice.reason
    assert f"named by {BY_OFFSET}" in choice.reason
    springs = [f for f in result.calibrated.document["findings"] if f["effect"] == "spring"]
    assert [(f["joints"], f["source"]) for f in springs] == [([2], "identify")]
    assert result.calibrated.document["identification"]["counterbalance"]["named_by"] == {"2": BY_OFFSET}
    # link 2 does not take the balancer back: its mass where the fit with the offset and the same payload puts it
    payloads = [f for f in result.calibrated.document["findings"] if f["effect"] == "payload"]
    assert payloads and result.options.offset_joints == (1,)  # the payload taken; the offset the spring replaced
    with_offset = identify_trajectories(carrying_payloads(robot, model, payloads), model, [train], result.options)
    assert result.fit.standard[1, 0] == pytest.approx(with_offset.standard[1, 0], rel=0.05)
    # held out: no joint worse beyond its margin (unless the refits clear it)
    rmse_with, rmse_without = np.array(choice.rmse_with), np.array(choice.rmse_without)
    over = np.flatnonzero(rmse_with - rmse_without > np.array(choice.margin))
    assert set(over) <= {j - 1 for j in choice.cleared}, choice.reason
    assert not [h for h in result.held_back if h.absorbs == "counterbalance"]  # the model written holds none back


@pytest.mark.slow  # the heavy arm's fit through the command line, the spring tried on the held-out recording: 15-30 s
def test_a_named_counterbalance_is_taken_where_the_held_out_recording_allows_it_or_suggested_with_diagnose(
    heavy_case, tmp_path
):
    """Seed 1: the truth's balancer on joint 2 is named there. Its torque shows as an offset of 17 % of the joint's
    recorded peak, which no sensor's zero error reaches, so identify tries a spring in its place: the spring is kept
    where the held-out recording finds no joint worse beyond its margin (the model then carries the balancer as a
    spring, no offset), and where it refuses the spring the report suggests the diagnose command with the run's own
    files. Written when a held-back gravity term of link 2, then joint 2's gravity departure, named it and the
    held-out recording refused every shape; the offset's size reading now names it first."""
    from heavy_arm import EFFECTS

    from identification.data.io import save_recording
    from psdm_casadi.cli import main

    robot, _, train, validation = heavy_case(1, EFFECTS)
    data, held_out, out = tmp_path / "train.csv", tmp_path / "val.csv", tmp_path / "model.json"
    save_recording(train, data)
    save_recording(validation, held_out)
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(io.StringIO()):
        code = main(["identify", robot.source, "--data", str(data), "--validate", str(held_out), "--out", str(out)])
    assert code == 0
    document = json.loads(out.read_text())
    choice = document["identification"]["counterbalance"]
    assert choice["joints"] == [2] and set(choice["named_by"]) == {"2"}, choice["reason"]
    assert f"counterbalance: {choice['reason']}" in stdout.getvalue()
    springs = [f for f in document.get("findings") or [] if f["effect"] == "spring"]
    rise = np.array(choice["rmse_with"]) - np.array(choice["rmse_without"])
    if choice["kept"]:  # a spring on joint 2 in the offset's place, no joint worse on the held-out recording
        assert [f["joints"] for f in springs] == [[2]]
        assert np.all(rise <= np.array(choice["margin"])), choice["reason"]
    else:  # refused: nothing written, the diagnose command suggested with the run's own files
        assert not springs and rise[1] > 0.0, choice["reason"]
        assert f"psdm diagnose {robot.source} --train {data} --validate {held_out}" in choice["reason"]


# slow: the route tries the payload and the counterbalance, each judged by block folds (75-120 s a seed); on shorter
# recordings a tool alone gets a counterbalance named (3 s at seed 0: joint 4; 5 s at seed 1: joint 3), so they
# cannot stand in for the heavy arm's 10 s
@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_the_heavy_arm_with_only_a_tool_gets_no_counterbalance(heavy_case, seed):
    robot, _, train, validation = heavy_case(seed, ("heavy_payload",))
    result = identify_recordings(robot, derive_psdm(robot), [train], validation=[validation])
    findings = result.calibrated.document.get("findings") or []
    taken = [f["parameters"]["mass"] for f in findings if f["effect"] == "payload"]
    if taken:  # the payload route took the tool: its mass near the truth's (with the joints' viscous power law chosen)
        assert taken[0] == pytest.approx(heavy_case.hidden["payload"]["mass"], rel=0.3)
    else:  # the tool is named, on link 5
        assert any(f.absorbs == "payload" for f in result.fit.envelope)
    assert result.counterbalance.joints == () and not result.counterbalance.kept
    assert not [f for f in result.calibrated.document.get("findings") or [] if f["effect"] == "spring"]


@pytest.mark.slow  # the heavy arm's fit without a held-out recording, the spring's shapes judged by 4 blocks: 40-90 s
@pytest.mark.parametrize("seed", [0, 1])
def test_without_a_held_out_recording_the_counterbalance_is_taken_only_where_the_unseen_recording_agrees(
    heavy_case, seed
):
    """Training-only identify (no ``--validate``) judges the spring by the blocks of its training recording alone
    (``counterbalance_opinion``), and the recording identify never saw (the same arm's next 10 s) must confirm what it
    takes: joint 2 lower, no joint worse beyond its margin, and the tool taken as a payload near its true mass. Seed 0:
    the balancer is named by joint 2's offset and the spring takes its place beside the payload. Seed 1: no offset is
    chosen, the links take the balancer and joint 2's gravity departure names it; the payload route did not try the
    tool (the body at the flange, fitted without the spring the model holds, was left joint 2's balancer: no body),
    and the spring alone raised joint 2 on the unseen recording; the payload estimated beside the spring
    (``payload_route.estimate_payload``) is taken with it, and the unseen recording agrees. Link 2's mass is not
    asserted: alone it is not identifiable (a null direction of the base parameters,
    ``test_the_heavy_arms_counterbalance_is_taken_in_the_offsets_place_...``)."""
    from heavy_arm import EFFECTS

    from identification.calibration.calibrated_model import CalibratedModel
    from identification.calibration.never_worse import compare_models

    robot, _, train, validation = heavy_case(seed, EFFECTS)
    model = derive_psdm(robot)
    result = identify_recordings(robot, model, [train])
    choice = result.counterbalance
    assert choice.joints == (1,) and choice.route.startswith("block cross-validation"), choice.reason
    springs = [f for f in result.calibrated.document.get("findings") or [] if f["effect"] == "spring"]
    assert choice.kept and [f["joints"] for f in springs] == [[2]], choice.reason
    assert result.payload.kept, result.payload.reason
    assert result.payload.mass == pytest.approx(heavy_case.hidden["payload"]["mass"], rel=0.3)
    without = CalibratedModel.from_fit(robot, model, result.start, robot_source=robot.source)
    unseen = compare_models(without, result.calibrated, model, [validation])
    assert unseen.after[1] < unseen.before[1] and not unseen.worse, (unseen.before, unseen.after, unseen.margin)
