"""The discovery loop for a model with LuGre friction: ``psdm diagnose MODEL --apply NEW`` keeps the LuGre friction.

A virtual Denso with known LuGre friction (``lugre_recordings_data``) and a hidden spring on joint 2: ``psdm
identify --friction lugre`` puts the spring into the gravity parameters and into joint 2's friction; the diagnosis
of that model finds the spring, and the recalibration with it (the LuGre identification again, the spring's
columns in every linear fit) recovers the spring, the LuGre truth of every joint and the validation error, in a
version 3 file whose compiled C (inverse dynamics with the spring, plus the LuGre step) gives the reported
validation RMSE. The fast test checks the refusal of the findings the LuGre model cannot carry yet.
"""

import json
import re
import shutil
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.recalibrate import recalibrate
from identification.diagnosis.candidates import DelayTerm, LoadDependentFrictionTerm
from identification.diagnosis.report import Finding
from identification.friction.models import LUGRE_PARAMETER_NAMES
from identification.virtual import effects as xp
from psdm_casadi.errors import ParameterError
from tests.identification.lugre_recordings_data import TRUTH

SPRING_K, SPRING_Q0 = 40.0, 0.2
#: Stated tolerances of the recovered spring: stiffness (relative, beside 3 of its sigma) and rest position [rad].
SPRING_K_TOLERANCE, SPRING_Q0_TOLERANCE = 0.05, 0.02
#: Stated tolerances (relative) of the LuGre parameters after the recalibration, as for the identification alone
#: (``test_lugre_recordings.TOLERANCE``).
TOLERANCE = {"fc": 0.05, "fs": 0.15, "vs": 0.25, "fv": 0.05, "sigma0": 0.15, "sigma1": 0.10}


@pytest.fixture(scope="module")
def spring_loop(denso, tmp_path_factory):
    """``psdm identify --friction lugre`` on the recordings with the spring, then ``psdm diagnose MODEL --apply``
    (the library's terms only: the search beyond it is not what these tests are about)."""
    from psdm_casadi.cli import main
    from tests.conftest import DENSO_FILE
    from tests.identification.lugre_recordings_data import CUTOFF, write_lugre_recordings

    folder = tmp_path_factory.mktemp("lugre_spring")
    spring = xp.Spring(joint=1, stiffness=SPRING_K, q0=SPRING_Q0)
    train, valid = write_lugre_recordings(denso, folder, extras=[spring])
    argv = ["identify", str(DENSO_FILE), "--data", str(train), "--friction", "lugre", "--cutoff", str(CUTOFF),
            "--out", str(folder / "model.json")]  # fmt: skip
    assert main(argv) == 0
    argv = ["diagnose", str(folder / "model.json"), "--train", str(train), "--validate", str(valid), "--cutoff",
            str(CUTOFF), "--no-sparse", "--apply", str(folder / "new.json")]  # fmt: skip
    assert main(argv) == 0
    return folder, valid


def _lugre_errors(calibrated) -> dict:
    """Relative error of each LuGre parameter per joint against the truth."""
    block = calibrated.document["drive"]["lugre"]
    return {name: np.abs(np.array(block[name]) - TRUTH[name]) / TRUTH[name] for name in TOLERANCE}


