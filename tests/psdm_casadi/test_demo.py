"""psdm demo --quick: the whole loop end to end (hidden spring, corrupted calibration, diagnosis, recalibration, C).

The reference is the virtual robot's truth (the robot file's Kt and the simulated spring); the demo
itself only reports it.
"""

import json

import numpy as np
import pytest

from psdm_casadi.cli import main
from psdm_casadi.demo import DemoOptions, run_demo
from psdm_casadi.robot import load_robot
from tests.psdm_casadi.html_page import assert_self_contained, plot_data


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    folder = tmp_path_factory.mktemp("demo") / "report"
    return run_demo(folder, DemoOptions.quick(quiet=True))


@pytest.mark.slow
@pytest.mark.needs_cc
def test_quick_demo_finds_the_hidden_spring_and_writes_the_report(quick_report):
    summary = quick_report.summary
    assert (summary["model"]["p"], summary["model"]["l"], summary["model"]["n_gravity"]) == (1318, 32, 9)
    spring = [f for f in summary["diagnosis"]["findings"] if f["effect"] == "spring"]
    assert spring and spring[0]["joints"] == [4]
    joint = 3
    assert summary["diagnosis"]["rmse_after"][joint] < 0.5 * summary["diagnosis"]["rmse_before"][joint]
    assert summary["codegen"]["c_vs_python_max_abs"] < 1e-9
    report = (quick_report.folder / "report.md").read_text()
    for heading in ("Derived model", "Excitation", "Table 3", "Diagnosis", "known term", "Before and after", "C code"):
        assert heading in report
    for plot in ("excitation.png", "validation_before.png", "validation_after.png"):
        assert (quick_report.folder / plot).stat().st_size > 0
    # report.md stays short: the diagnosis' residual analysis and confounding are on its page
    assert "Residual analysis" not in report and "diagnosis/report.html" in report
    page = (quick_report.folder / "report.html").read_text()
    assert_self_contained(page)
    assert "Diagnosis found: spring[j4]" in page and (quick_report.folder / "diagnosis" / "report.html").is_file()
    bars = plot_data(page, "demo-r2")
    assert bars[0]["y"] == summary["identification"]["r2_all"] and bars[1]["y"] == summary["recalibration"]["r2_all"]
    assert json.loads((quick_report.folder / "summary.json").read_text())["seed"] == 0


@pytest.mark.slow
@pytest.mark.needs_cc
def test_quick_demo_recalibrates_with_the_spring_into_a_consistent_model(quick_report):
    summary = quick_report.summary
    options = DemoOptions.quick()
    kt_true = np.array([d.kt for d in load_robot(options.robot_file).drives])
    before, after = summary["identification"], summary["recalibration"]
    assert not before["consistent"] and before["r2_min_all"] < 0.5  # the hidden spring corrupts the calibration
    assert summary["final_model_consistent"] is True and after["consistent"]
    assert np.abs(np.array(after["kt"]) / kt_true - 1).max() < 0.01
    # issue 16 asks every "All" R^2 >= 0.99 of the demo (`make demo`: 0.998, README). The quick plan's coarse
    # friction oscillations leave joint 1, which the spring does not reach, at 0.9885 before the loop and
    # 0.989-0.991 after it (settled or cold controller start): the loop must bring the spring's joint to that
    # level and make no joint worse, and the quick plan's own floor is 0.985.
    assert summary["final_min_r2_all"] == after["r2_min_all"] >= 0.985
    assert after["r2_all"][options.spring_joint] >= 0.99
    assert all(a >= b - 1e-3 for a, b in zip(after["r2_all"], before["r2_all"]))
    (term,) = after["extra_terms"]
    assert term["label"] == "spring[j4]"
    assert abs(term["physical"]["k"] / options.spring_stiffness - 1) < 0.02
    assert abs(term["physical"]["q0"] - options.spring_rest) < 0.02
    assert summary["codegen"]["model"] == "corrected" and summary["codegen"]["consistent"]
    assert summary["codegen"]["feedforward_c_vs_casadi_max_abs"] < 1e-9
    assert "psdm_feedforward_torque" in summary["codegen"]["functions"]
    assert "NOT physically consistent" not in (quick_report.folder / "report.md").read_text()


def test_demo_refuses_to_overwrite_a_report(tmp_path, capsys):
    folder = tmp_path / "report"
    folder.mkdir()
    (folder / "mine.txt").write_text("a user's file")
    assert main(["demo", "--quick", "--out", str(folder)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (folder / "mine.txt").read_text() == "a user's file"
