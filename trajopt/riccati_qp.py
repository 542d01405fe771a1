"""The real-time iteration's QP solved on its stage structure by C of this package: a Riccati recursion, with
a primal-dual interior point on the bounds only when the bounds are needed.

The QP of one RTI step (``trajopt.mpc_rti``) is a multiple-shooting OCP: a diagonal Hessian (the
least-squares tracking cost), the linearised dynamics ``dx_{k+1} = A_k dx_k + B_k du_k + b_k`` and
bounds on every variable. HPIPM (through CasADi) solves it with a Riccati-based interior point whose
dense algebra is BLASFEO's; CasADi ships BLASFEO's portable build, where the QP took two thirds of the
Panda's step (perf on ``examples/mpc_rti_loop.c``). ``templates/riccati_qp.c`` is the same
structure-exploiting method written for this problem: the sizes are compile-time constants (the
compiler unrolls and vectorises the stage products for the machine, ``-O3 -march=native`` as the
rest of the step), and it first solves the equality-constrained QP by one Riccati factorisation:
when that solution is within every bound it is the bounded QP's solution (zero bound multipliers
satisfy its KKT conditions), which is what a tracking step away from the limits needs; otherwise a
Mehrotra predictor-corrector interior point starts from it pushed inside the bounds, one Riccati
factorisation per iteration, at most ``max_iter``. The C follows CasADi's external-function API:
``riccati_qp`` compiles and loads it (``casadi.external``) for CasADi's evaluation of the step, and
the step's generated C calls the same function (``compile_rti`` compiles the two files together).
"""

from __future__ import annotations

import hashlib
import logging
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import casadi as ca

from psdm_casadi.errors import SolverError
from trajopt.c_compiler import run_compiler

LOG = logging.getLogger(__name__)
TEMPLATE = Path(__file__).resolve().parent / "templates" / "riccati_qp.c"
DEFAULT_FLAGS = ("-O3", "-march=native")
# the compiled QPs of this process: folders kept alive while their libraries are loaded
_LOADED: dict = {}


@dataclass(frozen=True)
class RiccatiQP:
    """The stage-structured QP solver of one problem size, as C and as a loaded CasADi Function.

    Attributes
    ----------
    name : str
        The C function's name (``psdm_rti_qp_<hash>``, one per size and options).
    source : str
        The C (``templates/riccati_qp.c`` with its sizes and options in front).
    function : casadi.Function
        ``(h, g, jac, b, lbx, ubx) -> (z, lam_g)``: diag Hessian, gradient, stage Jacobians
        ``[A_0 B_0 ... A_{N-1} B_{N-1}]``, offsets of the dynamics, bounds (x_0 fixed by lbx) -> the
        solution in stage order and the dynamics' multipliers (CasADi's sign).
    """

    name: str
    source: str
    function: ca.Function


def riccati_qp_source(n_x: int, n_u: int, horizon: int, max_iter: int, tol: float) -> tuple[str, str]:
    """(name, C source) of the solver for these sizes and options."""
    defines = f"#define NX {n_x}\n#define NU {n_u}\n#define NH {horizon}\n"
    defines += f"#define PSDM_QP_MAX_ITER {max_iter}\n#define PSDM_QP_TOL {float(tol)!r}\n"
    text = defines + TEMPLATE.read_text()
    name = "psdm_rti_qp_" + hashlib.sha256(text.encode()).hexdigest()[:12]
    return name, f"#define PSDM_QP_NAME {name}\n{text}"


def riccati_qp(
    n_x: int, n_u: int, horizon: int, max_iter: int, tol: float, *, compiler="cc", flags=DEFAULT_FLAGS
) -> RiccatiQP:
    """Compile (once per process and size) and load the solver.

    Raises
    ------
    SolverError
        When the compiler is missing or fails.
    """
    name, source = riccati_qp_source(n_x, n_u, horizon, max_iter, tol)
    key = (name, compiler, tuple(flags))
    if key not in _LOADED:
        found = shutil.which(compiler)
        if found is None:
            raise SolverError(
                f"the RTI's QP solver is C compiled on first use; compiler {compiler!r} was not found on PATH. "
                "Install gcc, or build_rti(..., qp_solver='hpipm').",
                status="compiler",
            )
        folder = tempfile.TemporaryDirectory(prefix="psdm-rti-qp-")
        path = Path(folder.name) / f"{name}.c"
        path.write_text(source)
        library = path.with_suffix(".so")
        command = [found, *flags, "-fPIC", "-shared", "-o", str(library), str(path), "-lm"]
        run_compiler(command, "the RTI's QP solver")
        _LOADED[key] = (folder, ca.external(name, str(library)))
        LOG.debug("compiled the RTI's QP solver %s", library)
    return RiccatiQP(name, source, _LOADED[key][1])
