"""The ``psdm`` command: one entry point whose subcommands each package registers.

Each package declares a ``register(subparsers)`` function under the ``psdm.commands`` entry-point
group in pyproject.toml, so this module never imports the other packages. A handler returns an
exit code; errors of psdm-casadi print in one line (``--debug`` shows the traceback).

Exit codes: 0 success, 1 a check failed (e.g. accuracy or a target not met), 2 bad input
(file, option, data), 3 a solver or compiler failed.
"""

from __future__ import annotations

import argparse
import json
import sys
from importlib.metadata import entry_points

from .errors import PSDMError, SolverError

EXIT_OK, EXIT_CHECK_FAILED, EXIT_BAD_INPUT, EXIT_SOLVER = 0, 1, 2, 3


def print_json(payload) -> None:
    """Print one JSON object on stdout (the ``--json`` contract of every subcommand)."""
    print(json.dumps(payload, sort_keys=False, default=float))


def progress(message: str, *, quiet: bool = False) -> None:
    """A progress line on stderr, so stdout stays machine-readable."""
    if not quiet:
        print(message, file=sys.stderr, flush=True)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="psdm",
        description=(
            "Pseudo-Symbolic Dynamic Modeling of robot arms: derive a minimal regressor model from a robot "
            "file, design excitation, identify it from recordings, diagnose missing physics, export C. "
            "Start with 'psdm demo' or 'psdm derive robots/denso_vs6556g.toml'."
        ),
    )
    parser.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    from . import commands  # the derive command lives in this package (imported late: it imports cli)

    commands.register(subparsers)
    for entry in sorted(entry_points(group="psdm.commands"), key=lambda e: e.name):
        if entry.value.startswith("psdm_casadi."):
            continue
        try:
            entry.load()(subparsers)
        except ImportError as exc:  # a package of the distribution failed to import: say so, keep the rest
            print(f"psdm: warning: command group {entry.name!r} unavailable ({exc})", file=sys.stderr)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    try:
        return int(args.handler(args) or 0)
    except SolverError as exc:
        if args.debug:
            raise
        print(f"psdm {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_SOLVER
    except (PSDMError, FileNotFoundError, FileExistsError) as exc:
        if args.debug:
            raise
        print(f"psdm {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("psdm: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
