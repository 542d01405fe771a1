"""HPIPM inside the generated C of the real-time-iteration MPC: which HPIPM/BLASFEO it links, and a
workspace kept from one call to the next.

CasADi's generated HPIPM call (``casadi_hpipm_solve``) allocates HPIPM's dimensions, QP, solution,
arguments and interior-point workspace with ``malloc`` on every call, zeroes them (HPIPM's
``*_create``) and frees them again: for the Panda's N = 20 QP about 0.1 ms of a 0.6 ms step went
into page faults and ``memset`` (perf on ``examples/mpc_rti_loop.c``). The problem's dimensions
are fixed in the generated code, so ``persistent_workspace`` rewrites that function to create them
once and reuse them; every value HPIPM reads is set again on each call (``d_ocp_qp_set_all``, the
arguments copied from the options, no warm start), so a step is the same computation as before
(the tests compare it with CasADi's own evaluation of the step). The function keeps one workspace
per loaded library: one thread at a time calls a compiled controller, as a control loop does.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import casadi as ca

from psdm_casadi.errors import ParameterError, SolverError

SOLVE_START = "int casadi_hpipm_solve("
SOLVE_END = "   return d->return_status==0;\n}"
READY = "psdm_hpipm_ready"


def persistent_workspace(text: str) -> str:
    """The generated C with ``casadi_hpipm_solve`` creating HPIPM's structures once (see the module).

    Raises
    ------
    SolverError
        When the generated function does not have the shape this rewrite knows (another CasADi):
        five allocations, five HPIPM structures created, five frees.
    """
    start = text.find(SOLVE_START)
    end = text.find(SOLVE_END, start)
    if start < 0 or end < 0:
        raise _unexpected("casadi_hpipm_solve was not found")
    lines, counts = [], {"malloc": 0, "struct": 0, "create": 0, "free": 0}
    for line in text[start:end].split("\n"):
        stripped = line.strip()
        allocation = re.fullmatch(r"void \*(\w+) = malloc\((\w+)\);", stripped)
        if allocation:
            name, size = allocation.groups()
            lines.append(f"    static void *{name} = 0; if (!{name}) {name} = malloc({size});")
            counts["malloc"] += 1
        elif re.fullmatch(r"struct d_ocp_qp\w* \w+;", stripped):
            lines.append(f"    static {stripped}")
            counts["struct"] += 1
        elif re.match(r"d_ocp_qp\w*_create\(", stripped):
            lines.append(f"    if (!{READY}) {stripped}")
            counts["create"] += 1
        elif re.fullmatch(r"free\(\w+\);", stripped):
            counts["free"] += 1
        else:
            lines.append(line)
    body = "\n".join(lines)
    solve = "d_ocp_qp_ipm_solve(&qp"
    if any(count != 5 for count in counts.values()) or body.count(solve) != 1:
        raise _unexpected(f"found {counts} and {body.count(solve)} solve call(s)")
    body = body.replace(solve, f"{READY} = 1;\n    {solve}")
    return f"{text[:start]}static int {READY} = 0;\n{body}{text[end:]}"


def _unexpected(detail: str) -> SolverError:
    return SolverError(
        f"export_rti_c: CasADi {ca.__version__} generated the HPIPM call differently than expected ({detail}); "
        "the persistent HPIPM workspace cannot be applied. Use CasADi 3.7-3.8 or check the generated code.",
        status="codegen",
    )


def hpipm_folders(hpipm_dir=None) -> tuple[Path, Path]:
    """(include, lib) folders of the HPIPM and BLASFEO the C links against.

    ``hpipm_dir`` (else ``$PSDM_HPIPM_DIR``) is an install prefix of both (``include/``, ``lib/``; static
    libraries built with -fPIC are linked in, else the shared ones),
    e.g. BLASFEO built for the machine's CPU (``TARGET=X64_INTEL_HASWELL``) as acados does; its
    headers must be those CasADi's generated code was written for (HPIPM af3ca47, BLASFEO 0.1.4.2
    for CasADi 3.7-3.8). By default CasADi's own copies, whose BLASFEO is the portable (generic) build.
    """
    chosen = hpipm_dir or os.environ.get("PSDM_HPIPM_DIR")
    if not chosen:
        folder = Path(ca.__file__).parent
        return folder / "include", folder
    folder = Path(chosen)
    if not (folder / "include" / "hpipm_d_ocp_qp_ipm.h").exists() or not (folder / "lib").is_dir():
        raise ParameterError(
            f"compile_rti hpipm_dir must hold include/hpipm_d_ocp_qp_ipm.h and lib/; got {str(folder)!r}. "
            "Pass the install prefix of HPIPM and BLASFEO, or unset PSDM_HPIPM_DIR for CasADi's copies."
        )
    return folder / "include", folder / "lib"
