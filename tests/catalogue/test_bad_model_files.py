"""Edited or corrupted calibrated-model files: refused by every command that reads them (exit 2, no traceback),
the message naming the file, the field (``base.values[3]``) and the fix, nothing written.

The good file is the SCARA's nominal parameters written as an identification writes them
(``tests.catalogue.model_files``); each case edits one field of a copy, as a user's editor or a broken copy would.
"""

import copy

import pytest

from tests.catalogue.harness import BadInput, check_refusal
from tests.catalogue.model_files import model_document, model_text

VALIDATE = ("validate", "model.json", "valid.csv")
CODEGEN = ("codegen", "model.json", "--out", "c")
URDF = ("export-urdf", "model.json", "out.urdf")
COMMANDS = {"validate": VALIDATE, "codegen": CODEGEN, "export-urdf": URDF}
FIX = "re-identify, or restore the file"


def _set(path, value):
    """An edit that sets ``document[a][b][k] = value`` for ``path = (a, b, k)``."""

    def edit(document):
        *parents, last = path
        node = document
        for key in parents:
            node = node[key]
        node[last] = value

    return edit


def _drop_last(block, key):
    def edit(document):
        document[block][key].pop()

    return edit


def _negative_mass(document):
    document["standard"]["values"][11] = -3.0  # m2: the file still says consistent


def _edit_robot_text(document):
    files = document["robot"]["files"]
    name = document["robot"]["main_file"]
    files[name] = files[name].replace("a = 0.25", "a = 0.35", 1)


def _edit_both(document):
    """theta2 changed, and standard parameters left as they were: base and standard disagree."""
    document["base"]["values"][1] += 0.5


# (name, edit, commands, expected words besides the file name and the fix)
EDITS = [
    ("a base parameter edited", _edit_both, ("validate", "codegen", "export-urdf"), ("base.values[1]", "theta2")),
    ("a NaN base parameter", _set(("base", "values", 0), float("nan")), ("validate", "codegen"),
     ("base.values[0]", "finite", "nan")),
    ("a string base parameter", _set(("base", "values", 3), "abc"), ("validate", "codegen"),
     ("base.values[3]", "'abc'")),
    ("a base parameter missing", _drop_last("base", "values"), ("validate", "export-urdf"),
     ("base.values", "8 numbers", "got 7")),
    ("a drive value missing", _drop_last("drive", "values"), ("validate", "codegen", "export-urdf"),
     ("drive.values", "one per drive.names")),
    ("a null drive value", _set(("drive", "values", 2), None), ("validate",), ("drive.values[2]", "none")),
    ("a drive name renamed", _set(("drive", "names", 0), "fk1"), ("codegen",), ("drive.names", "fk1")),
    ("a negative mass in a file claiming consistency", _negative_mass, ("validate", "codegen", "export-urdf"),
     ("standard.consistent is true", "m2=-3", "pseudo-inertia eigenvalue")),
    ("consistent is the string 'yes'", _set(("standard", "consistent"), "yes"), ("validate", "export-urdf"),
     ("standard.consistent", "boolean", "'yes'")),
    ("checked is 1", _set(("standard", "checked"), 1), ("codegen",), ("standard.checked", "boolean")),
    ("a standard parameter null in a checked file", _set(("standard", "values", 0), None), ("export-urdf",),
     ("standard.values[0]", "finite")),
    ("the robot text edited", _edit_robot_text, ("validate", "codegen", "export-urdf"), ("robot.sha256", "edited")),
    ("the robot hash zeroed", _set(("robot", "sha256"), "0" * 64), ("validate",), ("robot.sha256", "0000")),
    ("no cutoff frequency", _set(("identification", "cutoff_hz"), []), ("validate",),
     ("identification.cutoff_hz", "positive")),
    ("a drive-inertia joint 0", _set(("drive", "inertia_joints"), [0]), ("codegen",),
     ("drive.inertia_joints", "1..4")),
]  # fmt: skip


@pytest.fixture(scope="module")
def good_document():
    return model_document()


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))  # outside the case's folder


CASES = [(name, edit, command) for name, edit, commands, _ in EDITS for command in commands]


@pytest.mark.parametrize("name, edit, command", CASES, ids=[f"{c[2]}: {c[0]}" for c in CASES])
def test_an_edited_model_file_is_refused(name, edit, command, good_document, tmp_path, capsys, monkeypatch):
    document = copy.deepcopy(good_document)
    edit(document)
    expect = next(words for case, _, _, words in EDITS if case == name)
    case = BadInput(name, COMMANDS[command], ("model.json", FIX, *expect), {"model.json": model_text(document)})
    err = check_refusal(case, tmp_path, capsys, monkeypatch)
    assert len(err.strip().splitlines()) == 1, err


def test_the_unedited_file_is_accepted(good_document, tmp_path, capsys, monkeypatch):
    """The cases above fail because of their edit: the same file unedited exports."""
    from psdm_casadi.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "model.json").write_text(model_text(good_document))
    assert main(list(URDF)) == 0, capsys.readouterr().err
    assert "NOT physically consistent" not in (tmp_path / "out.urdf").read_text()
