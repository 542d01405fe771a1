"""Speed of the exported PSDM C code against Pinocchio and a direct CasADi SX Newton-Euler model.

For each robot, one C++ program (one process) is generated and compiled with -O3 -march=native. It
times, on the same 10^6 pre-generated random states (median of repeats):

- PSDM inverse dynamics (theta baked in) vs ``pinocchio::rnea``,
- PSDM forward dynamics vs ``pinocchio::aba``,
- PSDM regressor Y vs ``pinocchio::computeJointTorqueRegressor``,
- PSDM inverse/forward dynamics vs a CasADi SX rnea model code-generated the same way.

Targets (issue 3): id >= 8x, fd >= 6x, regressor >= 10x faster than Pinocchio; faster than the
CasADi rnea in both. Usage::

    python benchmarks/dynamics_speed.py [--robots denso panda] [--samples 1000000] [--repeats 5] [--json]

Needs a C/C++ compiler, Eigen (Debian: ``apt-get install libeigen3-dev``) and the Pinocchio/Boost
headers of the ``pin`` wheel (cmeel prefix). Exit code 0 when every target is met, 1 otherwise,
2 when a prerequisite is missing.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from codegen.export import export_c  # noqa: E402
from codegen.rnea_sx import build_rnea_functions  # noqa: E402
from psdm_casadi.oracle import build_pinocchio_model  # noqa: E402
from psdm_casadi.robot import from_urdf, load_robot  # noqa: E402

TARGETS = {
    "id_speedup_vs_pinocchio": 8.0,
    "fd_speedup_vs_pinocchio": 6.0,
    "regressor_speedup_vs_pinocchio": 10.0,
    "id_speedup_vs_casadi_rnea": 1.0,
    "fd_speedup_vs_casadi_rnea": 1.0,
}
PANDA_LOCKED = ("panda_finger_joint1", "panda_finger_joint2")
PINOCCHIO_DEFINES = (
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30",
    "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
    "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
    "-DNDEBUG",
)
OPT_FLAGS = ("-O3", "-march=native")
EIGEN_DIRS = (Path("/usr/include/eigen3"), Path("/usr/local/include/eigen3"))


def cmeel_prefix() -> Path:
    """The cmeel prefix of the installed ``pin`` wheel (Pinocchio and Boost headers)."""
    import pinocchio

    for parent in Path(pinocchio.__file__).resolve().parents:
        candidate = parent / "cmeel.prefix"
        if candidate.is_dir():
            return candidate
    return Path(sys.prefix) / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages" / "cmeel.prefix"


def check_prerequisites() -> tuple[Path, Path]:
    """Include folders of Eigen and of Pinocchio/Boost; exits with a clear message when missing."""
    eigen = next((d for d in EIGEN_DIRS if (d / "Eigen" / "Core").exists()), None)
    if eigen is None:
        sys.exit("dynamics_speed: Eigen headers not found in /usr/include/eigen3. "
                 "Install them: apt-get install -y libeigen3-dev")
    include = cmeel_prefix() / "include"
    if not (include / "pinocchio" / "algorithm" / "rnea.hpp").exists() or not (include / "boost" / "mpl").is_dir():
        sys.exit(f"dynamics_speed: Pinocchio/Boost headers not found under {include}. "
                 "Install the 'pin' wheel (pip install pin), which ships them in cmeel.prefix/include.")
    for tool in ("cc", "c++"):
        if shutil.which(tool) is None:
            sys.exit(f"dynamics_speed: no '{tool}' compiler on PATH. Install one: apt-get install -y g++")
    return eigen, include


def robots():
    """The benchmark robots by short name: the Denso VS-6556G and the 7-DOF Panda (fingers locked)."""
    panda = cmeel_prefix() / "share" / "example-robot-data" / "robots" / "panda_description" / "urdf" / "panda.urdf"
    return {
        "denso": lambda: load_robot(REPO / "robots" / "denso_vs6556g.toml"),
        "panda": lambda: from_urdf(panda, locked_joints=PANDA_LOCKED, name="panda"),
    }


def _cpp_numbers(values) -> str:
    return ", ".join(repr(float(v)) for v in np.asarray(values, dtype=float).ravel())


def _cpp_joint(model, jid) -> str:
    """C++ lines adding joint ``jid`` of a Python pin.Model with its placement and inertia."""
    jmodel = model.joints[jid]
    short = jmodel.shortname()
    if short in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        joint = f"pinocchio::{short}(Eigen::Vector3d({_cpp_numbers(jmodel.extract().axis)}))"
    elif short in ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelPX", "JointModelPY", "JointModelPZ"):
        joint = f"pinocchio::{short}()"
    else:
        raise SystemExit(f"dynamics_speed: joint type {short} is not supported by the harness")
    placement = model.jointPlacements[jid]
    inertia = model.inertias[jid]
    # Eigen's comma initialiser fills row by row
    return "\n".join([
        f"  rotation << {_cpp_numbers(placement.rotation)};",
        f"  translation << {_cpp_numbers(placement.translation)};",
        f"  jid = model.addJoint({model.parents[jid]}, {joint}, pinocchio::SE3(rotation, translation), "
        f"\"{model.names[jid]}\");",
        f"  lever << {_cpp_numbers(inertia.lever)};",
        f"  inertia << {_cpp_numbers(inertia.inertia)};",
        f"  model.inertias[jid] = pinocchio::Inertia({float(inertia.mass)!r}, lever, inertia);",
    ])


def psdm_functions(robot):
    """PSDM Functions and nominal base parameters, or (None, None, reason) when the builder is missing."""
    try:
        from psdm_casadi.derive import derive_psdm
        from psdm_casadi.symbolic import build_functions
    except ImportError as exc:
        return None, None, f"PSDM builder unavailable ({exc})"
    model = derive_psdm(robot)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    return build_functions(model), np.asarray(theta, dtype=float).ravel(), ""


def run_robot(key, robot, workdir: Path, eigen: Path, include: Path, n_samples: int, repeats: int, log) -> dict:
    """Export, generate, compile and run the harness of one robot; returns its timings and ratios."""
    pin_model = build_pinocchio_model(robot)
    n = pin_model.nv
    workdir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    peer = build_rnea_functions(pin_model)
    peer_export = export_c([peer.inverse_dynamics, peer.forward_dynamics], workdir, library="rnea_dyn",
                           prefix="rnea_", overwrite=True)
    functions, theta, reason = psdm_functions(robot)
    psdm_export = None
    if functions is not None:
        psdm_export = export_c([functions.inverse_dynamics, functions.forward_dynamics, functions.regressor], workdir,
                               theta=theta, runtime_theta=False, library="psdm_dyn", prefix="psdm_", overwrite=True)
    else:
        log(f"{key}: {reason}; timing Pinocchio and the CasADi rnea only")
    log(f"{key}: exported in {time.perf_counter() - t0:.1f} s")
    joints = "\n".join(_cpp_joint(pin_model, jid) for jid in range(1, pin_model.njoints))
    template = (REPO / "codegen" / "templates" / "dynamics_bench.cpp.in").read_text()
    n_base = theta.size if theta is not None else 1
    source = (template.replace("@ROBOT@", robot.name).replace("@N_DOF@", str(n)).replace("@JOINTS@", joints)
              .replace("@ARMATURE@", _cpp_numbers(pin_model.armature))
              .replace("@GRAVITY@", _cpp_numbers(pin_model.gravity.linear))
              .replace("@HAVE_PSDM@", "1" if psdm_export else "0").replace("@N_BASE@", str(n_base))
              .replace("@THETA@", _cpp_numbers(theta) if theta is not None else "0.0"))
    (workdir / "bench.cpp").write_text(source)
    t0 = time.perf_counter()
    objects = []
    for lib in ("rnea_dyn", "psdm_dyn") if psdm_export else ("rnea_dyn",):
        _run(["cc", *OPT_FLAGS, "-c", f"{lib}.c", "-o", f"{lib}.o"], workdir)
        objects.append(f"{lib}.o")
    _run(["c++", *OPT_FLAGS, "-std=c++17", *PINOCCHIO_DEFINES, f"-I{eigen}", f"-I{include}", "-w",
          "bench.cpp", *objects, "-o", "bench", "-lm"], workdir)
    log(f"{key}: compiled in {time.perf_counter() - t0:.1f} s; running {n_samples} states x {repeats} repeats")
    out = _run(["./bench", str(n_samples), str(repeats)], workdir)
    result = json.loads(out.strip().splitlines()[-1])
    ns = result["ns"]
    result["robot"] = robot.name
    result["n_dof"] = n
    if psdm_export:
        result["n_base"] = int(theta.size)
        result["n_instructions"] = psdm_export.n_instructions
        result["n_operations"] = {c.name: c.n_operations for c in psdm_export.operation_counts}
        result.update({
            "id_speedup_vs_pinocchio": ns["pinocchio_rnea"] / ns["psdm_id"],
            "fd_speedup_vs_pinocchio": ns["pinocchio_aba"] / ns["psdm_fd"],
            "regressor_speedup_vs_pinocchio": ns["pinocchio_regressor"] / ns["psdm_regressor"],
            "id_speedup_vs_casadi_rnea": ns["casadi_rnea_id"] / ns["psdm_id"],
            "fd_speedup_vs_casadi_rnea": ns["casadi_rnea_fd"] / ns["psdm_fd"],
        })
    else:
        result.update({key_: None for key_ in TARGETS})
    result["casadi_rnea_n_instructions"] = peer_export.n_instructions
    result["casadi_rnea_n_operations"] = {c.name: c.n_operations for c in peer_export.operation_counts}
    return result


def _run(command, cwd) -> str:
    proc = subprocess.run(command, cwd=cwd, capture_output=True, text=True)
    if proc.returncode != 0:
        tail = "\n".join(proc.stderr.strip().splitlines()[-20:])
        sys.exit(f"dynamics_speed: `{' '.join(command)}` failed ({proc.returncode}):\n{tail}")
    return proc.stdout


def print_table(results) -> None:
    rows = [("inverse dynamics", "psdm_id", "pinocchio_rnea", "casadi_rnea_id"),
            ("forward dynamics", "psdm_fd", "pinocchio_aba", "casadi_rnea_fd"),
            ("regressor Y", "psdm_regressor", "pinocchio_regressor", None)]
    for key, r in results.items():
        ns = r["ns"]
        print(f"\n{r['robot']} (n_dof={r['n_dof']}, {r['n_samples']} random states, median of {r['repeats']})")
        print(f"{'function':18s} {'PSDM [us]':>10s} {'Pinocchio [us]':>15s} {'CasADi rnea [us]':>17s} "
              f"{'vs Pinocchio':>13s} {'vs CasADi rnea':>15s}")
        for label, ours, pin_key, peer_key in rows:
            mine = ns[ours] / 1e3 if ns[ours] > 0 else float("nan")
            pin_t = ns[pin_key] / 1e3
            peer_t = ns[peer_key] / 1e3 if peer_key else float("nan")
            print(f"{label:18s} {mine:10.3f} {pin_t:15.3f} {peer_t:17.3f} {pin_t / mine:12.1f}x "
                  f"{(peer_t / mine if peer_key else float('nan')):14.2f}x")
        ops = {**r.get("n_operations", {}), **r["casadi_rnea_n_operations"]}
        print("arithmetic operations: " + ", ".join(f"{k}={v}" for k, v in ops.items()))
        errors = ", ".join(f"{k}={v:.1e}" for k, v in r["max_abs_error"].items())
        print(f"max |error| vs Pinocchio on 1000 states: {errors}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["denso", "panda"], choices=sorted(robots()))
    parser.add_argument("--samples", type=int, default=1_000_000, help="random states per repeat")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--keep", type=Path, default=None, help="build folder to keep (default: a temp folder)")
    parser.add_argument("--json", action="store_true", help="print one JSON object with per-robot entries")
    args = parser.parse_args(argv)
    eigen, include = check_prerequisites()

    def log(message):
        print(message, file=sys.stderr, flush=True)

    base = args.keep if args.keep is not None else Path(tempfile.mkdtemp(prefix="psdm_bench_"))
    results = {}
    try:
        for key in args.robots:
            robot = robots()[key]()
            results[key] = run_robot(key, robot, base / key, eigen, include, args.samples, args.repeats, log)
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)
    met = all(r[k] is not None and r[k] >= target for r in results.values() for k, target in TARGETS.items())
    if args.json:
        print(json.dumps({"robots": results, "targets": TARGETS, "targets_met": met}))
    else:
        print_table(results)
        print("\ntargets " + ("met" if met else "NOT met") + ": " + ", ".join(f"{k} >= {v:g}" for k, v in TARGETS.items()))
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
