"""Measure the exported C against Pinocchio's C++ and a CasADi SX Newton-Euler model, in one C++ process.

Shared by ``benchmarks/dynamics_speed.py`` and ``psdm demo``. One C++ program is generated per robot:
it builds the Pinocchio model from the Python model's numbers, checks every implementation against
Pinocchio on 1000 states, and times each on the same pre-generated random states (median of repeats).
Needs a C/C++ compiler, Eigen (the ``cmeel-eigen`` wheel, or Debian's ``libeigen3-dev``) and the
Pinocchio/Boost headers of the ``pin`` wheel.

Run as ``python -m codegen.peers.speed ROBOT_FILE --samples N --json`` to print one robot's result.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from codegen.derivatives import build_derivative_functions, lane_kernels
from codegen.export import export_c
from codegen.peers.harness import cpp_model_code, cpp_numbers, run_command
from codegen.peers.rnea_sx import build_rnea_functions
from psdm_casadi.errors import SolverError
from psdm_casadi.oracle import build_pinocchio_model

TEMPLATE = Path(__file__).resolve().parent / "templates" / "dynamics_bench.cpp.in"

PINOCCHIO_DEFINES = (
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30",
    "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
    "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
    "-DNDEBUG",
)
OPT_FLAGS = ("-O3", "-march=native")
SYSTEM_EIGEN_DIRS = (Path("/usr/include/eigen3"), Path("/usr/local/include/eigen3"))


def cmeel_prefix() -> Path:
    """The cmeel prefix of the installed ``pin`` wheel (Pinocchio and Boost headers)."""
    import pinocchio

    for parent in Path(pinocchio.__file__).resolve().parents:
        candidate = parent / "cmeel.prefix"
        if candidate.is_dir():
            return candidate
    return (
        Path(sys.prefix)
        / "lib"
        / f"python{sys.version_info.major}.{sys.version_info.minor}"
        / "site-packages"
        / "cmeel.prefix"
    )


def find_prerequisites() -> tuple:
    """(eigen_include, pinocchio_include) or raise SolverError saying what to install."""
    import shutil

    include = cmeel_prefix() / "include"
    eigen = next((d for d in (include / "eigen3", *SYSTEM_EIGEN_DIRS) if (d / "Eigen" / "Core").exists()), None)
    if eigen is None:
        raise SolverError(
            "Eigen headers not found; install them: pip install cmeel-eigen (or apt-get install libeigen3-dev)."
        )
    if not (include / "pinocchio" / "algorithm" / "rnea.hpp").exists() or not (include / "boost" / "mpl").is_dir():
        raise SolverError(
            f"Pinocchio/Boost headers not found under {include}; install the 'pin' wheel (pip install pin)."
        )
    for tool in ("cc", "c++"):
        if shutil.which(tool) is None:
            raise SolverError(f"no '{tool}' compiler on PATH; install one (apt-get install -y g++).")
    return eigen, include


# (label, our key suffix, Pinocchio key, CasADi Newton-Euler key) of the rows of every speed table.
SPEED_ROWS = (
    ("inverse dynamics", "id", "pinocchio_rnea", "casadi_rnea_id"),
    ("forward dynamics", "fd", "pinocchio_aba", "casadi_rnea_fd"),
    ("regressor Y", "regressor", "pinocchio_regressor", None),
)

# The sum form (the paper's pseudo-symbolic sum) is timed too when the model has few enough functions to
# compile quickly; a large sum form (the Panda's) would dominate the benchmark's compile time.
SUM_FORM_MAX_FUNCTIONS = 5000


@dataclass(frozen=True)
class _Variant:
    """One PSDM export timed by the harness: JSON keys ``<key>_id``, ``<key>_fd``, ``<key>_regressor``."""

    key: str
    functions: object
    label: str


def psdm_variants(robot, *, sum_form=None) -> tuple:
    """(variants, model, theta): the recursive form and, if small enough or asked, the sum form.

    theta are the robot's nominal base parameters (baked into every variant).
    """
    from psdm_casadi.derive import derive_psdm
    from psdm_casadi.recursive import build_recursive_functions
    from psdm_casadi.symbolic import build_functions

    model = derive_psdm(robot)
    variants = [_Variant("psdm", build_recursive_functions(model, robot), "recursive form")]
    if sum_form is None:
        sum_form = model.has_monomials and model.n_functions <= SUM_FORM_MAX_FUNCTIONS
    if sum_form:
        variants.append(_Variant("psdm_sum", build_functions(model), "sum form (paper)"))
    return tuple(variants), model


def _variant_setup(variant, n_base, theta) -> str:
    """C++ lines declaring one exported variant's calls (library ``<key>_dyn``) and checking them."""
    k = variant.key
    return "\n".join(
        [
            f"  static const double {k}_theta[] = {{{cpp_numbers(theta)}}};",
            f"  CasadiCall {k}_id = CASADI_CALL({k}_inverse_dynamics, n);",
            f"  CasadiCall {k}_fd = CASADI_CALL({k}_forward_dynamics, n);",
            f"  CasadiCall {k}_y = CASADI_CALL({k}_regressor, n * {n_base});",
            f'  errors["{k}_id"] = id_error({k}_id);',
            f'  errors["{k}_fd"] = fd_error({k}_fd);',
            f'  errors["{k}_regressor"] = regressor_error({k}_y, {k}_theta, {n_base});',
        ]
    )


