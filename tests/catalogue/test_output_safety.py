"""Outputs that would replace an input, a user's own file of an output's name, or carry the wrong format: refused
before any work (exit 2, naming both options and the fix); folder outputs carry a manifest of what psdm wrote.

Also the command line's exits that are not about files: a closed stdout ends quietly (141), ``--json`` prints
an error as JSON, and the LuGre fit's failure names the joint and the options of the command line.
"""

import json
import os
import subprocess
import sys
from functools import partial

import numpy as np
import pytest

from psdm_casadi.cli import EXIT_BROKEN_PIPE, main
from psdm_casadi.manifest import MANIFEST_NAME, ManifestFolder, read_manifest
from tests.catalogue.harness import BadInput, check_refusal

DENSO, SCARA = "denso_vs6556g", "scara"
RECORDINGS = {"train.csv": "t,q1\n", "valid.csv": "t,q1\n"}
DIAGNOSE = ("diagnose", DENSO, "--train", "train.csv", "--validate", "valid.csv", "--out", "diag")
DATA = {"data/payload.json": '{"mass": 2.0, "com": [0.0, 0.0, 0.05]}'}
SINE = ("simulate", DENSO, "--experiment", "sine", "--duration", "1")


def _reference_csv(n_dof: int = 6, n: int = 50) -> str:
    t = np.linspace(0.0, 0.5, n)
    q = 0.1 * np.sin(2 * np.pi * np.outer(t, np.arange(1, n_dof + 1)))
    header = "t," + ",".join(f"q{j + 1}" for j in range(n_dof))
    return header + "\n" + "\n".join(",".join(f"{v:.6f}" for v in row) for row in np.column_stack([t, q])) + "\n"


def _manifest(*names) -> str:
    return json.dumps({"tool": "psdm", "command": "identify", "files": list(names)})


CASES = [
    # an output equal to, holding or inside an input of the same command
    BadInput(
        "identify --out the --data recording",
        ("identify", DENSO, "--data", "good.csv", "--out", "good.csv", "--overwrite"),
        ("--out", "--data", "'good.csv'", "--overwrite never replaces an input", "good_model.json"),
        files={"good.csv": "t,q1\n"},
    ),
    BadInput(
        "identify --out the --validate recording",
        ("identify", DENSO, "--data", "a.csv", "--validate", "v.json", "--out", "v.json", "--overwrite"),
        ("--out", "--validate", "v.json"),
        files={"a.csv": "t\n", "v.json": "{}"},
    ),
    BadInput(
        "identify --out a folder inside the --data folder",
        ("identify", SCARA, "--data", "data", "--out", "data/model"),
        ("--out", "lies inside", "--data", "'data'"),
        files=DATA,
    ),
    BadInput(
        "identify --overwrite a folder holding the --model input",
        ("identify", SCARA, "--data", "data", "--model", "model/model.npz", "--out", "model", "--overwrite"),
        ("--out", "holding", "--model", "model.npz"),
        files={**DATA, "model/model.npz": b"old", f"model/{MANIFEST_NAME}": _manifest("model.npz")},
    ),
    BadInput(
        "export-urdf OUT the MODEL",
        ("export-urdf", "m.json", "m.json", "--overwrite"),
        ("OUT", "MODEL", "--overwrite never replaces", "m.urdf"),
        files={"m.json": "{}"},
    ),
    BadInput(
        "diagnose --apply the model it reads",
        ("diagnose", "m.json", "--train", "train.csv", "--validate", "valid.csv", "--apply", "m.json", "--overwrite"),
        ("--apply", "ROBOT", "m_applied.json"),
        files={**RECORDINGS, "m.json": "{}"},
    ),
    BadInput(
        "simulate --overwrite the --reference it reads",
        ("simulate", DENSO, "--reference", "data/reference.csv", "--out", "data", "--overwrite"),
        ("--out", "--reference", "reference.csv", "never replaces"),
        files={"data/reference.csv": _reference_csv()},
    ),
    # the format an output implies
    BadInput(
        "identify --out model.urdf",
        ("identify", DENSO, "--data", "a.csv", "--out", "model.urdf"),
        ("--out", "must end with .json", "--out model.json"),
        files={"a.csv": "t\n"},
    ),
    BadInput(
        "export-urdf OUT not .urdf",
        ("export-urdf", "m.json", "robot.json"),
        ("OUT", "must end with .urdf", "robot.urdf"),
        files={"m.json": "{}"},
    ),
    BadInput(
        "diagnose --apply not .json",
        ("diagnose", "m.json", "--train", "train.csv", "--validate", "valid.csv", "--apply", "m2.npz"),
        ("--apply", ".json", "m2.json"),
        files={**RECORDINGS, "m.json": "{}"},
    ),
    # a user's own file of an output's name, in a folder without (or not listing it in) a manifest
    BadInput(
        "codegen --overwrite keeps a user's main.c and Makefile",
        ("codegen", SCARA, "--out", "c", "--overwrite"),
        ("--out", "main.c", "Makefile", MANIFEST_NAME, "--overwrite", "new folder"),
        files={"c/main.c": "int main(void) { return 0; }\n", "c/Makefile": "all:\n"},
    ),
    BadInput(
        "codegen --overwrite keeps a main.c its manifest does not list",
        ("codegen", SCARA, "--out", "c", "--overwrite"),
        ("main.c", MANIFEST_NAME),
        files={"c/main.c": "mine", "c/psdm_dynamics.c": "old", f"c/{MANIFEST_NAME}": _manifest("psdm_dynamics.c")},
    ),
    BadInput(
        "diagnose --overwrite keeps a user's report.md",
        (*DIAGNOSE, "--overwrite"),
        ("--out", "report.md", MANIFEST_NAME, "--overwrite"),
        files={**RECORDINGS, "diag/report.md": "my notes"},
    ),
    BadInput(
        "simulate --overwrite keeps a user's sine.csv",
        (*SINE, "--out", "data", "--overwrite"),
        ("--out", "sine.csv", MANIFEST_NAME),
        files={"data/sine.csv": "t\n", "data/notes.txt": "kept"},
    ),
    BadInput(
        "identify --overwrite keeps a user's report.md",
        ("identify", SCARA, "--data", "data", "--out", "model", "--overwrite"),
        ("--out", "report.md", MANIFEST_NAME),
        files={**DATA, "model/report.md": "mine"},
    ),
    BadInput(
        "validate --plots --overwrite keeps a user's plot",
        ("validate", "m.json", "r.csv", "--plots", "plots", "--overwrite"),
        ("--plots", "r.png", MANIFEST_NAME),
        files={"m.json": "{}", "r.csv": "t\n", "plots/r.png": b"mine"},
    ),
    # --plots on the recordings route has no folder to write to
    BadInput(
        "identify --plots on recordings",
        ("identify", DENSO, "--data", "a.csv", "--out", "m.json", "--plots"),
        ("--plots", "psdm validate", "--plots DIR"),
        files={"a.csv": "t\n"},
    ),
]


