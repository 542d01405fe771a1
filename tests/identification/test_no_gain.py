"""Findings that earn their place in the model ``diagnose --apply`` writes (``no_gain``, issue 25 points 2 and 3).

Known truth: the virtual Denso with a spring on joint 2 (k = 40 N m/rad) that the model file, identified without it,
absorbed into its links, and nothing else. The spring lowers joint 2's validation RMSE in every bootstrap draw against
the model refitted without it and is written; a pre-sliding friction on joint 4 (a state of the friction no model
file's torque holds: ``reported``) changes no joint's RMSE and is dropped with its numbers, not written, as on the heavy
virtual arm where ``--apply`` wrote two of them beside every joint's RMSE unchanged; springs forced on joints 3 and 5,
where the robot has none, leave no joint worse (the never-worse gate lets them through) but gain nothing, and are
dropped by the same rule.
"""

from __future__ import annotations

import contextlib
import io
import json
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.calibrated_model import load_calibrated_model
from identification.calibration.no_gain import GAIN_SHARE, NO_GAIN
from identification.calibration.recalibrate import recalibrate
from identification.data.io import load_recording
from identification.diagnosis.candidates.friction import PreslidingTerm
from identification.diagnosis.candidates.torque import SpringTerm
from identification.paired_margin import share_lower
from psdm_casadi.cli import main
from psdm_casadi.cli.recalibration_text import adds_nothing, recalibration_markdown
from tests.conftest import DENSO_FILE
from tests.identification.diagnosis_data import SPRING_K, hidden_spring_files


def _report(*terms) -> SimpleNamespace:
    """A diagnosis report holding one finding per candidate term (what ``recalibrate`` reads of it)."""
    findings = [SimpleNamespace(label=t.label, effect=t.key, joints=(t.joint,), feature_names=(), coefficients=(0.0,),
                                parameters={}, rmse_before=[], rmse_after=[]) for t in terms]  # fmt: skip
    return SimpleNamespace(
        findings=findings, augmented=SimpleNamespace(terms=list(terms), coefficients=[np.zeros(2) for _ in terms])
    )


@pytest.fixture(scope="module")
def spring_case(tmp_path_factory, denso, denso_model):
    """(folder, model file, training and validation recordings) of the hidden spring on joint 2."""
    folder = hidden_spring_files(tmp_path_factory.mktemp("no_gain"), denso, denso_model, DENSO_FILE, 8.0, 250.0)
    train, valid = (load_recording(folder / name, denso.n_dof) for name in ("train.csv", "valid.csv"))
    return folder, load_calibrated_model(folder / "model.json"), train, valid


def test_a_finding_that_changes_nothing_is_dropped_and_the_spring_is_written(spring_case, denso, denso_model):
    folder, calibrated, train, valid = spring_case
    presliding, beside = PreslidingTerm(joint=3, scale=1e-3), PreslidingTerm(joint=1, scale=1e-3)
    report = _report(SpringTerm(joint=1), presliding, beside)
    result = recalibrate(calibrated, denso, denso_model, report, train, valid, robot_source=DENSO_FILE)
    assert result.refused is None
    document = result.after.document
    assert [e["label"] for e in document["findings"]] == ["spring[j2]"]  # neither presliding is written
    (spring,) = document["findings"]
    assert spring["parameters"]["k"] == pytest.approx(SPRING_K, rel=0.1)  # the truth
    gate = document["recalibration"]["never_worse"]
    before, after, margin = (np.array(gate[k]) for k in ("validation_rmse_before", "validation_rmse_after", "margin"))
    assert after[1] < before[1] - margin[1]  # the spring lowers joint 2 beyond the margin
    assert abs(after[3] - before[3]) <= margin[3]  # joint 4 unchanged within it: the presliding gained nothing
    dropped = {d["label"]: d for d in document["recalibration"]["dropped_findings"]}
    held_nothing = f"{NO_GAIN} in the model written: it holds no torque there"  # not "lower in 0% of draws"
    assert dropped[presliding.label]["reason"].startswith(held_nothing)
    assert "validation RMSE on joint 4 " in dropped[presliding.label]["reason"]
    assert dropped[presliding.label]["validation_rmse_with"] == pytest.approx([after[3]])
    # on the spring's joint: the spring lowers it, the presliding (no term in the model) adds nothing to that
    assert dropped[beside.label]["reason"].startswith(held_nothing)
    assert "validation RMSE on joint 2 " in dropped[beside.label]["reason"]
    assert dropped[beside.label]["validation_rmse_with"] == dropped[beside.label]["validation_rmse_without"]
    assert not any(d["refitted"] for d in dropped.values()) and "spring[j2]" not in dropped
    assert spring["gain"]["joints"] == [2] and spring["gain"]["share_lower"] == [1.0]  # lower in every draw
    assert not adds_nothing(calibrated.document, document)  # the spring is added: written
    text = recalibration_markdown(result, denso.joint_names, "new.json")
    assert f"- dropped {presliding.label}: {held_nothing}" in text and "presliding[j4] (" not in text
    result.after.save(folder / "new.json")  # the "after" is what psdm validate says of the file written
    with contextlib.redirect_stdout(io.StringIO()) as out:
        assert main(["validate", str(folder / "new.json"), str(folder / "valid.csv"), "--json"]) == 0
    np.testing.assert_allclose(json.loads(out.getvalue())["recordings"][0]["rmse"], result.rmse_after, rtol=1e-6)


