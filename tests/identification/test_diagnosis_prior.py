"""Which rigid body ``psdm diagnose MODEL`` starts from (``calibration.diagnosis_prior``, issue 25).

Reference: the virtual heavy arm's hidden truth (a cam counterbalance on joint 2 and a payload) for the route
identify -> diagnose MODEL, and the robot file / model file themselves for the decision: a model whose identify
pushed links against their envelope is diagnosed against its robot file's rigid body; one whose links stayed inside
(or only a drive inertia was pushed) keeps its own.
"""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.diagnosis_prior import (
    DiagnosisPrior,
    carried_as,
    carried_findings,
    diagnosis_prior,
    with_file_rigid_body,
)
from tests.identification.diagnosis_data import CAM, PAYLOAD, cli_json, saved_pair


def _pushed(link, absorbs, bounds):
    return {"link": link, "absorbs": absorbs, "bounds": list(bounds), "joint": link}


def test_a_link_pushed_for_an_absorbed_effect_sends_the_diagnosis_to_the_robot_files_rigid_body(denso):
    document = {"standard": {"envelope_findings": [_pushed(1, "counterbalance", ["mass upper"]),
                                                   _pushed(4, "payload", ["envelope"])]}}  # fmt: skip
    prior = diagnosis_prior(document, denso)
    assert prior == DiagnosisPrior(True, (1, 4), ("counterbalance", "payload"))
    assert "links 2, 5" in prior.note() and "counterbalance or a payload" in prior.note()
    assert "robot file" in prior.sentence()


@pytest.mark.parametrize(
    "findings",
    [
        [],  # identify kept every link inside, unpushed
        [_pushed(2, "drive_inertia", ["drive inertia lower"])],  # link-side torque sensors: not an absorbed body
        [_pushed(2, "counterbalance", ["drive inertia lower"])],  # a spring seen through a drive inertia only
    ],
)
def test_a_model_whose_links_stayed_inside_keeps_its_own_rigid_body(denso, findings):
    prior = diagnosis_prior({"standard": {"envelope_findings": findings}}, denso)
    assert not prior.robot_file and prior.note() == "" and prior.sentence() == ""


def test_without_the_robot_files_link_inertias_the_model_keeps_its_own(denso):
    import dataclasses

    document = {"standard": {"envelope_findings": [_pushed(1, "counterbalance", ["envelope"])]}}
    assert not diagnosis_prior(document, dataclasses.replace(denso, links=None)).robot_file
    assert not diagnosis_prior({}, denso).robot_file  # an old file without the block


def test_the_robot_files_rigid_body_with_the_models_friction(denso):
    import dataclasses

    heavier = denso.with_links([dataclasses.replace(link, mass=2 * link.mass) for link in denso.links])

    nominal = dataclasses.replace(heavier, drives=tuple(dataclasses.replace(d, fc=d.fc + 1.0) for d in denso.drives))
    out = with_file_rigid_body(nominal, denso)
    np.testing.assert_allclose(out.nominal_dynamic_parameters(), denso.nominal_dynamic_parameters())
    assert [d.fc for d in out.drives] == [d.fc + 1.0 for d in denso.drives]


def test_findings_the_model_already_carries_are_named():
    document = {"findings": [{"label": "spring[j2]", "kind": "torque", "term": {"effect": "spring", "joint": 2}},
                             {"kind": "signal", "term": None}]}  # fmt: skip
    found = [SimpleNamespace(label="gas_spring[j2]", effect="gas_spring", joints=(1,)),
             SimpleNamespace(label="torque_ripple[j2,h=2]", effect="torque_ripple", joints=(1,)),
             SimpleNamespace(label="spring[j3]", effect="spring", joints=(2,)),
             SimpleNamespace(label="payload", effect="payload", joints=(4, 1, 2))]  # fmt: skip
    assert carried_findings(found, document) == ("gas_spring[j2]", "torque_ripple[j2,h=2]")
    assert carried_findings(found, {}) == ()
    assert carried_as(found, document) == (("gas_spring[j2]", "spring[j2]"), ("torque_ripple[j2,h=2]", "spring[j2]"))


def test_a_coupling_the_model_already_carries_is_named():
    """TX40: diagnosing the file 'diagnose --apply' wrote (with coupling[j6->j5] and coupling[j5->j6]) listed both
    couplings again as findings without a word that the file holds them: a term of two joints was never matched."""
    document = {"findings": [{"label": "coupling[j6->j5]", "kind": "torque", "term": {"effect": "coupling",
                                                                                      "joint": 5}}]}  # fmt: skip
    found = [SimpleNamespace(label="coupling[j6->j5]", effect="coupling", joints=(4, 5)),
             SimpleNamespace(label="coupling[j4->j5]", effect="coupling", joints=(4, 3))]  # fmt: skip
    assert carried_as(found, document) == (("coupling[j6->j5]", "coupling[j6->j5]"),)


