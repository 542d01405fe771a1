"""Running the C compiler for the MPC's compiled pieces (the RTI step, its QP solver): one place that runs the
command and turns a failure into a :class:`SolverError` quoting the command and the tail of its output."""

from __future__ import annotations

import shlex
import subprocess

from psdm_casadi.errors import SolverError

__all__ = ["run_compiler"]


def run_compiler(command: list, purpose: str) -> None:
    """Run ``command``; raise ``SolverError`` saying that ``purpose`` must compile when it exits non-zero."""
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        tail = "\n".join(result.stderr.strip().splitlines()[-12:])
        raise SolverError(
            f"{purpose} must compile; `{shlex.join(command)}` exited with {result.returncode}:\n{tail}",
            status=result.returncode,
        )
