"""Two findings fitted to cancel each other are not physics (``finding_value.cancelling_findings``, issue 25).

Reference: the virtual heavy arm's hidden cam counterbalance on joint 2. Identify takes it as a cubic spring; the
diagnosis of that model file (whose nominal model leaves the file's spring out) finds it again as a torque ripple;
``--apply`` used to add the ripple beside the spring, and the joint refit made the two nearly collinear columns fight
(k = -6.8e4 N m/rad against a ripple of 3.5e4 N m, summing to the 2.5 kN m counterbalance). Now the ripple is dropped
with the numbers and the spring refitted alone.
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from identification.calibration.finding_value import CANCEL_CORRELATION, CANCEL_SHARE, cancelling_pairs

Q = np.linspace(-0.6, 0.8, 2000)  # joint 2's travel [rad]
COUNTERBALANCE = 2500.0 * np.sin(Q) * (1.0 + 0.4 * np.cos(2.0 * Q))  # the truth the pair sums to


def test_a_pair_fitted_to_cancel_each_other_drops_the_newer_one_with_its_numbers():
    spring = -6.8e4 * (Q - 0.12)  # the file's spring, refitted beside the ripple
    ripple = COUNTERBALANCE - spring  # the new ripple takes the rest: each ~10 kN m, together 1.5 kN m
    (dropped,) = cancelling_pairs([("spring[j2,order=3]", 1, spring), ("torque_ripple[j2,h=2]", 1, ripple)])
    assert dropped["label"] == "torque_ripple[j2,h=2]" and dropped["joints"] == [2]
    assert "cancels spring[j2,order=3] on joint 2" in dropped["reason"]
    correlation = float(dropped["reason"].split("correlation ")[1].split(")")[0])
    assert correlation == pytest.approx(np.corrcoef(spring, ripple)[0, 1], abs=1e-3) and correlation < -0.9


@pytest.mark.parametrize(
    "second, joint",
    [
        (800.0 * np.sin(2.0 * Q), 1),  # a genuine ripple beside a spring: they add, nothing cancels
        (-COUNTERBALANCE, 2),  # opposite torques on another joint: not a pair
        (-0.4 * COUNTERBALANCE, 1),  # anti-correlated, but most of the first is left: the sum is not small
    ],
)
def test_findings_that_do_not_cancel_are_kept(second, joint):
    first = COUNTERBALANCE
    total = np.sqrt(np.mean((first + second) ** 2))
    cancels = joint == 1 and np.corrcoef(first, second)[0, 1] < CANCEL_CORRELATION
    assert not (cancels and total < CANCEL_SHARE * np.sqrt(np.mean(second**2)))  # the case is what it says
    assert cancelling_pairs([("spring[j2]", 1, first), ("other", joint, second)]) == []


def _cli(argv) -> tuple:
    from psdm_casadi.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main([str(a) for a in argv])
    return code, json.loads(out.getvalue())


@pytest.mark.slow  # identify and diagnose --apply of the 1 t arm: ~15 s
@pytest.mark.xfail(strict=True, reason=(
    "with the pull towards the robot file at its stated uncertainty 2 (prior_pull), identify takes a linear spring for "
    "the cam (joint 2 held out 276.6 -> 125.7 N m; the cubic at 3: 124.6), and diagnose --apply keeps a "
    "torque_ripple[j2,h=2] beside it that trades slope with it (k -3330 -> +3803): two findings sharing one torque "
    "that the cancellation rule (correlation < -0.9) does not catch (issue 25)"))  # fmt: skip
def test_diagnose_apply_does_not_add_a_ripple_that_cancels_the_spring_the_model_carries(tmp_path, benchmark_modules):
    from unseen_cases import build

    case = build("heavy_counterbalance_slow", tmp_path, 0)
    model, applied = tmp_path / "model.json", tmp_path / "applied.json"
    code, _ = _cli(["identify", case.robot, "--data", *case.train, "--validate", case.validate, "--out", model,
                    "--json"])  # fmt: skip
    assert code == 0
    carried = json.loads(model.read_text())["findings"]
    assert [f["label"] for f in carried] == ["spring[j2,order=3]"]  # identify took the counterbalance
    code, report = _cli(["diagnose", model, "--train", case.train[-1], "--validate", case.validate, "--apply", applied,
                         "--json"])  # fmt: skip
    assert code == 0
    found = [f["label"] for f in report["findings"] if 2 in f["joints"]]
    assert found and all(label.startswith(("torque_ripple", "spring", "gas_spring")) for label in found)
    document = json.loads(applied.read_text())
    on_joint_2 = [f for f in document["findings"] if f["kind"] == "torque" and f["term"]["joint"] == 2]
    assert [f["label"] for f in on_joint_2] == ["spring[j2,order=3]"]  # one counterbalance, not two fighting
    k = on_joint_2[0]["parameters"]["k"]
    assert abs(k) == pytest.approx(abs(carried[0]["parameters"]["k"]), rel=0.2)  # the carried size, not -6.8e4
    dropped = {d["label"]: d["reason"] for d in document["recalibration"]["dropped_findings"]}
    assert any("cancels spring[j2,order=3] on joint 2" in dropped.get(label, "") for label in found), dropped
    before, after = (np.array(document["recalibration"][key]["validation_rmse"]) for key in ("before", "after"))
    assert np.all(after <= before * 1.01)