@pytest.mark.slow
def test_apply_to_a_lugre_model_finds_the_spring_and_recovers_the_friction(spring_loop, capsys):
    from psdm_casadi.cli import main

    folder, valid = spring_loop
    before, after = load_calibrated_model(folder / "model.json"), load_calibrated_model(folder / "new.json")
    assert after.document["version"] == 3 and after.document["drive"]["friction_shape"] == "lugre"
    assert after.lugre_parameters is not None and before.document["findings"] == []
    assert not any(name.startswith(("fc", "fs", "fv")) for name in after.document["drive"]["names"])
    spring = next(e for e in after.document["findings"] if e["label"] == "spring[j2]")
    assert spring["kind"] == "torque"
    k, q0 = spring["parameters"]["k"], spring["parameters"]["q0"]
    assert abs(k - SPRING_K) < 3 * spring["std"][0] + SPRING_K_TOLERANCE * SPRING_K, spring
    assert abs(q0 - SPRING_Q0) < SPRING_Q0_TOLERANCE, spring
    # the spring corrupted joint 2's LuGre friction; with it modelled, every joint's LuGre parameters are right again
    assert any(np.any(e[1] > TOLERANCE[name]) for name, e in _lugre_errors(before).items())
    for name, error in _lugre_errors(after).items():
        assert np.all(error < TOLERANCE[name]), (name, np.round(error, 3))
    block = after.document["recalibration"]
    assert block["after"]["validation_rmse"][1] < 0.5 * block["before"]["validation_rmse"][1], block
    assert block["dropped_findings"] == [] and block["after"]["consistent"]
    assert any(m["name"] == "fc2" for m in block["moved_parameters"])  # the LuGre friction of joint 2 moved
    capsys.readouterr()
    assert main(["validate", str(folder / "new.json"), str(valid), "--json"]) == 0  # judged as psdm validate judges
    validated = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    np.testing.assert_allclose(validated, block["after"]["validation_rmse"], rtol=1e-12)


@pytest.mark.slow
@pytest.mark.needs_cc
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_the_exported_c_of_the_recalibrated_lugre_model_gives_the_reported_rmse(spring_loop, tmp_path):
    """``psdm codegen NEW``: the spring in ``psdm_inverse_dynamics``, the LuGre step in ``<lib>_lugre.c``; carried
    along the validation recording they give the report's validation RMSE to 1e-9 relative."""
    from tests.identification.lugre_recordings_data import exported_c_rmse

    folder, valid = spring_loop
    after = load_calibrated_model(folder / "new.json")
    rmse_c, header = exported_c_rmse(folder / "new.json", valid, tmp_path / "c")
    assert "psdm_lugre_step" in header
    assert "spring[j2]" in (tmp_path / "c" / "psdm_dynamics.h").read_text()
    spring = next(e for e in after.document["findings"] if e["label"] == "spring[j2]")
    assert spring["validation_rmse_without"][1] > 10 * rmse_c[1]  # the C holds the spring: without it, far worse
    np.testing.assert_allclose(rmse_c, after.document["recalibration"]["after"]["validation_rmse"], rtol=1e-9)


def _lugre_document() -> CalibratedModel:
    """The parts of a LuGre model file the recalibration reads before it fits (two joints)."""
    lugre = {name: [1.0, 1.0] for name in LUGRE_PARAMETER_NAMES}
    return CalibratedModel({"robot": {"joint_names": ["j1", "j2"]}, "findings": [],
                            "drive": {"lugre": lugre, "coulomb_velocity": 0.05}})  # fmt: skip


@pytest.mark.parametrize(
    "candidate, parameters",
    [(DelayTerm(), {"delay_s": 0.004}), (LoadDependentFrictionTerm(joint=1), {"coefficient": 0.02})],
)
def test_apply_to_a_lugre_model_refuses_the_findings_it_cannot_carry(candidate, parameters):
    """A measurement correction and a load-dependent friction (a multiple of the model's own torque, whose LuGre part
    the exported inverse dynamics does not hold) are not supported for a LuGre model: the recalibration refuses them
    by name, before any fit, with the way out."""
    value = next(iter(parameters.values()))
    finding = Finding(effect=candidate.key, label=candidate.label, joints=(() if candidate.joint is None else (1,)),
                      parameters=parameters, coefficients=(value,), feature_names=tuple(candidate.feature_names()),
                      explanation="", signature="", rmse_before=(1.0, 1.0), rmse_after=(0.5, 0.5), delta_bic=-10.0,
                      validation_gain=0.5)  # fmt: skip
    report = SimpleNamespace(findings=[finding], augmented=SimpleNamespace(terms=(candidate,), coefficients=([value],)))
    match = rf"drive.lugre. does not take the findings \['{re.escape(candidate.label)}'\]"
    with pytest.raises(ParameterError, match=match) as refused:
        recalibrate(_lugre_document(), None, None, report, [], [])
    assert "--friction stribeck" in str(refused.value)
    assert "--friction stribeck" in str(refused.value)