@pytest.mark.slow
def test_identify_then_diagnose_model_finds_the_heavy_arms_counterbalance(tmp_path, benchmark_modules):
    """The route of ``benchmarks/heavy_arm.py`` (seed 0) on the command line: identify stays inside the envelope and
    takes the tool as a payload near the truth's mass (``payload_route``); diagnosing its model file finds the
    counterbalance on joint 2. Written on the old cam, when identify only pushed links 4-5 for the tool and diagnose
    MODEL found the payload: with the physical balancer and the payload route, the model file carries the payload, so
    diagnose MODEL has none left to find and the payload is checked where it is taken. Identify's first fit named both
    hidden effects where the truth puts them (``absorbed_effect_named``: the counterbalance on joint 2, the payload),
    though the model file it writes, having taken them, leaves no link pushed for either; the payload it named is the
    truth's (``payload_named``: the body identify estimated for it within 30 % of the truth's mass)."""
    from heavy_arm import run_case

    row = run_case(0, tmp_path)
    assert row["envelope_respected"] and row["payload_taken"], row["payload_reason"]
    assert row["absorbed_effect_named"] and row["stays_inside_unpushed"], row["counterbalance_reason"]
    assert row["payload_named"] and row["payload_mass_true_kg"] is not None, row["payload_reason"]
    assert abs(row["payload_mass_kg"] - row["payload_mass_true_kg"]) < 0.3 * row["payload_mass_true_kg"]
    assert row["diagnose_model_finds_counterbalance"], row["model_findings"]
    assert row["counterbalance_stated"], row["counterbalance_reason"]


@pytest.mark.slow
def test_identify_then_diagnose_model_names_a_counterbalance_the_model_carries_and_the_payload(tmp_path, denso):
    """A Denso with a cam counterbalance on joint 2 and a 1.5 kg payload (8 s training, 8 s held out): identify takes
    the counterbalance as a spring on joint 2 and the tool as a payload (``payload_route``), or leaves links pushed for
    it; diagnosing its model file finds the payload where the model does not carry it, and keeps the counterbalance on
    joint 2 the model carries (``carried_terms``), saying so."""
    import json

    (train, held_out), out = saved_pair(denso, [CAM, PAYLOAD], tmp_path), tmp_path / "model.json"
    identified = cli_json(["identify", denso.source, "--data", train, "--validate", held_out, "--out", out, "--json"])
    assert identified["counterbalance"]["kept"] and identified["counterbalance"]["joints"] == [2]
    report = cli_json(["diagnose", out, "--train", train, "--validate", held_out, "--json"])
    found = {(f["effect"], tuple(f["joints"])) for f in report["findings"]}
    carried = [f["effect"] for f in json.loads(out.read_text())["findings"]]  # identify's payload route takes the tool
    assert any(effect == "payload" for effect, _ in found) or "payload" in carried
    on_joint_2 = [f["label"] for f in report["findings"] if f["joints"] == [2]]
    notes = report["rigid_body_notes"]
    assert on_joint_2 and any("kept from identify" in note and on_joint_2[0] in note for note in notes)


def _fits(rng, n=1500, worse_by=(0.0, 1.0, 0.0), noise=0.1):
    """A validation recording's samples, the model file's prediction and a diagnosis's final prediction whose
    residual on each joint is the file's plus ``worse_by`` (a constant torque the nominal misses) and fresh noise."""
    t = np.arange(n) * 0.01
    tau = np.column_stack([np.sin(t * (j + 1)) for j in range(3)])
    predicted = tau - noise * rng.standard_normal(tau.shape)
    nominal = tau - noise * rng.standard_normal(tau.shape) - np.asarray(worse_by)
    report = SimpleNamespace(validation_t=t, validation_tau=tau, validation_final=nominal)
    file_fit = (None, SimpleNamespace(t=t, tau=tau), predicted)
    return report, file_fit, predicted, nominal


def test_a_robot_file_nominal_worse_than_the_model_file_beyond_the_margin_is_named():
    """Kinova (issue 25): the diagnosis from the robot file's rigid body (friction refitted, its finding added)
    predicted joint 2 at 19.3 N m where the model file gave 0.891; it started from it anyway. Reference: the synthetic
    residuals' own RMSE; the joints whose nominal residual is only fresh noise of the file's size (joints 1 and 3) are
    within the margin."""
    from identification.diagnosis.model_file import robot_file_worse

    report, file_fit, predicted, nominal = _fits(np.random.default_rng(0), worse_by=(0.0, 1.0, 0.0))
    text = robot_file_worse(report, file_fit)
    rmse_file = np.sqrt(np.mean((report.validation_tau - predicted) ** 2, axis=0))
    rmse_nominal = np.sqrt(np.mean((report.validation_tau - nominal) ** 2, axis=0))
    assert text.startswith(f"joint 2 {rmse_file[1]:.3g} -> {rmse_nominal[1]:.3g} N m, margin ")
    assert "joint 1" not in text and "joint 3" not in text
    assert robot_file_worse(_fits(np.random.default_rng(1), worse_by=(0.0, 0.0, 0.0))[0], file_fit) == ""


