"""HPIPM inside the generated C of the real-time-iteration MPC: which HPIPM/BLASFEO it links (``make hpipm``'s
build for this CPU when there is one), and a workspace kept from one call to the next.

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

import logging
import os
import re
from pathlib import Path

import casadi as ca

from psdm_casadi.errors import ParameterError, SolverError
from psdm_casadi.model_cache import CACHE_ENV

LOG = logging.getLogger(__name__)

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


def hpipm_cache_folder() -> Path:
    """Where ``make hpipm`` installs BLASFEO and HPIPM built for this CPU: ``hpipm`` in psdm's cache folder
    (``$PSDM_CACHE_DIR/hpipm`` when the variable is set)."""
    override = os.environ.get(CACHE_ENV)
    if override:
        return Path(override).expanduser() / "hpipm"
    import platformdirs

    return Path(platformdirs.user_cache_dir("psdm-casadi")) / "hpipm"


def cpu_runs(folder: Path) -> str | None:
    """None when this CPU runs the BLASFEO installed in ``folder``, else why not (its target's instructions)."""
    target = folder / "include" / "blasfeo_target.h"
    text = target.read_text() if target.exists() else ""
    needed = [flag for flag in ("avx2", "fma", "avx") if f"TARGET_NEED_FEATURE_{flag.upper()} 1" in text]
    flags = cpu_flags()
    missing = [flag for flag in needed if flags is not None and flag not in flags]
    return f"this CPU lacks {', '.join(missing)}" if missing else None


def cpu_flags() -> set | None:
    """The CPU's instruction-set flags (``/proc/cpuinfo``); None without that file (the build is then trusted)."""
    try:
        return set(Path("/proc/cpuinfo").read_text().split())
    except OSError:
        return None


def hpipm_folders(hpipm_dir=None) -> tuple[Path, Path]:
    """(include, lib) folders of the HPIPM and BLASFEO the C links against, and which was chosen is logged.

    In order: ``hpipm_dir``, ``$PSDM_HPIPM_DIR``, the build of ``make hpipm`` in ``hpipm_cache_folder()``
    when this CPU runs it, else CasADi's own copies, whose BLASFEO is the portable (generic) build: the
    Panda's MPC step 1.3-1.6x slower (docs/results/benchmarks.md). A prefix holds ``include/`` and
    ``lib/`` (static libraries built with -fPIC are linked in, else the shared ones), e.g. BLASFEO built for
    the machine's CPU (``TARGET=X64_INTEL_HASWELL``) as acados does (``benchmarks/build_hpipm.sh``); its
    headers must be those CasADi's generated code was written for (HPIPM af3ca47, BLASFEO 0.1.4.2 for
    CasADi 3.7-3.8).
    """
    chosen = hpipm_dir or os.environ.get("PSDM_HPIPM_DIR")
    if not chosen:
        cached = hpipm_cache_folder()
        if (cached / "include" / "hpipm_d_ocp_qp_ipm.h").exists() and (cached / "lib").is_dir():
            reason = cpu_runs(cached)
            if reason is None:
                LOG.info("HPIPM/BLASFEO built for this CPU: %s", cached)
                return cached / "include", cached / "lib"
            LOG.warning("not using the BLASFEO in %s (%s); CasADi's portable copy instead", cached, reason)
        folder = Path(ca.__file__).parent
        LOG.info("HPIPM/BLASFEO: CasADi's portable copies (`make hpipm` builds them for this CPU)")
        return folder / "include", folder
    folder = Path(chosen)
    if not (folder / "include" / "hpipm_d_ocp_qp_ipm.h").exists() or not (folder / "lib").is_dir():
        raise ParameterError(
            f"compile_rti hpipm_dir must hold include/hpipm_d_ocp_qp_ipm.h and lib/; got {str(folder)!r}. "
            "Pass the install prefix of HPIPM and BLASFEO, or unset PSDM_HPIPM_DIR for CasADi's copies."
        )
    return folder / "include", folder / "lib"