@pytest.mark.parametrize("case", CASES, ids=str)
def test_an_output_that_would_replace_an_input_or_a_user_s_file_is_refused(case, tmp_path, capsys, monkeypatch):
    err = check_refusal(case, tmp_path, capsys, monkeypatch)
    assert len(err.strip().splitlines()) == 1, err


def test_an_output_that_is_a_symlink_to_an_input_is_refused(tmp_path, capsys, monkeypatch):
    (tmp_path / "good.csv").write_text("t,q1\n")
    os.symlink("good.csv", tmp_path / "model.json")
    case = BadInput(
        "identify --out a symlink to --data",
        ("identify", DENSO, "--data", "good.csv", "--out", "model.json", "--overwrite"),
        ("--out", "'model.json'", "--data", "'good.csv'"),
    )
    check_refusal(case, tmp_path, capsys, monkeypatch)
    assert (tmp_path / "good.csv").read_text() == "t,q1\n"


def test_validate_plots_names_its_own_options(tmp_path, capsys, monkeypatch):
    case = BadInput(
        "validate --plots existing",
        ("validate", "m.json", "r.csv", "--plots", "plots"),
        ("--plots 'plots'", "pass --overwrite"),
        files={"m.json": "{}", "r.csv": "t\n", "plots/old.png": b"x"},
    )
    err = check_refusal(case, tmp_path, capsys, monkeypatch)
    assert "--out" not in err and "pass --plots" not in err


# --- the manifest ----------------------------------------------------------------------------------------------


def test_the_manifest_lists_what_was_written_and_lets_only_that_be_replaced(tmp_path):
    target = tmp_path / "out"
    folder = ManifestFolder(target, ("a.txt", "b.txt"), "test")
    folder.check(force=False)
    with folder.staging() as stage:
        (stage / "a.txt").write_text("1")
    assert read_manifest(target) == {"a.txt"}
    assert json.loads((target / MANIFEST_NAME).read_text())["command"] == "test"
    with pytest.raises(FileExistsError, match="not empty"):
        folder.check(force=False)
    folder.check(force=True)  # a.txt is listed
    with folder.staging() as stage:
        (stage / "b.txt").write_text("2")
    assert read_manifest(target) == {"a.txt", "b.txt"}  # the earlier entry is still there and listed
    assert (target / "a.txt").read_text() == "1" and (target / "b.txt").read_text() == "2"
    (target / MANIFEST_NAME).write_text(_manifest("a.txt"))  # b.txt as if a user had put it there
    with pytest.raises(FileExistsError, match=r"b\.txt, which psdm did not write"):
        folder.check(force=True)


