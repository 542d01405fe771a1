"""The bad-input catalogue's one check: run ``psdm`` on a bad input and hold it to the error contract.

Each case is a :class:`BadInput`: the command line, files to create first, and the words the error
message must contain (the input it names and the fix it proposes). :func:`check_refusal` runs the
command in-process and asserts

- the exit code (2 for bad input unless the case says otherwise);
- that no traceback reaches the terminal and no exception escapes ``main``;
- that stderr contains every expected word (case-insensitive);
- that no file that existed before the run changed, and no file appeared outside the case's
  ``may_create`` (checksums of the whole working folder before and after).

The cases live in the ``test_*.py`` files of this folder, one file per kind of input.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from psdm_casadi.cli import main


@dataclass(frozen=True)
class BadInput:
    """One bad input: ``argv`` with ``{tmp}`` for the case's folder, files to write first, expected words."""

    name: str
    argv: tuple
    expect: tuple
    files: dict = field(default_factory=dict)  # relative path -> str or bytes
    exit_code: int = 2
    may_create: tuple = ()  # relative paths a refusal may still leave (none by default)

    def __str__(self) -> str:
        return self.name


def _snapshot(folder: Path) -> dict:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def write_files(folder: Path, files: dict) -> None:
    for relative, content in files.items():
        path = folder / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)


def check_refusal(case: BadInput, folder: Path, capsys, monkeypatch) -> str:
    """Run ``case`` in ``folder`` (the working directory) and assert the error contract; return stderr."""
    monkeypatch.chdir(folder)
    write_files(folder, case.files)
    before = _snapshot(folder)
    argv = [a.replace("{tmp}", str(folder)) for a in case.argv]
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == case.exit_code, f"{case.name}: exit {code}, expected {case.exit_code}\n{err}"
    assert "Traceback" not in err + out, f"{case.name}: a traceback reached the terminal\n{err}"
    lowered = err.lower()
    missing = [word for word in case.expect if word.lower() not in lowered]
    assert not missing, f"{case.name}: the message lacks {missing}:\n{err}"
    after = _snapshot(folder)
    changed = [p for p in before if after.get(p) != before[p]]
    assert not changed, f"{case.name}: changed or removed {changed}"
    created = [p for p in after if p not in before and not any(p.startswith(m) for m in case.may_create)]
    assert not created, f"{case.name}: left {created}"
    return err
