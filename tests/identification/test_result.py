"""IdentifiedModel save/load and the validation report."""

from __future__ import annotations

import json

import numpy as np
import pytest

from identification.calibration.consistency import check_consistency
from identification.calibration.report import StepScore, ValidationReport, plot_observed_predicted
from identification.calibration.result import IdentifiedModel, load_identified
from identification.friction.models import LuGreParameters
from psdm_casadi.errors import ModelFileError, ParameterError, ShapeError


@pytest.fixture(scope="module")
def identified(denso, denso_model):
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    n = denso.n_dof
    report = ValidationReport(
        (
            StepScore("motor", np.ones(n), np.full(n, 0.99)),
            StepScore("all", np.arange(n, dtype=float), np.r_[np.full(n - 1, 0.98), np.nan]),
        ),
        tuple(denso.joint_names),
    )
    return IdentifiedModel(
        robot_name=denso.name,
        model=denso_model,
        theta=theta,
        kt=[d.kt for d in denso.drives],
        lugre=tuple(LuGreParameters.from_drive(d) for d in denso.drives),
        report=report,
        consistency=check_consistency(denso_model, theta, denso.q_min, denso.q_max, n_samples=10),
        metadata={"note": "test"},
    )


def test_save_load_round_trip(identified, tmp_path):
    out = identified.save(tmp_path / "model")
    back = load_identified(out)
    np.testing.assert_array_equal(back.theta, identified.theta)
    np.testing.assert_array_equal(back.kt, identified.kt)
    assert back.lugre == identified.lugre and back.model == identified.model
    assert back.report.min_r2("all") == pytest.approx(0.98)
    assert np.isnan(back.report["all"].r2[-1])
    assert back.consistency.consistent and back.metadata == {"note": "test"}
    assert IdentifiedModel.load(out).robot_name == identified.robot_name


def test_no_overwrite_and_versions(identified, tmp_path):
    out = identified.save(tmp_path / "m")
    before = (out / "identified.json").read_text()
    with pytest.raises(FileExistsError, match="overwrite"):
        identified.save(out)
    assert (out / "identified.json").read_text() == before
    identified.save(out, overwrite=True)
    header = json.loads((out / "identified.json").read_text())
    header["version"] = 99
    (out / "identified.json").write_text(json.dumps(header))
    with pytest.raises(ModelFileError, match="version"):
        load_identified(out)
    with pytest.raises(ModelFileError, match="missing"):
        load_identified(tmp_path / "nothing")


def test_validation(identified, denso_model):
    with pytest.raises(ShapeError, match="kt"):
        IdentifiedModel("r", denso_model, identified.theta, [1.0], identified.lugre, identified.report)
    with pytest.raises(ShapeError, match="theta"):
        IdentifiedModel("r", denso_model, [1.0], identified.kt, identified.lugre, identified.report)
    with pytest.raises(ParameterError, match="step"):
        StepScore("warp", np.ones(2), np.ones(2))


def test_markdown_and_plot(identified, tmp_path):
    text = identified.report.to_markdown()
    assert text.splitlines()[0].startswith("| joint | motor RMSE | motor R^2 | all RMSE")
    assert "| J1 | 1.000 | 0.990 | 0.000 | 0.980 |" in text
    t = np.linspace(0, 1, 50)
    path = plot_observed_predicted(t, np.sin(np.outer(t, [1, 2])), np.cos(np.outer(t, [1, 2])), tmp_path / "p.png")
    assert path.stat().st_size > 1000
