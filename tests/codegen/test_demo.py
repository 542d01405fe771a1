"""psdm demo --quick: the whole story end to end, and its report, on the virtual Denso."""

import json

import pytest

from psdm_casadi.cli import main
from psdm_casadi.demo import DemoOptions, run_demo


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    folder = tmp_path_factory.mktemp("demo") / "report"
    return run_demo(folder, DemoOptions.quick(quiet=True))


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
    for heading in ("Derived model", "Excitation", "Table 3", "Diagnosis", "C code"):
        assert heading in report
    assert (quick_report.folder / "excitation.png").stat().st_size > 0
    assert json.loads((quick_report.folder / "summary.json").read_text())["seed"] == 0


def test_demo_refuses_to_overwrite_a_report(tmp_path, capsys):
    folder = tmp_path / "report"
    folder.mkdir()
    (folder / "mine.txt").write_text("a user's file")
    assert main(["demo", "--quick", "--out", str(folder)]) == 2
    assert "--force" in capsys.readouterr().err
    assert (folder / "mine.txt").read_text() == "a user's file"