def _variant_timing(variant) -> str:
    """C++ lines timing one variant in a round: JSON keys ``<key>_id``, ``<key>_fd``, ``<key>_regressor``."""
    k = variant.key
    return "\n".join(
        [
            f'    rounds["{k}_id"].push_back(time_id({k}_id));',
            f'    rounds["{k}_fd"].push_back(time_fd({k}_fd));',
            f'    rounds["{k}_regressor"].push_back(time_id({k}_y));',
        ]
    )


def _cppadcg_peer(pin_model, workdir: Path, cache: Path, log, key: str) -> dict:
    """Generate and compile Pinocchio's CppADCodeGen code of one robot for the harness.

    Returns ``{"objects": [...], "declarations", "setup", "timing"}``, or ``{"error": reason}`` when the peer
    cannot be built here (the benchmark reports the reason and null ratios rather than dropping it).
    """
    from codegen.peers import cppadcg

    eigen, include = find_prerequisites()
    try:
        generator = cppadcg.build_generator(cache, eigen, include, PINOCCHIO_DEFINES, log)
        t0 = time.perf_counter()
        sources = cppadcg.generate_sources(generator, pin_model, workdir / "cppadcg")
        objects = []
        for source in sources:
            obj = source.with_suffix(".o")
            run_command(["cc", *OPT_FLAGS, "-w", "-c", str(source), "-o", str(obj)], workdir)
            objects.append(str(obj))
    except SolverError as exc:
        log(f"{key}: CppADCodeGen peer not built: {exc}")
        return {"error": str(exc)}
    log(f"{key}: CppADCodeGen code generated and compiled in {time.perf_counter() - t0:.0f} s")
    declarations, setup, timing = cppadcg.harness_code(10 * (pin_model.njoints - 1))
    return {"objects": objects, "declarations": declarations, "setup": setup, "timing": timing}


def _export_derivatives(variant, workdir: Path, theta):
    """(DerivativeFunctions, CExport, vector kernels) of a variant's inverse/forward dynamics derivatives, library
    ``psdm_deriv``."""
    derivatives = build_derivative_functions(variant.functions, regressor=False)
    kernels = lane_kernels(derivatives, theta, prefix="psdm_")  # the rows' reverse sweeps in vector lanes
    export = export_c(
        derivatives.all(),
        workdir,
        theta=theta,
        runtime_theta=False,
        library="psdm_deriv",
        prefix="psdm_",
        overwrite=True,
        kernels=kernels,
    )
    return derivatives, export, kernels


def _compile_harness(workdir: Path, libraries, extra_objects, eigen, include) -> None:
    """Compile the exported C libraries and link them with bench.cpp (and the CppADCodeGen objects)."""
    objects = []
    for lib in libraries:
        run_command(["cc", *OPT_FLAGS, "-c", f"{lib}.c", "-o", f"{lib}.o"], workdir)
        objects.append(f"{lib}.o")
    command = ["c++", *OPT_FLAGS, "-std=c++17", *PINOCCHIO_DEFINES, f"-I{eigen}", f"-I{include}", "-w", "bench.cpp"]
    run_command([*command, *objects, *extra_objects, "-o", "bench", "-lm"], workdir)