def test_every_finding_without_gain_leaves_nothing_to_apply(spring_case, denso, denso_model):
    _, calibrated, train, valid = spring_case
    result = recalibrate(calibrated, denso, denso_model, _report(PreslidingTerm(joint=3, scale=1e-3)), train, valid,
                         robot_source=DENSO_FILE)  # fmt: skip
    document = result.after.document
    assert document["findings"] == [] and adds_nothing(calibrated.document, document)  # diagnose writes nothing
    (dropped,) = document["recalibration"]["dropped_findings"]
    assert dropped["label"] == "presliding[j4]" and dropped["reason"].startswith(NO_GAIN)


def test_the_report_s_after_says_nothing_was_written_when_the_refit_adds_nothing(spring_case, denso, denso_model):
    """The gates left nothing new (a pre-sliding friction, no gain): the report's ``after_source`` said "(no gain in the
    written model)" though ``diagnose --apply`` wrote nothing; it says nothing was written, and its "after" is the
    refit as ``psdm validate`` judges it."""
    from identification.calibration.finding_value import validation_rmse
    from identification.diagnosis.applied_after import APPLIED_AFTER, with_written_after
    from identification.diagnosis.report import DiagnosisReport

    _, calibrated, train, valid = spring_case
    result = recalibrate(calibrated, denso, denso_model, _report(PreslidingTerm(joint=3, scale=1e-3)), train, valid,
                         robot_source=DENSO_FILE)  # fmt: skip
    n = denso.n_dof
    empty, ones = np.zeros((0, n)), (1.0,) * n
    report = DiagnosisReport("denso", n, "coulomb_viscous", "prior", (), *(ones,) * 6, (), 1, None, *(empty,) * 6,
                             after_source=APPLIED_AFTER, applied=SimpleNamespace(after=None))  # fmt: skip
    written = not adds_nothing(calibrated.document, result.after.document)
    assert not written
    after = with_written_after(report, result, denso_model, valid, None, written)
    text = after.after_source
    assert text.startswith(APPLIED_AFTER) and "presliding[j4] (no gain)" in text and "nothing was written" in text
    assert "written model" not in text and "model written" not in text, text
    np.testing.assert_allclose(after.rmse_after, validation_rmse(result.after, denso_model, valid)[0], rtol=1e-12)
    # as if it were written, the same refit is called the written model (the wording of a real write)
    assert "(gained nothing: " in with_written_after(report, result, denso_model, valid).after_source