def test_a_nominal_judged_on_other_samples_keeps_the_choice():
    from identification.diagnosis.model_file import robot_file_worse

    report, file_fit, _, _ = _fits(np.random.default_rng(0))
    shifted = SimpleNamespace(**{**vars(report), "validation_t": report.validation_t + 0.005})
    assert robot_file_worse(shifted, file_fit) == ""
    shorter = (None, SimpleNamespace(t=file_fit[1].t[:-5], tau=file_fit[1].tau[:-5]), file_fit[2][:-5])
    assert robot_file_worse(report, shorter) == ""


def test_a_declined_robot_file_rigid_body_says_why(denso):
    document = {"standard": {"envelope_findings": [_pushed(6, "payload", ["envelope"])]}}
    prior = diagnosis_prior(document, denso).declining("joint 2 0.891 -> 19.3 N m, margin 1.4")
    assert not prior.robot_file and prior.links == (6,)
    assert "link 7" in prior.note() and "joint 2 0.891 -> 19.3 N m" in prior.note()
    assert "starts from the model file's rigid body" in prior.note()
    assert "not the robot file's" in prior.sentence()


def test_the_two_passes_of_a_model_files_diagnosis_are_announced(denso):
    """Kinova Gen3 (new user, diagnose model.json): two diagnoses ran one after the other (the robot file's rigid body,
    then the model file's) with the same progress lines and no word on which was which. Each now opens with a line
    saying what it is; the second names the joints that sent the diagnosis there."""
    document = {"standard": {"envelope_findings": [_pushed(6, "payload", ["mass upper"])]}}
    prior = diagnosis_prior(document, denso)
    first = prior.first_pass()
    assert first.startswith("first pass, from the robot file's rigid body (identify pushed link 7 against its bounds")
    assert "absorbing a payload" in first and "a second pass starts from the model file's rigid body" in first
    second = prior.declining("joint 6 0.311 -> 0.379 N m, margin 0.034").second_pass()
    assert second.startswith("second pass, from the model file's rigid body")
    assert "(joint 6 0.311 -> 0.379 N m, margin 0.034)" in second


@pytest.mark.slow
@pytest.mark.real_data
def test_the_kinova_diagnosis_starts_from_the_model_file_when_the_robot_files_rigid_body_predicts_worse(tmp_path):
    """Issue 25, a new user's Kinova Gen3 (the URDF, opti_traj_testing1 with the last 30 % held out, the sensor
    torques): identify pushes link 7 for the undocumented tool; the diagnosis from the URDF's rigid body (the file's
    friction refitted, findings added) predicts some joint worse than the model file beyond the never-worse margin,
    so the diagnosis starts from the model file's rigid body and says why, each joint it names with the model file's
    own RMSE as its "before". Reference: the model file's own validation RMSE (as ``psdm validate``): no joint of the
    diagnosis's model is above it, and each finding's "before" is within noise of it.
    On defaults identify holds joint 7's friction at the robot file's fit (worse than it on the held-out part: 0.33
    against 0.14 N m); a hold the held-out recording chose is not evidence of what the data want, so link 7, still at
    its mass bound, is named for the tool as without the hold (it was named a counterbalance on joint 7)."""
    from tests.conftest import DATASETS

    kinova = DATASETS / "kinova_gen3_dynid"
    if not (kinova / "opti_traj_testing1.csv").exists():
        pytest.skip(f"Kinova Gen3 data absent in {kinova}")
    data, out = kinova / "opti_traj_testing1.csv", tmp_path / "kin.json"
    layout = ["--holdout", "0.3", "--columns", "t=Time,q=Position,tau=TorqueSm", "--rate", "1000.0"]

    identified = cli_json(["identify", kinova / "gen3.urdf", "--data", data, *layout, "--out", out, "--json"])
    assert identified["worse_joints"]["held_friction"]  # the hold is made, and the tool still named
    assert any(f["link"] == 6 and f["absorbs"] == "payload" for f in identified["envelope_findings"])
    report = cli_json(["diagnose", out, "--train", data, "--json"])
    note = report["rigid_body_notes"][0]
    own = np.asarray(report["model_file_rmse"])
    assert "starts from the model file's rigid body" in note, note
    named = re.findall(r"joint (\d+) ([\d.e+-]+) -> ([\d.e+-]+) N m, margin ([\d.e+-]+)", note)
    assert named, note  # the joints the robot file's rigid body predicts worse, with their numbers
    for joint, before, after, margin in named:  # before: the model file's own RMSE; after it beyond the margin
        assert before == f"{own[int(joint) - 1]:.3g}" and float(after) > float(before) + float(margin), note
    assert "not the robot file's" in report["nominal_model"]
    assert np.all(np.asarray(report["rmse_after"]) <= own * 1.01)
    for finding in report["findings"]:
        joints = [j - 1 for j in finding["joints"]]
        assert np.all(np.asarray(finding["rmse_before"])[joints] <= own[joints] * 1.05), finding
