"""The ``psdm`` command: the composition layer over the four library packages.

Every subcommand has a module here (``derive``, ``excite``, ``simulate``, ``identify``, ``diagnose``,
``codegen``) with a ``register(subparsers)`` function; ``psdm_casadi.demo`` adds ``demo``. Only this
package and the demo import more than one of ``psdm_casadi``, ``trajopt``, ``identification`` and
``codegen`` (tests/test_architecture.py checks it). A handler returns an exit code; errors of
psdm-casadi print in one line (``--debug`` shows the traceback).

Exit codes: 0 success, 1 a check failed (e.g. accuracy or a target not met), 2 bad input
(file, option, data), 3 a solver or compiler failed, 130 interrupted.
"""

from __future__ import annotations

import argparse
import logging
import sys

from psdm_casadi.cli.output import (
    EXIT_BAD_INPUT,
    EXIT_CHECK_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_SOLVER,
    configure_logging,
    print_json,
    progress,
)
from psdm_casadi.errors import PSDMError, SolverError

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_CHECK_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_SOLVER",
    "build_parser",
    "main",
    "print_json",
    "progress",
]


def build_parser() -> argparse.ArgumentParser:
    """The ``psdm`` parser with every subcommand."""
    from psdm_casadi import demo
    from psdm_casadi.cli import codegen, derive, diagnose, excite, identify, simulate

    parser = argparse.ArgumentParser(
        prog="psdm",
        description=(
            "Pseudo-Symbolic Dynamic Modeling of robot arms: derive a minimal regressor model from a robot "
            "file, design excitation, identify it from recordings, diagnose missing physics, export C. "
            "Start with 'psdm demo' or 'psdm derive denso_vs6556g'."
        ),
    )
    parser.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    verbosity = parser.add_mutually_exclusive_group()
    verbosity.add_argument("-q", "--quiet", action="store_true", help="no progress lines, only warnings and errors")
    verbosity.add_argument("-v", "--verbose", action="store_true", help="more detail on what each step does")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in (derive, excite, simulate, identify, diagnose, codegen, demo):
        module.register(subparsers)
    return parser


def _log_level(args) -> int:
    if args.quiet or getattr(args, "json", False):
        return logging.WARNING
    return logging.DEBUG if args.verbose else logging.INFO


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    configure_logging(_log_level(args))
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
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