def test_the_written_file_records_the_dropped_finding_with_its_hint_for_validate(spring_case, denso, denso_model):
    """A pre-sliding friction dropped for no gain is not in the model written, and its route ('psdm identify
    --friction lugre') was then only in the diagnosis's report: the file's ``diagnosis`` block records it (label,
    why, the diagnosis's explanation as the hint) and ``psdm validate`` of the file names it; the model file it was
    refitted from (no block: an older file) loads and validates with no such note."""
    from identification.calibration.dropped_findings import DIAGNOSIS_VERSION

    folder, calibrated, train, valid = spring_case
    presliding = PreslidingTerm(joint=3, scale=1e-3)
    report = _report(SpringTerm(joint=1), presliding)
    hint = presliding.interpret([0.5])[1]
    report.findings[1].explanation = hint
    result = recalibrate(calibrated, denso, denso_model, report, train, valid, robot_source=DENSO_FILE)
    block = result.after.document["diagnosis"]
    assert block["version"] == DIAGNOSIS_VERSION
    (entry,) = block["dropped"]
    assert entry["label"] == "presliding[j4]" and entry["joints"] == [4] and entry["reason"].startswith(NO_GAIN)
    assert entry["hint"] == hint and "psdm identify --friction lugre" in hint
    result.after.save(folder / "with_dropped.json")
    said = {}
    for name in ("with_dropped.json", "model.json"):
        err = io.StringIO()
        with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(err):
            assert main(["validate", str(folder / name), str(folder / "valid.csv"), "--json"]) == 0
        said[name] = (json.loads(out.getvalue())["not_written"], err.getvalue())
    (note,), err = said["with_dropped.json"]
    assert f"found presliding[j4] and did not write it ({NO_GAIN} in the model written: it holds no torque" in note
    assert hint in note
    assert note in err
    assert said["model.json"][0] == [] and "did not write it" not in said["model.json"][1]


def test_springs_forced_where_the_robot_has_none_gain_nothing_and_are_dropped(spring_case, denso, denso_model):
    """The gate lets the forced springs through (no joint worse beyond its margin); the gain rule drops them: against
    the model refitted without each, its joint is lower in fewer than ``GAIN_SHARE`` of the draws."""
    _, calibrated, train, valid = spring_case
    report = _report(SpringTerm(joint=1), SpringTerm(joint=2), SpringTerm(joint=4))
    result = recalibrate(calibrated, denso, denso_model, report, train, valid, robot_source=DENSO_FILE)
    assert result.refused is None
    document = result.after.document
    assert [e["label"] for e in document["findings"]] == ["spring[j2]"]  # the truth, alone
    assert document["findings"][0]["parameters"]["k"] == pytest.approx(SPRING_K, rel=0.1)
    block = document["recalibration"]
    assert block["never_worse"]["dropped"] == []  # no joint worse with them: the gate kept them
    dropped = {d["label"]: d for d in block["dropped_findings"]}
    for label, joint in (("spring[j3]", 3), ("spring[j5]", 5)):
        record = dropped[label]
        assert record["no_gain"] and record["refitted"] and record["joints"] == [joint]
        assert record["share_lower"][0] < GAIN_SHARE
        assert record["reason"].startswith(f"{NO_GAIN} on joint {joint}: lower in {record['share_lower'][0]:.0%}")
    # the model written is the one refitted without them: its RMSE is what psdm validate says of it
    np.testing.assert_allclose(result.rmse_after, block["after"]["validation_rmse"])


def test_without_an_effect_the_share_of_draws_is_about_uniform():
    """``GAIN_SHARE``'s reason: two models whose residuals differ by chance alone (independent noise of one size, each
    correlated over a few samples as a filtered residual is) are lower in 90 % of the draws or more about one time in
    ten; a model the same as the other never is, and a model with half the error always is."""
    rng = np.random.default_rng(0)
    kernel = np.ones(5) / 5.0
    shares = []
    for _ in range(300):
        a, b = (np.convolve(rng.normal(size=400), kernel, mode="same")[:, None] for _ in range(2))
        shares.append(share_lower(a, b)[0])
    assert 0.04 < np.mean(np.array(shares) >= GAIN_SHARE) < 0.2
    assert 0.35 < np.mean(shares) < 0.65
    assert share_lower(a, a)[0] == 0.0 and share_lower(a, 0.5 * a)[0] == 1.0


def test_the_after_source_names_why_each_dropped_finding_is_not_in_the_written_model():
    """A finding dropped because it splits one torque with a finding the model keeps (``split_torque``'s verdict,
    either side of the pair) is not said to be "no help on validation"; one the gain gate dropped is."""
    from identification.diagnosis.applied_after import dropped_text

    split = {"new": "torque_ripple[j2,h=2]", "carried": "offset2"}
    text = dropped_text([
        {"label": "torque_ripple[j2,h=2]", "split": split},
        {"label": "offset3", "split": {"new": "spring[j3]", "carried": "offset3"}},
        {"label": "presliding[j7]"},
    ])  # fmt: skip
    assert text == (
        "torque_ripple[j2,h=2] (one torque with offset2, which the model keeps), "
        "offset3 (one torque with spring[j3], which the model keeps), presliding[j7] (no help on validation)"
    )
