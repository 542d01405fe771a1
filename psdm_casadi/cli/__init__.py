"""The ``psdm`` command: the composition layer over the four library packages.

Every subcommand has a module here (``derive``, ``excite``, ``simulate``, ``identify``, ``diagnose``,
``codegen``) with a ``register(subparsers)`` function; ``psdm_casadi.demo`` adds ``demo``. Only this
package and the demo import more than one of ``psdm_casadi``, ``trajopt``, ``identification`` and
``codegen`` (tests/test_architecture.py checks it). A handler returns an exit code; errors of
psdm-casadi print in one line (``--debug`` shows the traceback).

Exit codes: 0 success, 1 a check failed (e.g. accuracy or a target not met), 2 bad input
(file, option, data), 3 a solver or compiler failed, 130 interrupted, 141 stdout closed by its reader
(``psdm ... | head -1``: the files are written, the rest of the printout is dropped). With ``--json`` an
error is printed as ``{"command", "error", "exit_code"}`` on stdout as well.
"""

from __future__ import annotations

import argparse
import logging
import sys

from psdm_casadi.cli.blas_threads import blas_thread_limit
from psdm_casadi.cli.checks import check_seed
from psdm_casadi.cli.column_hint import with_own_columns
from psdm_casadi.cli.interrupts import InterruptGuard
from psdm_casadi.cli.output import (
    EXIT_BAD_INPUT,
    EXIT_BROKEN_PIPE,
    EXIT_CHECK_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_SOLVER,
    configure_logging,
    json_printed,
    print_json,
    progress,
    remove_logging,
    reset_json,
    silence_stdout,
)
from psdm_casadi.errors import PSDMError, SolverError
from psdm_casadi.log_context import once_per_run
from psdm_casadi.overwrite_option import DEPRECATED_FORCE_NOTE, used_deprecated_force

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_BROKEN_PIPE",
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
    from psdm_casadi.cli import (
        codegen,
        derive,
        diagnose,
        excite,
        export_mjcf,
        export_urdf,
        fleet,
        identify,
        simulate,
        validate,
    )

    parser = argparse.ArgumentParser(
        prog="psdm",
        description=(
            "Pseudo-Symbolic Dynamic Modeling of robot arms: derive a minimal regressor model from a robot "
            "file, design excitation, identify it from recordings, diagnose missing physics, export C. "
            "Start with 'psdm demo' or 'psdm derive denso_vs6556g'."
        ),
    )
    parser.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    parser.add_argument(
        "--no-cache",
        action="store_true",
        help="derive the robot's model even when the model cache holds it (cache folder: $PSDM_CACHE_DIR, else "
        "the user's cache folder)",
    )
    verbosity = parser.add_mutually_exclusive_group()
    verbosity.add_argument("-q", "--quiet", action="store_true", help="no progress lines, only warnings and errors")
    verbosity.add_argument("-v", "--verbose", action="store_true", help="more detail on what each step does")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in (
        derive,
        excite,
        simulate,
        identify,
        validate,
        diagnose,
        codegen,
        export_urdf,
        export_mjcf,
        fleet,
        demo,
    ):
        module.register(subparsers)
    return parser


def _log_level(args) -> int:
    if args.quiet or getattr(args, "json", False):
        return logging.WARNING
    return logging.DEBUG if args.verbose else logging.INFO


def main(argv=None) -> int:
    """Run ``psdm`` on ``argv``; return the exit code (a usage error returns 2 after argparse's message)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help exits 0 through argparse; a usage error returns its code
        if exc.code in (0, None):
            raise
        return int(exc.code) if isinstance(exc.code, int) else EXIT_BAD_INPUT
    if not getattr(args, "handler", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    configure_logging(_log_level(args))
    reset_json()
    if used_deprecated_force(args):
        print(f"psdm {args.command}: note: {DEPRECATED_FORCE_NOTE}.", file=sys.stderr)
    try:
        with InterruptGuard(), blas_thread_limit(), once_per_run():  # a line every fit repeats, said once
            check_seed(getattr(args, "seed", None))
            code = int(args.handler(args) or 0)
            sys.stdout.flush()  # a closed stdout shows here, not in Python's flush at exit
            return code
    except KeyboardInterrupt:
        message = "interrupted; no output was written or changed"
        print(f"psdm {args.command}: {message}", file=sys.stderr)
        _json_error(args, message, EXIT_INTERRUPTED)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # stdout closed by its reader (| head): the files are written; end quietly
        silence_stdout()
        return EXIT_BROKEN_PIPE
    except SolverError as exc:
        return _report(args, exc, EXIT_SOLVER)
    except (PSDMError, OSError) as exc:
        return _report(args, exc, EXIT_BAD_INPUT)
    finally:  # the command's stderr may close after it (tests run many commands in one process)
        remove_logging()


def _report(args, exc: Exception, code: int) -> int:
    """Print an error of a command in one line (``--debug``: raise it with its traceback)."""
    if args.debug:
        raise exc
    message = str(exc)
    if isinstance(exc, OSError) and exc.strerror and message.startswith("["):  # [Errno 13] ...: name the file
        where = f" {str(exc.filename)!r}" if exc.filename else ""
        message = f"{exc.strerror}:{where}. Check the file and folder options (--out, --data, ...)."
    if "=PREFIX:" in message:  # a unit hint: in this file's column names, as the option to pass
        message = with_own_columns(message, getattr(args, "columns", None))
    print(f"psdm {args.command}: error: {message}", file=sys.stderr)
    _json_error(args, message, code)
    return code


def _json_error(args, message: str, code: int) -> None:
    """With ``--json``, an error is one JSON object on stdout too (unless the command printed its own)."""
    if not getattr(args, "json", False) or json_printed():
        return
    try:
        print_json({"command": args.command, "error": message, "exit_code": code})
    except BrokenPipeError:
        silence_stdout()


if __name__ == "__main__":
    sys.exit(main())