def test_a_shared_folder_keeps_other_files_and_merges_its_manifest(tmp_path):
    target = tmp_path / "data"
    target.mkdir()
    (target / "notes.txt").write_text("mine")
    for name in ("a.csv", "b.csv"):
        folder = ManifestFolder(target, (name,), "simulate", shared=True)
        folder.check(force=False)
        with folder.staging() as stage:
            (stage / name).write_text(name)
    assert read_manifest(target) == {"a.csv", "b.csv"}
    assert (target / "notes.txt").read_text() == "mine"
    (target / "c.csv").write_text("mine")
    with pytest.raises(FileExistsError, match="c.csv"):
        ManifestFolder(target, ("c.csv",), "simulate", shared=True).check(force=True)


def test_codegen_overwrite_replaces_its_own_export_and_json_names_the_command(tmp_path, capsys):
    out = tmp_path / "c"
    assert main(["codegen", SCARA, "--out", str(out), "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["command"] == "codegen"
    listed = read_manifest(out)
    assert {"main.c", "Makefile", "psdm_dynamics.c", "psdm_dynamics.h"} <= listed
    assert listed == {p.name for p in out.iterdir()} - {MANIFEST_NAME}
    (out / "main.c").write_text("edited")
    assert main(["codegen", SCARA, "--out", str(out), "--overwrite"]) == 0
    assert (out / "main.c").read_text() != "edited"


# --- exits that are not about files ------------------------------------------------------------------------------


def test_json_error_is_printed_on_stdout(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["derive", SCARA, "--seed", "-1", "--json"]) == 2
    out = json.loads(capsys.readouterr().out)
    assert out["command"] == "derive" and out["exit_code"] == 2 and "--seed" in out["error"]
    assert main(["export-urdf", "missing.json", "x.urdf", "--json"]) == 2
    out = json.loads(capsys.readouterr().out)
    assert out["command"] == "export-urdf" and "missing.json" in out["error"]


def test_derive_and_experiment_json_name_the_command(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["derive", SCARA, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["command"] == "derive"
    assert main(["experiment", "gravity", DENSO, "--json", "--out", "g.csv"]) == 0
    assert json.loads(capsys.readouterr().out)["command"] == "experiment"


def _closed_stdout(argv, cwd):
    """Run ``psdm argv`` with its stdout's reader gone (``| head -0``); return (exit code, stderr)."""
    command = [sys.executable, "-c", "import sys; from psdm_casadi.cli import main; sys.exit(main())", *argv]
    read, write = os.pipe()
    os.close(read)  # no reader: every write to stdout fails with EPIPE
    try:
        done = subprocess.run(command, cwd=cwd, stdout=write, stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        os.close(write)
    return done.returncode, done.stderr


def test_a_closed_stdout_ends_quietly_after_writing_the_files(tmp_path):
    code, err = _closed_stdout(["derive", SCARA, "-o", "m.npz"], tmp_path)
    assert code == EXIT_BROKEN_PIPE, err
    assert "error" not in err.lower() and "Broken pipe" not in err and "Traceback" not in err
    assert (tmp_path / "m.npz").is_file()


# --- a robot read from a URDF, identified: its own URDF is an input of export-urdf -------------------------------

ARM_URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0 0 0.1"/><mass value="3.0"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.15 0 0"/><mass value="2.0"/>
    <inertia ixx="0.004" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-2.8" upper="2.8" effort="100" velocity="2.5"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.2" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-1.6" upper="1.6" effort="100" velocity="2.5"/></joint>
</robot>
"""
DRIVE = "[[drive]]\nkt = 10.0\nfc = 2.0\nfs = 2.5\nvs = 0.05\nfv = 2.0\ndv = 1.0\nsigma0 = 2000.0\nsigma1 = 10.0\n"
ARM_TOML = 'format = "psdm-robot/1"\nname = "arm"\n[urdf]\npath = "arm.urdf"\n\n' + 2 * DRIVE


@pytest.fixture(scope="module")
def arm_model(tmp_path_factory):
    """(folder, model.json) of a 2-joint URDF robot identified from a simulated recording."""
    folder = tmp_path_factory.mktemp("arm")
    (folder / "arm.urdf").write_text(ARM_URDF)
    (folder / "arm.toml").write_text(ARM_TOML)
    robot = str(folder / "arm.toml")
    sim = ["simulate", robot, "--experiment", "sine", "--duration", "8", "--rate", "200", "--tau", "--json"]
    assert main([*sim, "--out", str(folder / "data")]) == 0
    model = folder / "model.json"
    assert main(["identify", robot, "--data", str(folder / "data" / "sine.csv"), "--out", str(model)]) == 0
    return folder, model


def test_export_urdf_never_replaces_the_robot_s_own_urdf(arm_model, tmp_path, capsys, monkeypatch):
    folder, model = arm_model
    for name in ("arm.urdf", "copy.urdf"):  # the file of the robot's name, or its text under another name
        (tmp_path / name).write_text(ARM_URDF)
        case = BadInput(
            f"export-urdf OUT {name}",
            ("export-urdf", str(model), name, "--overwrite"),
            ("OUT", "robot file", "--overwrite never replaces", "_identified.urdf"),
        )
        check_refusal(case, tmp_path, capsys, monkeypatch)
    code = main(["export-urdf", str(model), str(tmp_path / "arm_identified.urdf")])
    assert code == 0 and "<robot" in (tmp_path / "arm_identified.urdf").read_text()


def test_a_closed_stdout_after_export_urdf_keeps_the_urdf(arm_model, tmp_path):
    _, model = arm_model
    code, err = _closed_stdout(["export-urdf", str(model), "out.urdf"], tmp_path)
    assert code == EXIT_BROKEN_PIPE and "error" not in err.lower(), err
    assert "<robot" in (tmp_path / "out.urdf").read_text()


@pytest.mark.slow
def test_a_lugre_fit_that_does_not_converge_names_the_joint_and_the_cli_options(arm_model, capsys, monkeypatch):
    """A real Ipopt failure (one iteration allowed): the message names the joint, --cutoff and --friction."""
    from identification.calibration import lugre_recordings
    from identification.friction.shooting import ShootingOptions

    folder, _ = arm_model
    monkeypatch.setattr(lugre_recordings, "ShootingOptions", partial(ShootingOptions, max_iter=1))
    out = folder / "lugre.json"
    argv = ["identify", str(folder / "arm.toml"), "--data", str(folder / "data" / "sine.csv"), "--out", str(out)]
    assert main([*argv, "--friction", "lugre", "--cutoff", "20"]) == 3
    err = capsys.readouterr().err
    assert "joint 1 (j1)" in err and "--cutoff 20" in err and "--cutoff 40" in err and "--friction stribeck" in err
    assert "ShootingOptions" not in err and "Maximum_Iterations_Exceeded" in err
    assert not out.exists()


def test_ctrl_c_during_a_lugre_identification_exits_130(arm_model, tmp_path):
    """Ipopt swallows the KeyboardInterrupt of its callbacks and fails with NonIpopt_Exception_Thrown; the command
    reports the interrupt (130), not a solver failure (3), and writes nothing."""
    import signal
    import threading
    import time

    folder, _ = arm_model
    data = tmp_path / "data"
    sim = ["simulate", str(folder / "arm.toml"), "--experiment", "sine", "--duration", "20", "--rate", "500", "--tau"]
    assert main([*sim, "--out", str(data)]) == 0
    argv = ["identify", str(folder / "arm.toml"), "--data", str(data / "sine.csv"), "--out", "m.json"]
    command = [sys.executable, "-c", "import sys; from psdm_casadi.cli import main; sys.exit(main())", *argv]
    command += ["--friction", "lugre"]
    process = subprocess.Popen(command, cwd=tmp_path, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    lines, seen = [], threading.Event()

    def read():
        for line in process.stderr:
            lines.append(line)
            if "Stribeck velocities" in line:  # the consistent fit, then the LuGre fits, run now
                seen.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert seen.wait(120), "the LuGre fit never started:\n" + "".join(lines)
        time.sleep(0.1)  # about where the unfixed command failed with exit 3 (its Ipopt solve)
        process.send_signal(signal.SIGINT)
        code = process.wait(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    reader.join(timeout=5)
    err = "".join(lines)
    assert code == 130, err
    assert "interrupted" in err and "NonIpopt" not in err and "Traceback" not in err
    assert sorted(os.listdir(tmp_path)) == ["data"]  # no model, no temporary file


def test_a_solver_failure_caused_by_ctrl_c_exits_130(monkeypatch, capsys):
    """In-process and deterministic: a handler whose solver swallowed the interrupt and then failed."""
    import signal

    from psdm_casadi.cli import derive
    from psdm_casadi.errors import SolverError

    def swallowed(args):
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:  # what Ipopt does inside its callbacks
            pass
        raise SolverError("Ipopt returned status NonIpopt_Exception_Thrown", status="NonIpopt_Exception_Thrown")

    monkeypatch.setattr(derive, "run_derive", swallowed)
    assert main(["derive", SCARA]) == 130
    err = capsys.readouterr().err
    assert "interrupted" in err and "NonIpopt" not in err
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the guard restored it

    def failed(args):
        raise SolverError("Ipopt returned status Maximum_Iterations_Exceeded")

    monkeypatch.setattr(derive, "run_derive", failed)
    assert main(["derive", SCARA]) == 3  # without an interrupt a solver failure stays one
