"""Outputs that may not be written: refused before any work, exit 2, naming the option and the fix, and no
file of the working folder changed (an existing report, a file named as a folder, foreign files, an
unwritable place, the working folder)."""

import json
import os
import stat

import numpy as np
import pytest

from psdm_casadi.cli import main
from psdm_casadi.fileio import OutputFile, OutputFolder, atomic_write, markdown_escape
from tests.catalogue.harness import BadInput, check_refusal

DENSO, SCARA = "denso_vs6556g", "scara"
#: A folder nobody can create files in (sysfs refuses root too).
UNWRITABLE = "/sys/psdm_catalogue/out"
DATA = {"data/payload.json": '{"mass": 2.0, "com": [0.0, 0.0, 0.05]}'}
IDENTIFY = ("identify", SCARA, "--data", "data", "--out", "model")
DIAGNOSE = ("diagnose", DENSO, "--train", "train.csv", "--validate", "valid.csv", "--out", "diag")
RECORDINGS = {"train.csv": "t,q1\n", "valid.csv": "t,q1\n"}
SINE = ("simulate", DENSO, "--experiment", "sine", "--duration", "1")
EXCITE = ("excite", SCARA)

CASES = [
    # psdm identify --out: report.md and the plot were overwritten without --overwrite
    BadInput(
        "identify keeps an existing report.md",
        IDENTIFY,
        ("--out", "'model'", "--overwrite"),
        files={**DATA, "model/report.md": "the user's notes"},
    ),
    BadInput(
        "identify --plots keeps an existing validation_all.png",
        (*IDENTIFY, "--plots"),
        ("--out", "--overwrite"),
        files={**DATA, "model/validation_all.png": b"\x89PNG old"},
    ),
    BadInput(
        "identify keeps an existing model",
        IDENTIFY,
        ("--out", "--overwrite"),
        files={**DATA, "model/identified.json": "{}", "model/model.npz": b"old"},
    ),
    BadInput(
        "identify --overwrite keeps foreign files",
        (*IDENTIFY, "--overwrite"),
        ("did not write", "thesis.tex", "new folder"),
        files={**DATA, "model/report.md": "old", "model/thesis.tex": "mine"},
    ),
    BadInput(
        "identify --out a file", (*IDENTIFY[:-1], "notes.txt"), ("--out", "is a file"), files={**DATA, "notes.txt": "x"}
    ),
    BadInput(
        "identify --out under a file",
        (*IDENTIFY[:-1], "notes.txt/model"),
        ("--out", "notes.txt", "in a folder"),
        files={**DATA, "notes.txt": "x"},
    ),
    BadInput("identify --out .", (*IDENTIFY[:-1], "."), ("--out", "working", "--out report"), files=DATA),
    BadInput("identify --out unwritable", (*IDENTIFY[:-1], UNWRITABLE), ("--out", "not writable"), files=DATA),
    BadInput(
        "identify --out the data folder",
        (*IDENTIFY[:-1], "data", "--overwrite"),
        ("--out", "did not write", "payload.json"),
        files=DATA,
    ),
    # psdm diagnose --out: plots and report.md were written before report.json was refused
    BadInput(
        "diagnose keeps an existing report.json",
        DIAGNOSE,
        ("--out", "'diag'", "--overwrite"),
        files={**RECORDINGS, "diag/report.json": "{}"},
    ),
    BadInput(
        "diagnose keeps existing plots",
        DIAGNOSE,
        ("--out", "--overwrite"),
        files={**RECORDINGS, "diag/residuals.png": b"old", "diag/fit.png": b"old"},
    ),
    BadInput(
        "diagnose --overwrite keeps foreign files",
        (*DIAGNOSE, "--overwrite"),
        ("did not write", "notes.md"),
        files={**RECORDINGS, "diag/report.json": "{}", "diag/notes.md": "mine"},
    ),
    BadInput("diagnose --out a file", (*DIAGNOSE[:-1], "train.csv"), ("--out", "is a file"), files=RECORDINGS),
    BadInput("diagnose --out unwritable", (*DIAGNOSE[:-1], UNWRITABLE), ("--out", "not writable"), files=RECORDINGS),
    # psdm simulate --out: a folder of recordings shared by several runs; its own files are kept
    BadInput(
        "simulate keeps an existing recording",
        (*SINE, "--out", "data"),
        ("--out", "sine.csv", "--overwrite"),
        files={"data/sine.csv": "t\n", "data/motor_j1_nominal.csv": "t\n"},
    ),
    BadInput(
        "simulate keeps an existing truth file",
        (*SINE, "--out", "data"),
        ("--out", "sine.truth.json", "--overwrite"),
        files={"data/sine.truth.json": "{}"},
    ),
    BadInput("simulate --out a file", (*SINE, "--out", "notes.txt"), ("--out", "is a file"), files={"notes.txt": "x"}),
    BadInput("simulate --out unwritable", (*SINE, "--out", UNWRITABLE), ("--out", "not writable")),
    BadInput(
        "simulate --payload -2 leaves no orphan recording",
        ("simulate", DENSO, "--experiment", "motor", "--joints", "6", "--payload", "-2", "--out", "data"),
        ("--payload", "got -2"),
        files={"data/gravity.csv": "t\n"},
    ),
    # psdm excite / experiment: single files
    BadInput(
        "excite keeps an existing CSV",
        (*EXCITE, "--out", "t.csv"),
        ("--out", "'t.csv'", "--overwrite"),
        files={"t.csv": "t\n"},
    ),
    BadInput(
        "excite keeps an existing plot",
        (*EXCITE, "--out", "t.csv", "--plot", "t.png"),
        ("--plot", "'t.png'", "--overwrite"),
        files={"t.png": b"old"},
    ),
    BadInput(
        "excite --out a folder",
        (*EXCITE, "--out", "runs"),
        ("--out", "is a folder", "name a file"),
        files={"runs/a": "x"},
    ),
    BadInput(
        "excite --out under a file",
        (*EXCITE, "--out", "notes.txt/t.csv"),
        ("--out", "notes.txt", "in a folder"),
        files={"notes.txt": "x"},
    ),
    BadInput("excite --out unwritable", (*EXCITE, "--out", UNWRITABLE + ".csv"), ("--out", "not writable")),
    BadInput("excite --plot unwritable", (*EXCITE, "--plot", UNWRITABLE + ".png"), ("--plot", "not writable")),
    BadInput(
        "excite --plot onto --out", (*EXCITE, "--out", "t.csv", "--plot", "t.csv"), ("--plot", "--out", "rename one")
    ),
    BadInput(
        "experiment keeps an existing CSV",
        ("experiment", "motor", DENSO, "--joint", "2", "--out", "m.csv"),
        ("--out", "'m.csv'", "--overwrite"),
        files={"m.csv": "t\n"},
    ),
    BadInput(
        "experiment default CSV kept",
        ("experiment", "gravity", DENSO),
        ("--out", "gravity_experiment.csv", "--overwrite"),
        files={"gravity_experiment.csv": "t\n"},
    ),
    # psdm derive -o
    BadInput(
        "derive keeps an existing model",
        ("derive", SCARA, "-o", "m.npz"),
        ("--output", "--overwrite"),
        files={"m.npz": b"x"},
    ),
    BadInput(
        "derive -o without .npz keeps the .npz it would write",
        ("derive", SCARA, "-o", "m"),
        ("--output", "m.npz", "--overwrite"),
        files={"m.npz": b"x"},
    ),
    BadInput(
        "derive -o a folder",
        ("derive", SCARA, "-o", "models.npz"),
        ("--output", "is a folder"),
        files={"models.npz/a": "x"},
    ),
    BadInput("derive -o unwritable", ("derive", SCARA, "-o", UNWRITABLE + ".npz"), ("--output", "not writable")),
    # psdm codegen --out
    BadInput(
        "codegen --out not empty",
        ("codegen", SCARA, "--out", "c"),
        ("--out", "--overwrite"),
        files={"c/mine.c": "int x;"},
    ),
    BadInput(
        "codegen --overwrite keeps foreign files",
        ("codegen", SCARA, "--out", "c", "--overwrite"),
        ("did not write", "mine.c", "new folder"),
        files={"c/psdm_dynamics.c": "old", "c/mine.c": "int x;"},
    ),
    BadInput(
        "codegen --out a file", ("codegen", SCARA, "--out", "x.c"), ("--out", "is a file"), files={"x.c": "int x;"}
    ),
    BadInput(
        "codegen --out . --overwrite",
        ("codegen", SCARA, "--out", ".", "--overwrite"),
        ("--out", "working, home or root"),
    ),
    BadInput("codegen --out unwritable", ("codegen", SCARA, "--out", UNWRITABLE), ("--out", "not writable")),
    # psdm demo --out
    BadInput(
        "demo --out a file", ("demo", "--quick", "--out", "notes.txt"), ("--out", "is a file"), files={"notes.txt": "x"}
    ),
    BadInput("demo --out home", ("demo", "--quick", "--out", "~", "--overwrite"), ("--out", "home", "--out report")),
    BadInput("demo --out unwritable", ("demo", "--quick", "--out", UNWRITABLE), ("--out", "not writable")),
]


