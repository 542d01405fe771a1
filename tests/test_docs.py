"""The documentation cannot rot: its site builds with ``--strict`` and its tutorials' code runs.

``mkdocs build --strict`` (run by ``make test`` before pytest, and here when mkdocs is installed) fails on
a broken link or a page missing from the navigation; the CLI reference is generated from the parsers at
build time (``docs/hooks/cli_reference.py``). The Python blocks of every page in ``docs/tutorials/`` are
executed in order in one namespace, in an empty folder, on the built-in robots; their own asserts check
the results against an independent reference (the two dynamics forms agree, the compiled C equals the
model in Python, the diagnosis finds the hidden spring's stiffness, the MPC tracks its reference). A fenced
block titled with a file name (```` ```c title="feedforward.c" ````) is saved under that name when the
page reaches it, as a reader would save it. Pages whose blocks take long are marked slow in ``SLOW``.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
TUTORIALS = DOCS / "tutorials"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
#: A fenced block of any language, with its info string (``c title="feedforward.c"``) and its text.
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```", re.S | re.M)
TITLE = re.compile(r'title="([^"]+)"')
#: Tutorial pages too long for the default suite (each has a fast test of its own below).
SLOW = {"discovery-loop.md", "four-step.md"}


def python_blocks(page: Path) -> list[str]:
    """The ```python fenced blocks of a Markdown page, in order."""
    return BLOCK.findall(page.read_text(encoding="utf-8"))


def page_steps(page: Path) -> list[tuple[str, str, str]]:
    """The page's executable steps in order: ("python", label, code) or ("file", name, text) for titled blocks."""
    steps = []
    for info, text in FENCE.findall(page.read_text(encoding="utf-8")):
        language, title = info.split(" ")[0].strip(), TITLE.search(info)
        if language == "python":
            steps.append(("python", f"{page.name} block {len(steps) + 1}", text))
        elif title is not None:
            steps.append(("file", title.group(1), text))
    return steps


def run_page(page: Path) -> dict:
    """Run the page as a reader would: save its titled files and execute its Python blocks in one namespace."""
    return run_steps(page_steps(page))


def run_steps(steps) -> dict:
    """Run ``page_steps`` in order in one namespace (the current folder receives the files)."""
    namespace: dict = {"__name__": "tutorial"}
    for kind, label, text in steps:
        if kind == "file":
            Path(label).write_text(text, encoding="utf-8")
        else:
            exec(compile(text, label, "exec"), namespace)  # the page's own code, run as a reader would
    return namespace


def tutorial_pages() -> list:
    pages = sorted(TUTORIALS.glob("*.md"))
    return [pytest.param(p, marks=pytest.mark.slow) if p.name in SLOW else p for p in pages if page_steps(p)]


def test_python_blocks_are_found():
    """The extractor sees every block of every tutorial (a renamed fence would silently run nothing)."""
    for page in TUTORIALS.glob("*.md"):
        text = page.read_text(encoding="utf-8")
        blocks = [code for kind, _, code in page_steps(page) if kind == "python"]
        assert len(blocks) == len(python_blocks(page)) == text.count("```python"), page.name
    assert len(python_blocks(TUTORIALS / "first-model.md")) >= 5


def test_every_tutorial_with_code_is_run_and_listed_in_the_site():
    """No tutorial escapes: each page with code is in the parametrised run below and in mkdocs.yml's nav."""
    pages = {p.name for p in TUTORIALS.glob("*.md") if page_steps(p)}
    assert {"first-model.md", "ros2-bag-to-c.md", "discovery-loop.md", "mpc.md", "four-step.md"} <= pages
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    assert all(f"tutorials/{name}" in nav for name in pages)
    assert SLOW <= pages


def test_titled_blocks_are_saved_as_files_before_the_code_that_uses_them(tmp_path, monkeypatch):
    page = tmp_path / "page.md"
    page.write_text('Text\n```c title="a.c"\nint x;\n```\n```python\nassert open("a.c").read() == "int x;\\n"\n```\n')
    monkeypatch.chdir(tmp_path)
    assert [kind for kind, _, _ in page_steps(page)] == ["file", "python"]
    run_page(page)
    page.write_text('```python\nassert False, "the page own assert"\n```\n')
    with pytest.raises(AssertionError, match="page own assert"):
        run_page(page)


@pytest.mark.parametrize("page", tutorial_pages(), ids=lambda p: p.stem)
def test_tutorial_runs(page, tmp_path, monkeypatch):
    """Every block of the tutorial runs and its asserts hold (first-model 3 s idle, ros2-bag-to-c 15 s, ...).

    Not marked slow on purpose (except the pages in ``SLOW``): ``make test`` must execute the tutorials, or
    a page can rot unseen."""
    monkeypatch.chdir(tmp_path)
    run_page(page)


def test_discovery_loop_until_the_diagnosis(tmp_path, monkeypatch):
    """The fast part of the (slow) discovery-loop page: its recordings with a hidden spring and the identification
    whose joint 4 fits badly (the page's own assert); the diagnosis and --apply run with the whole page."""
    monkeypatch.chdir(tmp_path)
    steps = page_steps(TUTORIALS / "discovery-loop.md")
    first = next(k for k, (kind, _, text) in enumerate(steps) if kind == "python" and 'psdm("diagnose' in text)
    assert first >= 3
    run_steps(steps[:first])


def test_four_step_route_designs(tmp_path, monkeypatch):
    """The fast part of the (slow) four-step page: the experiments' designs (the motor sweep's speed, the page's
    own assert); the simulation of every experiment, the four steps and the comparison with the truth run
    with the whole page."""
    monkeypatch.chdir(tmp_path)
    steps = page_steps(TUTORIALS / "four-step.md")
    first = next(k for k, (kind, _, text) in enumerate(steps) if kind == "python" and "simulate_calibration(" in text)
    assert first >= 2
    run_steps(steps[:first])
    assert (tmp_path / "friction_j4_validation.csv").exists()


#: A ``psdm`` command line of a fenced block (``\\`` continuations joined), not a line of output (``psdm identify:``).
COMMAND = re.compile(r"^\s*(psdm (?![a-z-]+:)[^\n]*)$", re.M)


def documented_commands() -> list:
    """(page, command) of every ``psdm`` command line the README and the documentation show in a fenced block, its
    trailing comment cut; lines with ``...`` (an elided argument) left out."""
    import shlex

    out = []
    for page in (ROOT / "README.md", *sorted(DOCS.rglob("*.md"))):
        for _, text in FENCE.findall(page.read_text(encoding="utf-8")):
            for line in COMMAND.findall(text.replace("\\\n", " ")):
                line = re.split(r"\s#", line)[0]
                if "..." not in line:
                    out.append((page.relative_to(ROOT), shlex.split(line)[1:]))
    return out


def test_every_documented_command_parses_as_printed(capsys):
    """A reader copies a command from a page: each one the pages show parses with today's options (a renamed or
    removed option fails here, not in the reader's terminal). Parsed, not run: the runs are the tutorials' tests."""
    from psdm_casadi.cli import build_parser

    commands, failed = documented_commands(), []
    assert len(commands) > 50  # the README's and the guides' commands are found
    parser = build_parser()
    for page, argv in commands:
        try:
            parser.parse_args(argv)
        except SystemExit as exc:
            if exc.code:
                failed.append(f"{page}: psdm {' '.join(argv)}: {capsys.readouterr().err.strip().splitlines()[-1]}")
    assert failed == []


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
