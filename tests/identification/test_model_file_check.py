"""``load_calibrated_model`` checks what a file claims (``model_file_check``): what it accepts, what it refuses.

The refusals through the command line (exit 2, file, field and fix named) are in
``tests/catalogue/test_bad_model_files.py``; here: the tolerance of the base-versus-standard check, and the files
that must still load (models marked inconsistent, base-parameters-only models, findings).
"""

import copy
import json

import numpy as np
import pytest

from identification.calibration.calibrated_model import load_calibrated_model
from identification.calibration.model_file_check import BASE_TOLERANCE
from psdm_casadi.cli import main
from psdm_casadi.derive import derive_psdm
from psdm_casadi.errors import ModelFileError
from psdm_casadi.robot import load_robot
from tests.catalogue.model_files import SCARA_FILE, model_document, model_text


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def scara():
    robot = load_robot(SCARA_FILE)
    return robot, derive_psdm(robot), model_document()


def _write(tmp_path, document, name="model.json"):
    path = tmp_path / name
    path.write_text(model_text(document))
    return path


def test_base_parameters_must_be_the_standard_blocks_within_the_tolerance(tmp_path, scara):
    _, model, document = scara
    theta = np.array(document["base"]["values"])
    k = int(np.argmax(np.abs(theta)))
    for relative, accepted in ((0.1 * BASE_TOLERANCE, True), (10 * BASE_TOLERANCE, False)):
        edited = copy.deepcopy(document)
        edited["base"]["values"][k] = float(theta[k] + relative * np.max(np.abs(theta)))
        path = _write(tmp_path, edited)
        if accepted:
            np.testing.assert_array_equal(load_calibrated_model(path).theta, edited["base"]["values"])
        else:
            with pytest.raises(ModelFileError, match=rf"base.values\[{k}\] \(theta{k + 1}\).*Re-identify"):
                load_calibrated_model(path)


def test_a_model_marked_inconsistent_loads_and_is_refused_by_the_exports(tmp_path, scara, capsys, monkeypatch):
    """An inconsistent standard block with its own base parameters, marked as such (--allow-inconsistent)."""
    _, model, document = scara
    edited = copy.deepcopy(document)
    standard = np.array(edited["standard"]["values"]).reshape(-1, 11)
    standard[1, 0] = -3.0  # m2 < 0
    edited["standard"].update(values=standard.ravel().tolist(), consistent=False, min_pseudo_inertia_eigenvalue=-3.0)
    edited["base"]["values"] = model.base_parameters(standard).tolist()
    path = _write(tmp_path, edited)
    assert load_calibrated_model(path).consistent is False
    monkeypatch.chdir(tmp_path)
    assert main(["export-urdf", str(path), "out.urdf"]) == 1
    assert "not physically consistent" in capsys.readouterr().err and not (tmp_path / "out.urdf").exists()
    assert main(["codegen", str(path), "--out", "c"]) == 1 and not (tmp_path / "c").exists()
    # the same file claiming consistency is refused: the check is run again on its standard block
    edited["standard"]["consistent"] = True
    with pytest.raises(ModelFileError, match=r"standard.consistent is true.*link 2 \(m2=-3"):
        load_calibrated_model(_write(tmp_path, edited))


def test_a_consistent_model_marked_inconsistent_is_taken_at_its_word(tmp_path, scara):
    document = copy.deepcopy(scara[2])
    document["standard"]["consistent"] = False
    assert load_calibrated_model(_write(tmp_path, document)).consistent is False


def test_a_negative_drive_inertia_breaks_a_consistency_claim(tmp_path, scara):
    robot, model, document = scara
    edited = copy.deepcopy(document)
    edited["standard"]["values"][10] = -0.5  # Ia1
    edited["base"]["values"] = model.base_parameters(np.array(edited["standard"]["values"])).tolist()
    with pytest.raises(ModelFileError, match=r"drive inertias must be >= 0; got Ia1=-0.5"):
        load_calibrated_model(_write(tmp_path, edited))


def test_a_base_parameters_only_model_loads_unless_it_claims_consistency(tmp_path, scara):
    """--no-consistency writes null standard parameters, checked and consistent false."""
    document = copy.deepcopy(scara[2])
    document["standard"].update(values=[None] * len(document["standard"]["values"]), consistent=False,
                                checked=False, min_pseudo_inertia_eigenvalue=None)  # fmt: skip
    document["base"]["values"][0] += 1.0  # no standard block to compare with
    assert load_calibrated_model(_write(tmp_path, document)).theta[0] == document["base"]["values"][0]
    document["standard"]["consistent"] = True
    with pytest.raises(ModelFileError, match="standard.consistent must be false for a model not checked"):
        load_calibrated_model(_write(tmp_path, document))


def test_findings_are_checked_when_the_file_is_read(tmp_path, scara):
    document = copy.deepcopy(scara[2])
    document["findings"] = [{"effect": "spring", "label": "spring[j2]", "kind": "torque", "joints": [2],
                             "term": {"effect": "spring", "joint": 2}, "feature_names": ["spring_k_2", "spring_c_2"],
                             "coefficients": [3.0]}]  # fmt: skip
    with pytest.raises(ModelFileError, match=r"findings\['spring\[j2\]'\].coefficients"):
        load_calibrated_model(_write(tmp_path, document))
    document["findings"][0]["coefficients"] = [3.0, 0.25]
    assert load_calibrated_model(_write(tmp_path, document)).torque_findings[0][1].tolist() == [3.0, 0.25]


def test_integer_json_numbers_still_load(tmp_path, scara):
    """Integers where floats were written (a hand-written or re-serialised file) are numbers all the same."""
    document = json.loads(model_text(scara[2]))
    document["identification"]["cutoff_hz"] = [10]
    assert load_calibrated_model(_write(tmp_path, document)).document["identification"]["cutoff_hz"] == [10]
