"""``psdm export-urdf`` of a model with findings: each finding a URDF cannot hold is named on stderr and in a comment
on its joint with its exact parameters; the inertials stay the model's (findings do not change the body)."""

import copy
import re
from xml.dom import minidom

import numpy as np
import pinocchio as pin
import pytest

from codegen.target_holds import findings_left_out, findings_not_representable
from identification.calibration.calibrated_model import load_calibrated_model
from psdm_casadi.cli import main
from tests.catalogue.model_files import model_document, model_text

SPRING = {"effect": "spring", "label": "spring[j2]", "kind": "torque", "joints": [2],
          "term": {"effect": "spring", "joint": 2}, "feature_names": ["spring_k_2", "spring_c_2"],
          "coefficients": [19.078944408223368, 0.5165913046084039],
          "parameters": {"k": 19.078944408223368}}  # fmt: skip
ELASTICITY = {"effect": "joint_elasticity", "label": "joint_elasticity[j3]", "kind": "signal", "joints": [3],
              "parameters": {"compliance_rad_per_Nm": 5.872700553990982e-05},
              "applied": "measurement correction (the 'corrections' block)"}  # fmt: skip
DELAY = {"effect": "delay", "label": "delay", "kind": "signal", "joints": [], "parameters": {"delay_s": 0.007}}
PAYLOAD = {"effect": "payload", "label": "payload", "kind": "rigid_body", "joints": [4], "parameters": {"mass": 1.0}}


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def documents():
    plain = model_document()
    found = copy.deepcopy(plain)
    found["findings"] = [SPRING, ELASTICITY, DELAY, PAYLOAD]
    found["corrections"] = {"joint_elasticity[j3]": {"effect": "joint_elasticity", "joint": 3,
                                                     "compliance_rad_per_Nm": 5.872700553990982e-05},
                            "delay": {"effect": "delay", "delay_s": 0.007}}  # fmt: skip
    return plain, found


def _export(tmp_path, document, name, capsys):
    (tmp_path / f"{name}.json").write_text(model_text(document))
    capsys.readouterr()
    assert main(["export-urdf", str(tmp_path / f"{name}.json"), str(tmp_path / f"{name}.urdf")]) == 0
    return (tmp_path / f"{name}.urdf").read_text(), capsys.readouterr().err


def _joint_comment(text: str, joint: str) -> str:
    """The psdm comment just before the moving joint ``joint`` of a generated (DH) URDF."""
    document = minidom.parseString(text)
    for node in document.getElementsByTagName("joint"):
        if node.getAttribute("name") == joint:
            previous = node.previousSibling
            while previous is not None and previous.nodeType != previous.COMMENT_NODE:
                previous = previous.previousSibling
            return previous.data
    raise AssertionError(joint)


def test_each_finding_left_out_is_named_with_its_parameters(tmp_path, capsys, documents):
    plain, found = documents
    text, err = _export(tmp_path, found, "found", capsys)
    warning = [line for line in err.splitlines() if "finding(s) a URDF cannot hold" in line]
    assert len(warning) == 1 and "3 finding(s)" in warning[0]
    for label in ("spring[j2]", "joint_elasticity[j3]", "delay"):
        assert label in warning[0]
    assert "payload" not in warning[0]  # a rigid-body finding is in the standard parameters, so in the inertials
    spring = _joint_comment(text, "J2")
    numbers = dict(re.findall(r"(spring_k_2|spring_c_2) = ([-0-9.e]+)", spring))
    assert [float(numbers["spring_k_2"]), float(numbers["spring_c_2"])] == SPRING["coefficients"]  # exact
    assert "joint_elasticity[j3]" in _joint_comment(text, "J3") and "spring" not in _joint_comment(text, "J3")
    assert "compliance_rad_per_Nm = 5.872700553990982e-05" in _joint_comment(text, "J3")
    assert "Finding delay (measurement correction, NOT in the URDF): delay_s = 0.007" in " ".join(text.split())
    # the bodies are the model's, findings or not
    plain_text, plain_err = _export(tmp_path, plain, "plain", capsys)
    assert "finding" not in plain_err.lower() and "finding" not in plain_text.lower()
    models = [pin.buildModelFromXML(t) for t in (text, plain_text)]
    for a, b in zip(*(m.inertias for m in models)):
        np.testing.assert_array_equal(a.toDynamicParameters(), b.toDynamicParameters())


def test_the_functions_say_nothing_for_a_model_without_such_findings(tmp_path, documents):
    plain, found = documents
    (tmp_path / "plain.json").write_text(model_text(plain))
    assert findings_left_out(load_calibrated_model(tmp_path / "plain.json")) == ({}, [])
    assert findings_not_representable(load_calibrated_model(tmp_path / "plain.json")) is None
    (tmp_path / "found.json").write_text(model_text(found))
    per_joint, general = findings_left_out(load_calibrated_model(tmp_path / "found.json"))
    assert sorted(per_joint) == [1, 2] and len(general) == 1 and general[0].startswith("delay")


def test_the_warning_names_a_couplings_parameters_once_and_the_comment_keeps_its_coefficients():
    """TX40 (new user, export-urdf of diagnose --apply's model): the warning listed 'coupling_qd6_on_5 = 0.8502,
    coupling_qdd6_on_5 = 0.02021, viscous = 0.8502, inertia = 0.02021, source_joint = 6', each number twice. The
    warning gives the physical parameters; the joint's comment keeps the coefficients too (exact, to rebuild it)."""
    from types import SimpleNamespace

    entry = {"kind": "torque", "label": "coupling[j6->j5]", "effect": "coupling", "joints": [5],
             "feature_names": ["coupling_qd6_on_5", "coupling_qdd6_on_5"], "coefficients": [0.8502, 0.02021],
             "parameters": {"viscous": 0.8502, "inertia": 0.02021, "source_joint": 6}}  # fmt: skip
    calibrated = SimpleNamespace(document={"findings": [entry]}, n_dof=6)
    warning = findings_not_representable(calibrated)
    assert "coupling[j6->j5] (torque term, NOT in the URDF): viscous = 0.8502, inertia = 0.02021, source_joint = 6" in (
        warning
    )
    assert "coupling_qd6_on_5" not in warning
    (comment,) = findings_left_out(calibrated)[0][4]
    assert "coupling_qd6_on_5 = 0.8502" in comment and "viscous = 0.8502" in comment
