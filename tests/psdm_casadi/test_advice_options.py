"""Every command-line option the library's and the command line's messages name is one ``psdm`` parses.

A new user read identify's advice for a link at its inertia floor, "or keep the robot file's inertia of this link",
and found no option that does it; advice that names an option that was renamed or never existed is the same fault in
a form a scan can catch. Reference: the options of every subcommand of ``psdm_casadi.cli.build_parser`` against each
``--name`` in a string constant of ``identification`` and ``psdm_casadi`` (messages, help, docstrings). The demo's
timing script has a parser of its own (``psdm_casadi/demo/speed.py``) and is left out.
"""

from __future__ import annotations

import argparse
import ast
import re
from pathlib import Path

from psdm_casadi.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
OWN_PARSER = {Path("psdm_casadi/demo/speed.py")}
OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


def _options(parser) -> set:
    out = set()
    for action in parser._actions:
        out.update(action.option_strings)
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                out |= _options(sub)
    return out


def test_every_option_a_message_names_is_parsed_by_psdm():
    known = _options(build_parser())
    unknown = []
    for package in ("identification", "psdm_casadi"):
        for path in sorted((ROOT / package).rglob("*.py")):
            if path.relative_to(ROOT) in OWN_PARSER:
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Constant) and isinstance(node.value, str):
                    unknown += [f"{path.relative_to(ROOT)}:{node.lineno} {name}"
                                for name in OPTION.findall(node.value) if name not in known]  # fmt: skip
    assert len(known) > 50  # the scan reads the real parser
    assert not unknown, unknown