def measure_speed(
    robot,
    workdir,
    *,
    theta=None,
    n_samples: int = 1_000_000,
    repeats: int = 5,
    log=None,
    key: str | None = None,
    sum_form: bool | None = None,
    cppadcg_cache=None,
    cppadcg: bool = True,
) -> dict:
    """Export, generate, compile and run the harness of one robot; returns its timings and ratios.

    Parameters
    ----------
    robot : RobotDescription
        With nominal inertia (the Pinocchio and Newton-Euler models use it).
    workdir : Path
        Build folder (created).
    theta : array, optional
        Base parameters baked into the PSDM functions; the robot's nominal ones by default (the
        Pinocchio model always has the nominal inertia, so other values fail the agreement check).
    n_samples, repeats : int
        Random states per repeat, and repeats (the median is reported).
    log : callable, optional
        Progress messages.
    key : str, optional
        Name of the robot in the messages.
    sum_form : bool, optional
        Also time the sum form; by default when the model has at most SUM_FORM_MAX_FUNCTIONS functions.
    cppadcg_cache : Path, optional
        Folder where the CppADCodeGen generator is compiled once and reused (default: ``workdir``).
    cppadcg : bool
        Build and time the CppADCodeGen peer (minutes of compilation); when False its ratios are None with
        the reason "not requested".

    Returns
    -------
    dict
        ``ns`` (median time per call), ``max_abs_error`` against Pinocchio on 1000 states, the five
        ratios of issue 3 for the recursive form (``*_speedup_*``), the same for the sum form under
        ``sum_form`` when timed, and operation counts.

    Raises
    ------
    SolverError
        When a prerequisite is missing or a compile or run fails.
    """
    workdir = Path(workdir)
    log = log or (lambda message: None)
    key = key or robot.name
    eigen, include = find_prerequisites()
    pin_model = build_pinocchio_model(robot)
    n = pin_model.nv
    workdir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    peer = build_rnea_functions(pin_model)
    peer_export = export_c(
        [peer.inverse_dynamics, peer.forward_dynamics], workdir, library="rnea_dyn", prefix="rnea_", overwrite=True
    )
    variants, model = psdm_variants(robot, sum_form=sum_form)
    if theta is None:
        theta = model.base_parameters(robot.nominal_dynamic_parameters())
    theta = np.asarray(theta, dtype=float).ravel()
    exports = {}
    for variant in variants:
        functions = variant.functions
        exports[variant.key] = export_c(
            [functions.inverse_dynamics, functions.forward_dynamics, functions.regressor],
            workdir,
            theta=theta,
            runtime_theta=False,
            library=f"{variant.key}_dyn",
            prefix=f"{variant.key}_",
            overwrite=True,
            regressor_structure=functions.regressor_structure,
        )
    derivatives, derivatives_export, kernels = _export_derivatives(variants[0], workdir, theta)
    log(f"{key}: exported in {time.perf_counter() - t0:.1f} s ({', '.join(v.label for v in variants)}, derivatives)")
    joints = cpp_model_code(pin_model)
    source = (
        TEMPLATE.read_text()
        .replace("@ROBOT@", robot.name)
        .replace("@N_DOF@", str(n))
        .replace("@JOINTS@", joints)
        .replace("@ARMATURE@", cpp_numbers(pin_model.armature))
        .replace("@GRAVITY@", cpp_numbers(pin_model.gravity.linear))
        .replace("@INCLUDES@", "\n".join(f'#include "{v.key}_dyn.h"' for v in variants))
        .replace("@VARIANT_SETUP@", "\n".join(_variant_setup(v, theta.size, theta) for v in variants))
        .replace("@VARIANT_TIMING@", "\n".join(_variant_timing(v) for v in variants))
    )
    if cppadcg:
        cppadcg_peer = _cppadcg_peer(pin_model, workdir, Path(cppadcg_cache or workdir), log, key)
    else:
        cppadcg_peer = {"error": "not requested (--no-cppadcg)"}
    for part in ("declarations", "setup", "timing"):
        source = source.replace(f"@CPPADCG_{part.upper()}@", cppadcg_peer.get(part, ""))
    (workdir / "bench.cpp").write_text(source)
    t0 = time.perf_counter()
    libraries = ["rnea_dyn", "psdm_deriv"] + [f"{v.key}_dyn" for v in variants]
    _compile_harness(workdir, libraries, cppadcg_peer.get("objects", []), eigen, include)
    log(f"{key}: compiled in {time.perf_counter() - t0:.1f} s; running {n_samples} states x {repeats} repeats")
    out = run_command(["./bench", str(n_samples), str(repeats)], workdir)
    result = json.loads(out.strip().splitlines()[-1])
    result.update(robot=robot.name, n_dof=n, n_base=int(theta.size), n_functions=int(model.n_functions))
    result.update(speedups(result["ns"], "psdm"))
    result.update(derivative_speedups(result["ns"]))
    result.update(cppadcg_speedups(result["ns"], cppadcg_peer.get("error")))
    result.update(
        id_speedup_vs_casadi_pinocchio=None,
        fd_speedup_vs_casadi_pinocchio=None,
        casadi_pinocchio_error=CASADI_PINOCCHIO_ERROR,
    )
    if "psdm_sum" in exports:
        result["sum_form"] = speedups(result["ns"], "psdm_sum")
    result["n_operations"] = {c.name: c.n_operations for e in exports.values() for c in e.operation_counts}
    result["n_operations"].update({c.name: c.n_operations for c in derivatives_export.operation_counts})
    result["fd_derivatives_form"] = derivatives.forward_form
    result["lane_operations"] = {  # what the derivatives run: scalar part once, vector instructions for all rows
        k.name: {"scalar": k.n_scalar_operations, "vector": k.n_vector_operations} for k in kernels
    }
    result["n_instructions"] = {name: count for e in exports.values() for name, count in e.n_instructions.items()}
    result["casadi_rnea_n_instructions"] = peer_export.n_instructions
    result["casadi_rnea_n_operations"] = {c.name: c.n_operations for c in peer_export.operation_counts}
    return result