@pytest.mark.parametrize("case", CASES, ids=str)
def test_output_that_may_not_be_written_is_refused_first(case, tmp_path, capsys, monkeypatch):
    if UNWRITABLE in " ".join(case.argv) and not os.path.isdir("/sys"):
        pytest.skip("no /sys on this system to stand for an unwritable folder")
    err = check_refusal(case, tmp_path, capsys, monkeypatch)
    assert "[Errno" not in err and len(err.strip().splitlines()) == 1


# --- what psdm identify writes: nothing for an inconsistent model, escaped names, the usual permissions --------

ODD_NAMES = {"SCARA RRPR": "SCARA | *v2* <b>", "J1": "J|1", "J2": "J*2*", "J3": "J_3_", "J4": "J`4`"}


@pytest.fixture
def odd_scara(tmp_path):
    """The built-in SCARA renamed with Markdown's special characters."""
    from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

    text = (BUILTIN_ROBOTS_DIR / "scara.toml").read_text()
    for old, new in ODD_NAMES.items():
        text = text.replace(f'"{old}"', json.dumps(new))
    path = tmp_path / "odd_scara.toml"
    path.write_text(text)
    return path


@pytest.fixture
def fake_fit(monkeypatch):
    """IdentificationPipeline.fit returning nominal (consistent) or negated (negative definite) base parameters."""
    from identification.calibration.consistency import check_consistency
    from identification.calibration.pipeline import IdentificationPipeline
    from identification.calibration.report import StepScore, ValidationReport
    from identification.calibration.result import IdentifiedModel
    from identification.friction.models import LuGreParameters

    sign = {"value": 1.0}

    def fit(self, data):
        robot, model, n = self.robot, self.model, self.robot.n_dof
        theta = sign["value"] * model.base_parameters(robot.nominal_dynamic_parameters())
        report = ValidationReport((StepScore("all", np.ones(n), np.full(n, 0.99)),), tuple(robot.joint_names))
        lugre = LuGreParameters(fc=1.0, fs=1.5, vs=0.1, fv=0.2, dv=1.0, sigma0=1e3, sigma1=1.0)
        self.result_ = IdentifiedModel(
            robot_name=robot.name,
            model=model,
            theta=theta,
            kt=np.ones(n),
            lugre=(lugre,) * n,
            report=report,
            consistency=check_consistency(model, theta, robot.q_min, robot.q_max, n_samples=20),
        )
        t = np.linspace(0.0, 1.0, 50)
        self.plot_data_ = (t, np.ones((50, n)), np.ones((50, n)))
        self.timings_ = {}
        return self

    monkeypatch.setattr(IdentificationPipeline, "fit", fit)
    return sign


