"""mkdocs hook: the command-line reference, generated from the ``psdm`` parsers at every build.

``docs/reference/cli.md`` holds the hand-written conventions and the marker ``<!-- psdm-cli -->``; this
hook replaces the marker with one section per subcommand (and per ``psdm fleet`` action): its one-line
help and its ``--help`` text. Generated at build time, the page cannot fall behind the parsers, and a
parser that fails to build fails ``mkdocs build``.
"""

from __future__ import annotations

import argparse
import os

MARKER = "<!-- psdm-cli -->"


def subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """(name, one-line help, parser) of each subcommand of ``parser``, in registration order."""
    for action in parser._actions:  # argparse has no public accessor for its subparsers
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help or "" for choice in action._choices_actions}
            return [(name, helps.get(name, ""), sub) for name, sub in action.choices.items()]
    return []


def section(name: str, help_text: str, parser: argparse.ArgumentParser, level: int) -> list[str]:
    lines = [f"{'#' * level} `{name}`", ""]
    if help_text:
        lines += [help_text[0].upper() + help_text[1:] + ("" if help_text.endswith(".") else "."), ""]
    lines += ["```text", parser.format_help().rstrip(), "```", ""]
    for sub_name, sub_help, sub in subcommands(parser):
        lines += section(f"{name} {sub_name}", sub_help, sub, level + 1)
    return lines


def cli_reference() -> str:
    """The Markdown of every ``psdm`` subcommand: a summary table, then one section each."""
    os.environ["COLUMNS"] = "100"  # argparse wraps at the terminal's width: the same page on every machine
    from psdm_casadi.cli import build_parser

    parser = build_parser()
    commands = subcommands(parser)
    lines = ["| command | what it does |", "|---|---|"]
    lines += [f"| [`psdm {name}`](#psdm-{name.replace(' ', '-')}) | {help_text} |" for name, help_text, _ in commands]
    lines += ["", "## `psdm`", "", "```text", parser.format_help().rstrip(), "```", ""]
    for name, help_text, sub in commands:
        lines += section(f"psdm {name}", help_text, sub, 2)
    return "\n".join(lines)


def on_page_markdown(markdown: str, page, config, files) -> str:  # mkdocs' hook signature
    """Replace the marker of the CLI reference page with the generated reference."""
    if MARKER not in markdown:
        return markdown
    return markdown.replace(MARKER, cli_reference())
