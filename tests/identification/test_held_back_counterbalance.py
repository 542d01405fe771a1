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


#: Seed 0 with the physical balancer: the spring identify takes in place of joint 2's offset gains nothing and gives
#: link 2 back the mass the offset had taken off it.
LINK_2_PULLED_BACK = pytest.mark.xfail(
    strict=True,
    reason="seed 0: identify names the balancer by joint 2's torque offset (+2528 N m) and takes a spring in its "
    "place, but the spring does not lower joint 2 (held-out 188.6 -> 188.6 N m, each of the 4 blocks by 0.1-0.8 N m) "
    "and link 2's mass goes from 237.1 kg (the offset's fit) to 293.6 kg (truth 246.3, robot file 292.5): the links "
    "take the balancer's curve",
)


@LINK_2_PULLED_BACK
@pytest.mark.slow  # the heavy arm's fit, the spring's three shapes on the held-out recording and 4 blocks: 20-40 s
def test_the_heavy_arms_held_back_counterbalance_is_taken_and_link_2_comes_back_to_its_mass(heavy_case):
    """Written on the old cam, which a held-back gravity term of link 2 named; the physical balancer, nearly constant
    over the recorded range, is taken by joint 2's torque offset instead and named by it (``BY_OFFSET``)."""
    from heavy_arm import EFFECTS

    robot, truth, train, validation = heavy_case(0, EFFECTS)
    result = identify_recordings(robot, derive_psdm(robot), [train], validation=[validation])
    assert counterbalance_joints(result.start) == ()  # no bound pressed for the cam: the envelope does not name it
    assert named_joints(result.start) == {}  # no held-back gravity term: the offset takes the balancer
    choice = result.counterbalance
    assert choice.kept and choice.joints == (1,), choice.reason
    assert f"named by {BY_OFFSET}" in choice.reason
    springs = [f for f in result.calibrated.document["findings"] if f["effect"] == "spring"]
    assert [(f["joints"], f["source"]) for f in springs] == [([2], "identify")]
    assert result.calibrated.document["identification"]["counterbalance"]["named_by"] == {"2": BY_OFFSET}
    # link 2 does not take the balancer back: no farther from the truth's mass than the fit without the spring (5 %)
    mass, before = result.fit.standard[1, 0], result.start.standard[1, 0]
    truth_mass = truth.nominal_dynamic_parameters()[1, 0]
    assert abs(mass - truth_mass) < max(abs(before - truth_mass), 0.05 * truth_mass), (before, mass, truth_mass)
    # held out: joint 2 lower, no joint worse beyond its margin (unless the refits clear it)
    rmse_with, rmse_without = np.array(choice.rmse_with), np.array(choice.rmse_without)
    assert rmse_with[1] < 0.95 * rmse_without[1]
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


@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.slow)])  # 5-9 s each
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


LINK_2_PULLED_BACK_BLOCKS = pytest.mark.xfail(
    strict=True,
    reason="seed 0 without a held-out recording: the blocks take the spring though it leaves joint 2 where it was in "
    "them (116.3 -> 116.3 N m) and the unseen recording agrees (joint 2 379.1 -> 214.3 N m), but link 2's mass goes "
    "from 237.6 kg (the offset's fit) to 292.1 kg (truth 246.3, robot file 292.5)",
)
KEPT_WITHOUT_GAIN = pytest.mark.xfail(
    strict=True,
    reason="seed 1: the spring named by joint 2's fitted gravity torque (its departure from the robot file) is kept "
    "though the blocks raise joint 2 (457.4 -> 469.9 N m; block 2 318.4 -> 377.8 N m) and so does the unseen recording "
    "(302.7 -> 312.0 N m): the blocks should refuse it. Judged as replacing what the links held (no joint worse), the "
    "rise is inside the blocks' noise: margin 32.2 N m with the spread of their changes (-17.7, +59.4, +8.5, +9.8), "
    "19.2 from the pooled residuals' bootstrap alone, block 2's own 75.5; the unseen recording, worse beyond its "
    "margin on joints 2 (4.9) and 3 (184.0 -> 189.3, margin 2.5), and link 2 (239.0 -> 258.8 kg, truth 242.2) show "
    "it wrong, which no never-worse margin on the blocks sees",
)


@pytest.mark.slow  # the heavy arm's fit without a held-out recording, the spring's shapes judged by 4 blocks: 40-90 s
@pytest.mark.parametrize(
    "seed",
    [
        pytest.param(0, marks=LINK_2_PULLED_BACK_BLOCKS),
        pytest.param(1, marks=KEPT_WITHOUT_GAIN),
    ],
)
def test_without_a_held_out_recording_the_counterbalance_is_taken_only_where_the_unseen_recording_agrees(
    heavy_case, seed
):
    """Training-only identify (no ``--validate``) judges the spring by the blocks of its training recording alone; they
    must lower joint 2 taken together beyond their noise margin (``counterbalance_opinion``). Seed 0: the cam holds in
    every block, the spring is taken, and the recording identify never saw (the same arm's next 10 s) confirms it
    (joint 2 lower, link 2 nearer its true mass). Seed 1: every block was lower, one by nearly half and the others
    within their noise, and the spring raised joint 2 on the unseen recording (the held-out route refuses it there:
    ``test_a_named_counterbalance_the_held_out_recording_refuses_...``); now the blocks refuse it too. Both seeds were
    written on the old cam and fail with the physical balancer (their marks say what is missed)."""
    from heavy_arm import EFFECTS

    from identification.calibration.calibrated_model import CalibratedModel
    from identification.calibration.never_worse import compare_models

    robot, truth, train, validation = heavy_case(seed, EFFECTS)
    model = derive_psdm(robot)
    result = identify_recordings(robot, model, [train])
    choice = result.counterbalance
    assert choice.joints == (1,) and choice.route.startswith("block cross-validation"), choice.reason
    springs = [f for f in result.calibrated.document.get("findings") or [] if f["effect"] == "spring"]
    if seed == 1:
        assert not choice.kept and not springs, choice.reason
        assert (
            "joint 2: the block cross-validation" in choice.reason and "a drop within its noise margin" in choice.reason
        )
        assert "psdm diagnose" in choice.reason  # the route that fits it against the robot file is suggested
        return
    assert choice.kept and [f["joints"] for f in springs] == [[2]], choice.reason
    without = CalibratedModel.from_fit(robot, model, result.start, robot_source=robot.source)
    unseen = compare_models(without, result.calibrated, model, [validation])
    assert unseen.after[1] < unseen.before[1] and not unseen.worse, (unseen.before, unseen.after, unseen.margin)
    truth_mass = truth.nominal_dynamic_parameters()[1, 0]
    assert abs(result.fit.standard[1, 0] - truth_mass) < abs(result.start.standard[1, 0] - truth_mass)
