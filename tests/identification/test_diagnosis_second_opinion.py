"""Findings that hold (issue 25): a finding is kept only if it holds on every validation recording, or, with one,
on every held-out block of the training recording; one that flips is reported unstable with its numbers."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.diagnosis import DiagnosisOptions, SpringTerm, TorqueOffsetTerm, diagnose, second_opinion
from identification.diagnosis.columns import BlockColumns
from identification.diagnosis.second_opinion import CROSS_VALIDATION_ROUTE, VALIDATION_ROUTE, SecondOpinion
from identification.diagnosis.selection import forward_select
from identification.virtual import effects as xp
from psdm_casadi.errors import ParameterError
from tests.identification.diagnosis_data import sine_recording


def _part(rng, offset, n=1600, phase=0.0, name=""):
    """One joint: the nominal column x (fitted, truth 2) plus a torque offset ``offset`` (array or number)."""
    t = np.linspace(0.0, 16.0, n)
    x = np.sin(1.1 * t + phase) + 0.5 * np.sin(2.7 * t + 2.0 * phase)
    y = (2.0 * x + offset + 0.01 * rng.standard_normal(n))[:, None]
    ctx = SimpleNamespace(tau=y, t=t, n_samples=n, n_dof=1, name=name)
    return ctx, BlockColumns.from_dense(x[:, None, None]), y


def test_a_finding_that_improves_one_validation_recording_and_hurts_the_other_is_unstable_not_kept(rng):
    # known truth: an offset of +0.4 N m on the training recording and validation recording A; on B the sensor was
    # re-zeroed the other way (-0.4 N m): the offset fitted on training lowers A's error and raises B's
    train, a, b = _part(rng, 0.4), _part(rng, 0.4, phase=0.5, name="A"), _part(rng, -0.4, phase=1.0, name="B")
    candidates = [TorqueOffsetTerm(joint=0)]
    alone = forward_select(candidates, train[0], a[0], train[1], a[1], train[2], a[2])
    assert [s.term.label for s in alone.steps] == ["torque_offset[j1]"]  # one validation recording keeps it
    opinion = SecondOpinion(train[0], [a, b])
    result = forward_select(candidates, train[0], a[0], train[1], a[1], train[2], a[2], opinion=opinion)
    assert result.steps == () and result.opinion_route == VALIDATION_ROUTE
    (unstable,) = result.unstable
    assert unstable.label == "torque_offset[j1]" and unstable.effect == "torque_offset"
    on_a, on_b = unstable.opinions
    assert on_a.failure is None and on_b.failure.startswith("raises the validation RMSE of its joint 1")
    # the numbers: the offset fitted on each recording alone is that recording's truth, and B's error rises
    assert on_a.parameters["offset"] == pytest.approx(0.4, abs=0.02)
    assert on_b.parameters["offset"] == pytest.approx(-0.4, abs=0.02)
    assert on_b.rmse_after[0] > on_b.rmse_before[0] and on_a.rmse_after[0] < 0.2 * on_a.rmse_before[0]
    assert "unstable" in unstable.sentence() and "offset = -0.4" in unstable.sentence()


def test_with_one_validation_recording_a_block_cross_validation_of_the_training_data_is_the_second_opinion(rng):
    # known truth: the offset is +0.4 N m during the first three quarters of the training recording and -0.4 N m in
    # the last; the validation recording has +0.4. Fitted on all of training (+0.2) it improves the validation
    # recording, but held out, the last block is predicted worse by the offset the other blocks give (+0.4)
    n = 1600
    offset = np.where(np.arange(n) < 3 * n // 4, 0.4, -0.4)
    train, val = _part(rng, offset, n=n), _part(rng, 0.4, phase=0.5)
    candidates = [TorqueOffsetTerm(joint=0)]
    alone = forward_select(candidates, train[0], val[0], train[1], val[1], train[2], val[2])
    assert [s.term.label for s in alone.steps] == ["torque_offset[j1]"]
    opinion = SecondOpinion(train[0], [val], folds=4)
    assert opinion.route == CROSS_VALIDATION_ROUTE
    result = forward_select(candidates, train[0], val[0], train[1], val[1], train[2], val[2], opinion=opinion)
    assert result.steps == () and result.opinion_route == CROSS_VALIDATION_ROUTE
    (unstable,) = result.unstable
    blocks = [o for o in unstable.opinions if o.name.startswith("training block")]
    assert len(blocks) == 4
    # per block, the offset fitted on the other three: (0.4 + 0.4 - 0.4) / 3 for the first three, 0.4 for the last
    for o in blocks[:3]:
        assert o.parameters["offset"] == pytest.approx(0.4 / 3, abs=0.02) and o.failure is None
    assert blocks[3].parameters["offset"] == pytest.approx(0.4, abs=0.02)
    assert blocks[3].failure is not None and blocks[3].rmse_after[0] > blocks[3].rmse_before[0]


def test_an_offset_that_holds_on_every_block_is_kept(rng):
    train, val = _part(rng, 0.4), _part(rng, 0.4, phase=0.5)
    opinion = SecondOpinion(train[0], [val], folds=4)
    result = forward_select(
        [TorqueOffsetTerm(joint=0)], train[0], val[0], train[1], val[1], train[2], val[2], opinion=opinion
    )
    assert [s.term.label for s in result.steps] == ["torque_offset[j1]"] and result.unstable == ()


def _offset(value, joint=2):
    vec = np.zeros(6)
    vec[joint] = value
    return [xp.TorqueOffset(offset=tuple(vec))]


def test_diagnose_with_two_validation_recordings_reports_a_flipping_offset_as_unstable(denso, denso_model):
    # the Denso with a 3 N m offset on joint 3 in training and validation A, -3 N m in validation B (re-zeroed)
    train = sine_recording(denso, 1, 10.0, _offset(3.0))[0]
    a, b = sine_recording(denso, 2, 5.0, _offset(3.0))[0], sine_recording(denso, 3, 5.0, _offset(-3.0))[0]
    options = DiagnosisOptions(library=SpringTerm() + TorqueOffsetTerm(), sparse=False, rigid_body="prior")
    one = diagnose(denso, train, a, options, model=denso_model)
    assert "torque_offset" in one.effects and one.opinion_route == CROSS_VALIDATION_ROUTE
    assert "block cross-validation" in one.to_markdown()
    both = diagnose(denso, train, [a, b], options, model=denso_model)
    assert "torque_offset" not in both.effects and both.opinion_route == VALIDATION_ROUTE
    unstable = {u.label: u for u in both.unstable}
    assert "torque_offset[j3]" in unstable
    fitted = [o.parameters["offset"] for o in unstable["torque_offset[j3]"].opinions]
    assert fitted[0] == pytest.approx(3.0, rel=0.15) and fitted[1] == pytest.approx(-3.0, rel=0.15)
    listed = both.to_dict()["unstable"]
    assert listed[0]["label"] == "torque_offset[j3]" and [o["holds"] for o in listed[0]["opinions"]] == [True, False]
    assert "## Unstable" in both.to_markdown()
    # each validation recording's verdict on the final model: the first is the one the report's errors are on
    assert [r.name.split(" (")[0] for r in both.recordings] == ["validation recording 1", "validation recording 2"]
    np.testing.assert_allclose(both.recordings[0].rmse_after, both.rmse_after, rtol=1e-9)
    np.testing.assert_allclose(both.recordings[0].rmse_before, both.rmse_before, rtol=1e-6)
    assert both.findings_not_holding == ()
    with pytest.raises(ParameterError, match="non-empty list of Recordings"):
        diagnose(denso, train, [], options, model=denso_model)
    with pytest.raises(ParameterError, match=r"diagnose train must be a Recording .* Pass train=\[recording_a"):
        diagnose(denso, [], a, options, model=denso_model)
    with pytest.raises(ParameterError, match="diagnose train must be .* got ndarray"):
        diagnose(denso, train.tau, a, options, model=denso_model)


def test_an_offset_the_rest_of_the_joint_s_torque_dilutes_on_the_training_blocks_is_kept(rng, monkeypatch):
    """Known truth: an offset of +0.4 N m on both recordings, and on the training recording an unmodelled torque of
    1 N m RMS whose mean over each quarter is zero (sines of whole periods per block). Held out, every block is lower
    with the offset the other blocks give (+0.4), but by 7 % only: the rest dilutes the relative gain, which the
    selection asked (20 %) on the validation recording already. Judged on replication (``REPLICATED``), it is kept;
    on the pooled 20 % it was called unstable."""
    n = 1600
    t = np.linspace(0.0, 16.0, n, endpoint=False)
    rest = sum(np.sin(2 * np.pi * k * t / 4.0 + k) for k in (3, 5, 7))
    train, val = _part(rng, 0.4 + rest / np.sqrt(np.mean(rest**2)), n=n), _part(rng, 0.4, n=n, phase=0.5)
    opinion = SecondOpinion(train[0], [val], folds=4)
    result = forward_select(
        [TorqueOffsetTerm(joint=0)], train[0], val[0], train[1], val[1], train[2], val[2], opinion=opinion
    )
    assert [s.term.label for s in result.steps] == ["torque_offset[j1]"] and result.unstable == ()
    assert result.steps[0].term.label == "torque_offset[j1]"
    monkeypatch.setattr(second_opinion, "REPLICATED", ())  # the pooled 20 % asked of every kind of term
    opinion = SecondOpinion(train[0], [val], folds=4)
    strict = forward_select(
        [TorqueOffsetTerm(joint=0)], train[0], val[0], train[1], val[1], train[2], val[2], opinion=opinion
    )
    (unstable,) = strict.unstable
    *blocks, pooled = unstable.opinions
    assert all(o.failure is None and o.parameters["offset"] == pytest.approx(0.4, abs=0.05) for o in blocks)
    assert pooled.failure == "lowers no own joint's validation RMSE by 20%"
    assert 0.0 < 1.0 - pooled.rmse_after[0] / pooled.rmse_before[0] < 0.1


def test_an_offset_of_one_part_of_the_training_recording_is_unstable_on_the_blocks(rng):
    """Known truth: the training recording carries +1.2 N m during its first quarter only (a sensor re-zeroed, no
    constant offset) and the validation recording +0.4: the training BIC and the validation recording want an offset,
    but the offset the other blocks give raises each of the last three blocks; it is not kept, whatever the pooled
    gain (the replication rule keeps the condition of every block)."""
    n = 1600
    train = _part(rng, np.where(np.arange(n) < n // 4, 1.2, 0.0), n=n)
    val = _part(rng, 0.4, n=n, phase=0.5)
    opinion = SecondOpinion(train[0], [val], folds=4)
    result = forward_select(
        [TorqueOffsetTerm(joint=0)], train[0], val[0], train[1], val[1], train[2], val[2], opinion=opinion
    )
    assert result.steps == ()
    (unstable,) = result.unstable
    blocks = [o for o in unstable.opinions if o.name.startswith("training block")]
    assert [o.failure is None for o in blocks] == [True, False, False, False]


def test_diagnose_takes_a_sensor_offset_on_a_noisier_training_recording_and_finds_none_without_one():
    """Virtual SCARA, Coulomb-viscous friction (``test_model_file_offsets.recording``): a sensor offset of 0.3 N m on
    joint 1 in both recordings, and on the training recording an unmodelled low-frequency torque of 0.6 N m RMS on
    that joint (sines of 0.3-3 Hz), none on the validation recording. The diagnosis's block cross-validation lowers
    every training block with the offset but by 13 % pooled: called unstable under the pooled 20 %, it is now taken
    (0.30 N m). Without the offset, the same recordings give no finding and nothing unstable on joint 1."""
    from dataclasses import replace

    from psdm_casadi import derive_psdm, load_robot
    from tests.identification.test_model_file_offsets import OFFSET, recording

    robot = load_robot("scara")
    model = derive_psdm(robot)

    def case(seed, offset, rest):
        r = recording(robot, seed)
        rng = np.random.default_rng(100 + seed)
        f, phase = rng.uniform(0.3, 3.0, 8), rng.uniform(0.0, 2 * np.pi, 8)
        d = np.sin(2 * np.pi * f[:, None] * r.t + phase[:, None]).sum(0)
        extra = np.array([offset, 0, 0, 0]) + np.outer(rest * d / np.sqrt(np.mean(d**2)), [1, 0, 0, 0])
        return replace(r, tau=r.tau - OFFSET + extra)

    for offset in (0.3, 0.0):
        report = diagnose(robot, case(2, offset, 0.6), case(3, offset, 0.0), DiagnosisOptions(sparse=False),
                          model=model)  # fmt: skip
        if offset:
            assert [f.label for f in report.findings] == ["torque_offset[j1]"], [u.label for u in report.unstable]
            assert report.findings[0].parameters["offset"] == pytest.approx(offset, rel=0.1)
        else:
            assert report.findings == () and not [u for u in report.unstable if 0 in u.joints]
