"""Measure the batched C (``codegen.batch``) against Pinocchio's parallel algorithms, in one C++ process.

Issue 18, item 3: states per second per core (one thread) and on all cores, for batches of B states
per call (B = 1024 by default, as the GPU anchor), against ``pinocchio::rneaInParallel`` /
``abaInParallel`` (``pinocchio/algorithm/parallel``, OpenMP, in the pin wheel), Pinocchio's
CppADCodeGen rnea/aba (``codegen.peers.cppadcg``) and Pinocchio's regressor in OpenMP loops; the
single-call exported C in an OpenMP loop is timed beside them. The
figure is also given per core against the published GPU anchor (GRiD: about 75 M inverse-dynamics
states per second for a 7-DOF arm on an RTX 5090, N = 1024).

Per core is measured in states per CPU-second of the process on one thread, which does not depend on
what else the machine runs; all cores in states per wall-clock second. ``benchmarks/batch_speed.py``
prints the table; ``benchmarks/dynamics_speed.py`` merges the figures into its JSON.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from codegen.batch import export_batch
from codegen.peers import cppadcg as cppadcg_code
from codegen.peers.harness import cpp_model_code, cpp_numbers, run_command
from codegen.peers.speed import OPT_FLAGS, PINOCCHIO_DEFINES, find_prerequisites
from psdm_casadi.errors import SolverError
from psdm_casadi.oracle import build_pinocchio_model

TEMPLATE = Path(__file__).resolve().parent / "templates" / "batch_bench.cpp.in"
# GRiD (Plancher et al.) inverse dynamics on an RTX 5090, 7-DOF arm, N = 1024: states per second.
GPU_ANCHOR_STATES_PER_S = 75e6
# (label, our key, Pinocchio key) of the rows of the batch table.
BATCH_ROWS = (
    ("inverse dynamics", "id", "pinocchio_rnea_parallel"),
    ("forward dynamics", "fd", "pinocchio_aba_parallel"),
    ("regressor Y", "regressor", "pinocchio_regressor_loop"),
)
MAX_THREADS = 32
# OpenMP threads wait for the next parallel region as libgomp lets them when nothing is set: they spin for
# 300,000 iterations (a fraction of a millisecond) and then sleep. Back-to-back batches therefore find the
# pool awake, as a user's control or estimation loop does. Forcing them to sleep at once (PASSIVE) costs a
# wake-up per call, tens of microseconds in a virtual machine, against about 15 us of work per thread for
# 1024 states of inverse dynamics: that, not the kernel, held two threads to 1.2-1.4x. The one-thread
# figures are per CPU-second of the calling thread, so spinning pool threads do not inflate them.
HARNESS_ENV = {"OMP_WAIT_POLICY": "ACTIVE", "GOMP_SPINCOUNT": "300000"}


# Per quantity, the CPU peers of the batch table: (our key, peers timed as <peer>_t<threads>).
CPU_PEERS = {
    "id": ("pinocchio_rnea_parallel", "cppadcg_rnea_loop"),
    "fd": ("pinocchio_aba_parallel", "cppadcg_aba_loop"),
    "regressor": ("pinocchio_regressor_loop",),
}


def best_cpu_peer(rates: dict, key: str) -> str:
    """The CPU peer with the most states per second on one thread, of those timed, for ``key`` (id, fd, regressor)."""
    timed = [peer for peer in CPU_PEERS[key] if f"{peer}_t1" in rates]
    return max(timed, key=lambda peer: rates[f"{peer}_t1"])


def batch_ratios(rates: dict, threads: int) -> dict:
    """The issue-18 batch figures from the harness's states per second (``<key>_t<threads>``).

    Per core is one thread; the best CPU peer is the fastest peer timed on one thread (Pinocchio's
    parallel algorithms, and CppADCodeGen's functions in an OpenMP loop when that peer was built).
    """
    ours_1, ours_all = rates["psdm_batch_id_t1"], rates[f"psdm_batch_id_t{threads}"]
    best = best_cpu_peer(rates, "id")
    result = {
        "batch_states_per_s_per_core": ours_1,
        "batch_states_per_s_all_cores": ours_all,
        "batch_speedup_vs_best_cpu_peer": ours_1 / rates[f"{best}_t1"],
        "batch_vs_gpu_anchor_per_core": ours_1 / GPU_ANCHOR_STATES_PER_S,
        "batch_best_cpu_peer": best,
    }
    for key in ("fd", "regressor"):
        peer = best_cpu_peer(rates, key)
        result[f"batch_{key}_speedup_vs_best_cpu_peer"] = rates[f"psdm_batch_{key}_t1"] / rates[f"{peer}_t1"]
    return result


def thread_scaling(wall_rates: dict, threads: int) -> dict:
    """Wall-clock states per second on ``threads`` threads over one thread, ours and Pinocchio's, per quantity.

    ``{"psdm": {"id": .., "fd": .., "regressor": ..}, "pinocchio": {...}}``: the issue-29 figure
    ``batch_thread_scaling`` (both rates per wall-clock second, so that it measures what a second core adds).
    """
    scaling = {"psdm": {}, "pinocchio": {}}
    for _, ours, peer in BATCH_ROWS:
        for side, key in (("psdm", f"psdm_batch_{ours}"), ("pinocchio", peer)):
            if f"{key}_t1" in wall_rates and f"{key}_t{threads}" in wall_rates:
                scaling[side][ours] = wall_rates[f"{key}_t{threads}"] / wall_rates[f"{key}_t1"]
    return scaling


def _cppadcg_objects(pin_model, workdir: Path, cache: Path, eigen, include, log) -> tuple:
    """(object files, None) of Pinocchio's CppADCodeGen code of one robot, or ([], reason) when it cannot be built."""
    try:
        generator = cppadcg_code.build_generator(cache, eigen, include, PINOCCHIO_DEFINES, log)
        objects = []
        wanted = {f"{cppadcg_code.c_function(name)}.c" for name in ("rnea", "aba")}
        for source in cppadcg_code.generate_sources(generator, pin_model, workdir / "cppadcg"):
            if source.name not in wanted:
                continue
            run_command(["cc", *OPT_FLAGS, "-w", "-c", str(source), "-o", str(source.with_suffix(".o"))], workdir)
            objects.append(str(source.with_suffix(".o")))
    except SolverError as exc:
        return [], str(exc)
    return objects, None


def _compile_harness(workdir: Path, export, peer_objects, cppadcg_error, eigen, include):
    """Compile the batch export and link batch_bench (with CppADCodeGen's objects when they were built; without
    them, and saying why, when that link fails). Returns the CppADCodeGen error or None."""
    ours = []
    for c_file in (export.single.source, export.source):
        run_command(["cc", *OPT_FLAGS, "-fopenmp", "-c", c_file.name, "-o", f"{c_file.stem}.o"], workdir)
        ours.append(f"{c_file.stem}.o")
    flags = [*OPT_FLAGS, "-std=c++17", "-fopenmp", *PINOCCHIO_DEFINES, f"-I{eigen}", f"-I{include}", "-w"]
    if cppadcg_error is None:
        try:
            run_command(
                ["c++", *flags, "-DPSDM_CPPADCG", "batch_bench.cpp", *ours, *peer_objects, "-o", "batch_bench"], workdir
            )
            return None
        except SolverError as exc:
            cppadcg_error = f"the harness did not link with CppADCodeGen's code: {exc}"
    run_command(["c++", *flags, "batch_bench.cpp", *ours, "-o", "batch_bench"], workdir)
    return cppadcg_error


def measure_batch_speed(
    robot,
    workdir,
    *,
    theta=None,
    batch: int = 1024,
    n_batches: int = 64,
    repeats: int = 5,
    threads: int | None = None,
    cppadcg: bool = True,
    cppadcg_cache=None,
    log=None,
) -> dict:
    """Export, compile and run the batch harness of one robot.

    Parameters
    ----------
    robot : RobotDescription
        With nominal inertia (the Pinocchio model uses it).
    workdir : Path
        Build folder (created; files of an earlier run are replaced).
    theta : array, optional
        Base parameters baked in; the robot's nominal ones by default.
    batch, n_batches, repeats : int
        States per call, calls per round (distinct states), rounds (the median is reported).
    threads : int, optional
        Threads of the all-cores figures; OpenMP's default (all cores) when None.
    cppadcg : bool
        Also time Pinocchio's CppADCodeGen rnea/aba in an OpenMP loop (``codegen.peers.cppadcg``); when
        it cannot be built, ``batch["cppadcg_error"]`` says why.
    cppadcg_cache : Path, optional
        Where the CppADCodeGen generator is compiled once and reused; ``workdir`` by default.
    log : callable, optional
        Progress messages.

    Returns
    -------
    dict
        ``batch_states_per_s_per_core``, ``batch_states_per_s_all_cores``, ``batch_speedup_vs_best_cpu_peer``
        and ``batch_vs_gpu_anchor_per_core`` (inverse dynamics), the forward-dynamics and regressor ratios,
        and under ``batch`` every rate, the errors against Pinocchio and the harness settings.

    Raises
    ------
    SolverError
        When a prerequisite is missing, or a compile or run fails.
    """
    from psdm_casadi.derive import derive_psdm
    from psdm_casadi.recursive import build_recursive_functions

    log = log or (lambda message: None)
    if threads is not None and not 1 <= threads <= MAX_THREADS:
        raise SolverError(f"batch_speed threads must be in 1..{MAX_THREADS}; got {threads}.")
    workdir = Path(workdir)
    eigen, include = find_prerequisites()
    pin_model = build_pinocchio_model(robot)
    t0 = time.perf_counter()
    model = derive_psdm(robot)
    functions = build_recursive_functions(model, robot)
    if theta is None:
        theta = model.base_parameters(robot.nominal_dynamic_parameters())
    theta = np.asarray(theta, dtype=float).ravel()
    export = export_batch(functions, workdir, theta=theta, library="psdm_batch_dyn", overwrite=True)
    log(f"{robot.name}: batch export in {time.perf_counter() - t0:.1f} s (state lanes: {export.state_lanes})")
    source = (
        TEMPLATE.read_text()
        .replace("@ROBOT@", robot.name)
        .replace("@LIBRARY_PREFIX@", "psdm_")
        .replace("@LIBRARY@", export.library)
        .replace("@N_DOF@", str(pin_model.nv))
        .replace("@N_BASE@", str(theta.size))
        .replace("@THETA@", cpp_numbers(theta))
        .replace("@JOINTS@", cpp_model_code(pin_model))
        .replace("@ARMATURE@", cpp_numbers(pin_model.armature))
        .replace("@GRAVITY@", cpp_numbers(pin_model.gravity.linear))
        .replace("@CPPADCG_RNEA@", cppadcg_code.c_function("rnea"))
        .replace("@CPPADCG_ABA@", cppadcg_code.c_function("aba"))
    )
    (workdir / "batch_bench.cpp").write_text(source)
    t0 = time.perf_counter()
    peer_objects, cppadcg_error = [], "not asked for (cppadcg=False)"
    if cppadcg:
        cache = Path(cppadcg_cache or workdir)
        peer_objects, cppadcg_error = _cppadcg_objects(pin_model, workdir, cache, eigen, include, log)
    cppadcg_error = _compile_harness(workdir, export, peer_objects, cppadcg_error, eigen, include)
    log(f"{robot.name}: compiled in {time.perf_counter() - t0:.1f} s; {n_batches} x {batch} states x {repeats}")
    out = run_command(
        ["./batch_bench", str(batch), str(n_batches), str(repeats), str(threads or 0)], workdir, HARNESS_ENV
    )
    harness = json.loads(out.strip().splitlines()[-1])
    harness.pop("sink", None)
    harness.update(state_lanes=list(export.state_lanes), lane_width=export.lane_width, cppadcg_error=cppadcg_error)
    scaling = thread_scaling(harness["states_per_s_wall"], harness["threads"])
    return {
        **batch_ratios(harness["states_per_s"], harness["threads"]),
        "batch_thread_scaling": scaling,
        "batch": harness,
    }