def _identify(robot, folder, *extra):
    """identify of the paper's experiments folder (its payload.json marks it; the fit itself is ``fake_fit``)."""
    (folder / "data").mkdir(exist_ok=True)
    (folder / "data" / "payload.json").write_text('{"mass": 1.0, "com": [0, 0, 0.05]}')
    return main(["identify", str(robot), "--data", str(folder / "data"), "--out", str(folder / "model"), *extra])


def test_identify_refuses_to_save_an_inconsistent_model(odd_scara, fake_fit, tmp_path, capsys):
    fake_fit["value"] = -1.0  # D(q) negative definite
    before = sorted(p.name for p in tmp_path.iterdir())
    assert _identify(odd_scara, tmp_path) == 1
    err = capsys.readouterr().err
    assert "not physically consistent" in err and "--allow-inconsistent" in err and "Nothing was written" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(before + ["data"])  # no model, no staging folder


def test_identify_allow_inconsistent_says_so_in_every_file(odd_scara, fake_fit, tmp_path, capsys):
    fake_fit["value"] = -1.0
    assert _identify(odd_scara, tmp_path, "--allow-inconsistent", "--plots", "--json") == 0
    captured = capsys.readouterr()
    assert "INCONSISTENT" in captured.err and json.loads(captured.out)["inconsistent"] is True
    model = tmp_path / "model"
    header = json.loads((model / "identified.json").read_text())
    assert header["consistent"] is False and "not positive definite" in header["metadata"]["inconsistent"]
    report = (model / "report.md").read_text()
    assert "**WARNING: INCONSISTENT MODEL" in report and "--allow-inconsistent" in report
    written = ["identified.json", "parameters.npz", "model.npz", "report.md", "validation_all.png"]
    assert sorted(p.name for p in model.iterdir()) == sorted([*written, ".psdm-manifest.json"])
    assert sorted(json.loads((model / ".psdm-manifest.json").read_text())["files"]) == sorted(written)


