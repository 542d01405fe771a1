"""Output folders: refused before any work when they may not be written, replaced only where ours, never lost."""

import os

import pytest

from psdm_casadi.cli import main
from psdm_casadi.fileio import OutputFolder

NAMES = ("report.md", "plots")


def _write_outputs(stage, text="new"):
    (stage / "report.md").write_text(text)
    (stage / "plots").mkdir()
    (stage / "plots" / "a.png").write_text(text)


def test_a_new_folder_is_created_complete_and_no_staging_folder_is_left(tmp_path):
    folder = OutputFolder(tmp_path / "out", NAMES)
    folder.check(force=False)
    with folder.staging() as stage:
        _write_outputs(stage)
        assert not (tmp_path / "out").exists()  # nothing is visible before the end
    assert (tmp_path / "out" / "plots" / "a.png").read_text() == "new"
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_force_replaces_only_our_entries_and_refuses_folders_with_other_files(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.md").write_text("old")
    folder = OutputFolder(out, NAMES)
    with pytest.raises(FileExistsError, match="pass --force"):
        folder.check(force=False)
    folder.check(force=True)
    with folder.staging() as stage:
        _write_outputs(stage)
    assert (out / "report.md").read_text() == "new"
    (out / "notes.txt").write_text("the user's")
    with pytest.raises(FileExistsError, match=r"did not write \(notes.txt\)"):
        OutputFolder(out, NAMES).check(force=True)
    assert (out / "notes.txt").read_text() == "the user's"


def test_an_interrupted_run_leaves_the_target_as_it_was(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.md").write_text("old")
    folder = OutputFolder(out, NAMES)
    with pytest.raises(KeyboardInterrupt):
        with folder.staging() as stage:
            _write_outputs(stage)
            raise KeyboardInterrupt
    assert (out / "report.md").read_text() == "old"
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_files_working_and_home_folders_are_refused(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError, match="is a file"):
        OutputFolder(tmp_path / "file", NAMES).check(force=True)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(FileExistsError, match="working, home or root"):
        OutputFolder(".", NAMES).check(force=True)
    with pytest.raises(FileExistsError, match="working, home or root"):
        OutputFolder("~", NAMES).check(force=True)


def test_undeclared_outputs_are_a_programming_error(tmp_path):
    folder = OutputFolder(tmp_path / "out", NAMES)
    with pytest.raises(RuntimeError, match="names must list every output"):
        with folder.staging() as stage:
            (stage / "surprise.txt").write_text("x")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("case", ["foreign file with --force", "dot", "a file", "partial folder kept"])
def test_demo_refuses_before_any_work_and_touches_nothing(tmp_path, monkeypatch, capsys, case):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "keep.txt").write_text("mine")
    if case == "foreign file with --force":
        (tmp_path / "r").mkdir()
        (tmp_path / "r" / "thesis.tex").write_text("mine")
        argv = ["demo", "--quick", "--out", "r", "--force"]
    elif case == "dot":
        argv = ["demo", "--quick", "--out", ".", "--force"]
    elif case == "a file":
        argv = ["demo", "--quick", "--out", "keep.txt", "--force"]
    else:  # an existing R.partial is the user's: a run must neither use nor remove it
        (tmp_path / "r.partial").mkdir()
        (tmp_path / "r.partial" / "x").write_text("mine")
        (tmp_path / "r").mkdir()
        (tmp_path / "r" / "y").write_text("mine")
        argv = ["demo", "--quick", "--out", "r"]
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    assert main(argv) == 2
    assert "--out" in capsys.readouterr().err
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