def speedups(ns: dict, key: str) -> dict:
    """The five ratios of issue 3 (peer time / our time) for the variant ``key`` of a harness result."""
    return {
        "id_speedup_vs_pinocchio": ns["pinocchio_rnea"] / ns[f"{key}_id"],
        "fd_speedup_vs_pinocchio": ns["pinocchio_aba"] / ns[f"{key}_fd"],
        "regressor_speedup_vs_pinocchio": ns["pinocchio_regressor"] / ns[f"{key}_regressor"],
        "id_speedup_vs_casadi_rnea": ns["casadi_rnea_id"] / ns[f"{key}_id"],
        "fd_speedup_vs_casadi_rnea": ns["casadi_rnea_fd"] / ns[f"{key}_fd"],
    }


def derivative_speedups(ns: dict) -> dict:
    """Pinocchio's analytical derivatives' time / the exported PSDM derivatives' time."""
    return {
        "id_derivatives_speedup_vs_pinocchio": ns["pinocchio_rnea_derivatives"] / ns["psdm_id_derivatives"],
        "fd_derivatives_speedup_vs_pinocchio": ns["pinocchio_aba_derivatives"] / ns["psdm_fd_derivatives"],
    }


# Pinocchio templated on CasADi's SX (pinocchio/autodiff/casadi.hpp) and generated by CasADi: not built by this
# harness; the JSON says so (null ratios and this reason) rather than dropping the peer.
CASADI_PINOCCHIO_ERROR = (
    "not built: the pin wheel ships no CasADi bindings (no pinocchio.casadi module), and compiling Pinocchio's "
    "C++ templated on casadi::SX against the casadi wheel's libcasadi is not implemented in this harness; the "
    "CasADi SX Newton-Euler peer (casadi_rnea_*) is the CasADi-generated Newton-Euler code timed instead"
)

# (JSON ratio, our key, CppADCodeGen keys: the ratio is against the fastest of them).
CPPADCG_RATIOS = (
    ("id_speedup_vs_cppadcg", "psdm_id", ("cppadcg_rnea",)),
    ("fd_speedup_vs_cppadcg", "psdm_fd", ("cppadcg_aba",)),
    ("regressor_speedup_vs_cppadcg", "psdm_regressor", ("cppadcg_regressor",)),
    ("id_derivatives_speedup_vs_cppadcg", "psdm_id_derivatives", ("cppadcg_rnea_jacobian", "cppadcg_rnea_derivatives")),
    ("fd_derivatives_speedup_vs_cppadcg", "psdm_fd_derivatives", ("cppadcg_aba_jacobian", "cppadcg_aba_derivatives")),
)


def cppadcg_speedups(ns: dict, error: str | None) -> dict:
    """Ratios against Pinocchio's CppADCodeGen code (its fastest route per quantity); None with ``cppadcg_error``
    when that peer was not built."""
    if error is not None:
        return {**{name: None for name, _, _ in CPPADCG_RATIOS}, "cppadcg_error": error}
    return {name: min(ns[p] for p in peers) / ns[ours] for name, ours, peers in CPPADCG_RATIOS}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="Time one robot's exported C against Pinocchio (prints JSON).")
    parser.add_argument("robot", help="robot file (.toml or .urdf) with nominal inertia")
    parser.add_argument("--workdir", type=Path, required=True)
    parser.add_argument("--samples", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--theta", type=Path, help=".npy file of base parameters to bake in")
    parser.add_argument(
        "--sum-form",
        choices=("auto", "yes", "no"),
        default="auto",
        help=f"also time the paper's sum form (auto: models of at most {SUM_FORM_MAX_FUNCTIONS} functions)",
    )
    parser.add_argument("--no-cppadcg", action="store_true", help="skip the CppADCodeGen peer (minutes of compilation)")
    args = parser.parse_args(argv)
    from psdm_casadi.robot import load_robot

    theta = np.load(args.theta) if args.theta else None
    try:
        result = measure_speed(
            load_robot(args.robot),
            args.workdir,
            theta=theta,
            n_samples=args.samples,
            repeats=args.repeats,
            log=lambda m: print(m, file=sys.stderr, flush=True),
            sum_form={"auto": None, "yes": True, "no": False}[args.sum_form],
            cppadcg=not args.no_cppadcg,
        )
    except SolverError as exc:
        print(json.dumps({"error": str(exc)}))
        return 3
    print(json.dumps(result, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