def test_identify_escapes_robot_and_joint_names_in_report_md(odd_scara, fake_fit, tmp_path, capsys):
    assert _identify(odd_scara, tmp_path) == 0
    capsys.readouterr()
    report = (tmp_path / "model" / "report.md").read_text()
    assert report.startswith("# Identified model: SCARA \\| \\*v2\\* \\<b\\>\n")
    for escaped in ("| J\\|1 |", "| J\\*2\\* |", "| J\\_3\\_ |", "| J\\`4\\` |"):
        assert escaped in report
    assert "WARNING" not in report
    assert json.loads((tmp_path / "model" / "identified.json").read_text())["consistent"] is True
    # a second run replaces the tool's own files only with --overwrite
    assert _identify(odd_scara, tmp_path) == 2 and "--overwrite" in capsys.readouterr().err
    assert _identify(odd_scara, tmp_path, "--overwrite") == 0


def test_markdown_escape_keeps_one_line_and_the_text():
    assert markdown_escape("a|b*c_d`e<f>\ng") == "a\\|b\\*c\\_d\\`e\\<f\\> g"
    assert markdown_escape("Denso VS-6556G") == "Denso VS-6556G"


def test_outputs_get_the_usual_permissions(tmp_path):
    old = os.umask(0o027)
    try:
        path = atomic_write(tmp_path / "a.txt", lambda h: h.write("x"))
        assert stat.S_IMODE(path.stat().st_mode) == 0o640
        os.chmod(path, 0o600)  # a replaced file keeps the permissions its owner gave it
        atomic_write(path, lambda h: h.write("y"), overwrite=True)
        assert stat.S_IMODE(path.stat().st_mode) == 0o600
        folder = OutputFolder(tmp_path / "report", ("r.md",))
        with folder.staging() as stage:
            (stage / "r.md").write_text("x")
            os.chmod(stage / "r.md", 0o600)
        assert stat.S_IMODE((tmp_path / "report").stat().st_mode) == 0o750
        assert stat.S_IMODE((tmp_path / "report" / "r.md").stat().st_mode) == 0o640
        with OutputFile(tmp_path / "t.csv").staging() as staged_path:
            staged_path.write_text("t\n")
        assert stat.S_IMODE((tmp_path / "t.csv").stat().st_mode) == 0o640
    finally:
        os.umask(old)
