"""The documentation cannot rot: its site builds with ``--strict`` and its tutorial's code runs.

``mkdocs build --strict`` (run by ``make test`` before pytest, and here when mkdocs is installed) fails on
a broken link or a page missing from the navigation; the CLI reference is generated from the parsers at
build time (``docs/hooks/cli_reference.py``). The Python blocks of ``docs/tutorials/first-model.md`` are
executed in order in one namespace on the built-in Denso; their own asserts check the results against
the model (the two dynamics forms agree, the fit is consistent and predicts held-out data).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def python_blocks(page: Path) -> list[str]:
    """The ```python fenced blocks of a Markdown page, in order."""
    return BLOCK.findall(page.read_text(encoding="utf-8"))


def test_python_blocks_are_found():
    """The extractor sees every block (a renamed fence would silently run nothing)."""
    page = DOCS / "tutorials" / "first-model.md"
    blocks = python_blocks(page)
    assert len(blocks) == page.read_text(encoding="utf-8").count("```python") >= 5


def test_first_model_tutorial_runs(tmp_path, monkeypatch):
    """Every Python block of the first tutorial runs and its asserts hold (3 s idle, up to 20 s on a loaded machine).

    Not marked slow on purpose: ``make test`` must execute the tutorial, or the page can rot unseen."""
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "tutorial"}
    for index, block in enumerate(python_blocks(DOCS / "tutorials" / "first-model.md")):
        code = compile(block, f"first-model.md block {index + 1}", "exec")
        exec(code, namespace)  # the page's own code, run as a reader would


def test_cli_reference_covers_every_subcommand():
    """The generated CLI reference has a section for each ``psdm`` subcommand, with its --help text."""
    sys.path.insert(0, str(DOCS / "hooks"))
    try:
        import cli_reference
    finally:
        sys.path.remove(str(DOCS / "hooks"))
    from psdm_casadi.cli import build_parser

    text = cli_reference.cli_reference()
    names = [name for name, _, _ in cli_reference.subcommands(build_parser())]
    assert {"derive", "identify", "diagnose", "codegen", "export-urdf", "demo"} <= set(names)
    for name in names:
        assert f"## `psdm {name}`" in text
        assert f"usage: psdm {name}" in text


@pytest.mark.slow
def test_mkdocs_build_strict(tmp_path):
    """The site builds with --strict (broken links, unlisted pages and hook errors fail); ``make test`` runs it."""
    pytest.importorskip("mkdocs")
    pytest.importorskip("material")
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr[-3000:]
