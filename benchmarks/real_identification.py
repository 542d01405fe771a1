"""Identification from ordinary recordings on real data: our consistent fit against OLS, the URDF and Gaz et al.

For each real recording in ../shared/datasets (``--data-root PATH``: PATH/datasets and PATH/reference; Staubli
TX40 from FIGAROH, Franka Panda from Gaz et al. 2019; read at run time, never copied; a robot whose data are
absent is skipped), the first 70 % trains and the last 30 % validates (loaders and split of
``real_data_diagnosis``):

- derive the PSDM model and identify on default settings with the library's route that ``psdm identify`` calls
  (``identify_route.identify_recordings``): the Coulomb smoothing, the friction shape, the offsets and the drive
  inertias per joint chosen from the training part alone (information criterion, block cross-validation), the fit,
  the counterbalance its envelope report names, kept only where it holds out of sample, and for the TX40 the coupling
  terms of the wrist its robot file states (``examples/staubli_tx40.toml``'s transmission; ``coupled_drives``, judged by
  block cross-validation of the training part); for comparison the hand-picked options the README used before
  (``OPTIONS``: Coulomb, viscous and offset friction on every joint, drive inertias for the TX40's motor-side torques,
  none for the Panda's link-side sensors) are fitted too (``rmse_options``);
- prepare the validation part with ``prepare_recording`` (the fit's filter, differentiation and
  decimation) and compare, per joint, validation RMSE [N m] and R^2 of (a) our consistent fit,
  (b) the unconstrained weighted least-squares estimate on the same drive columns (without the coupling terms),
  (c) the robot file's URDF/CAD inertias by Pinocchio's rnea (no friction) and (d) for the Panda, the published
  identified model of Gaz et al. (RA-L 2019), ``tau = M(q) ddq + C(q, dq) dq + g(q) + tau_f(dq)``
  on the same prepared samples, and (e) the physically consistent fit on the defaults' columns without the envelope
  (``rmse_consistent``): what the envelope costs;
- where the validation part ends in a standstill (the TX40's last 15 % of the recording, half its validation part: every
  joint within ``REST_RAD`` of its final pose), the RMSE on the moving samples before it as well (``rmse_moving``): at
  rest a joint holds whatever static friction it stopped with (TX40 joint 2: up to fc ~ 8 N m), one constant per joint
  that no model of friction as a function of velocity predicts;
- check consistency: the smallest mass-matrix eigenvalue of our model on random configurations
  within the joint limits and the smallest pseudo-inertia eigenvalue.

The published model is the authors' generated C++ in ../shared/reference/panda_gaz2019_model, compiled
with a shim of ours into a shared library in a cache folder outside the repository
(``~/.cache/psdm-casadi/gaz2019/<hash of sources, shim, flags and compiler>``, or ``--build-dir``)
and loaded with ctypes. The first build takes minutes (CoriolisMatrix.cpp is 2.5 MB, compiled at -O1).

Then, unless ``--no-loop``, the loop a new user runs with default options, ``psdm identify`` -> ``psdm diagnose
model.json --apply`` (``never_worse_loop``), judged by ``psdm validate`` before and after.

Targets: consistent (both eigenvalues > 0); our validation RMSE within 10 % of the consistent fit without the
envelope on every joint (``rmse_vs_consistent``: the envelope's cost. Not the OLS: on the Panda's joint 4 the OLS is
0.194 N m against 0.219 for every consistent fit, with or without the envelope, and a consistent fit that may take a
negative drive inertia on joint 4 gives 0.193 with Ia4 = -0.09 kg m^2: the OLS's gain is a negative inertia about the
joint, which no rigid body or drive has; the OLS is shown);
on the Panda, defaults below the published model on every joint (``defaults_beat_published_every_joint``);
defaults not worse than the hand-picked options beyond 2 % on any joint; derive + identify under 60 s
per robot (with one BLAS thread, as ``psdm`` commands run: ``cli.blas_threads``. With OpenBLAS's threads the Panda's
identify took 12-16 s of CPU against 2 s, its spinning threads' share varying with the machine's load);
``loop_never_worse``: at the end of the loop no joint's validation RMSE above its value after identify plus the
noise margin the diagnosis states; ``mjcf_max_rel_error``: the fit exported as MJCF, MuJoCo's
``mj_inverse`` on the file equals the model's torque without its Coulomb term and offsets to 1e-9 relative
(``mjcf_round_trip``).
Usage::

    python benchmarks/real_identification.py [--robots tx40 panda kinova] [--build-dir DIR] [--jobs 2]
        [--configurations 10000] [--seed 0] [--json] [--no-loop]

Exit code 0 when every target is met, 1 otherwise, 2 when no dataset is found or an option is wrong.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import contextlib
import ctypes
import hashlib
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from bench_support import (
    DEFAULT_DATA_ROOT,
    ROOT,
    add_data_root_argument,
    at_data_root,
    loader_at,
    print_table,
    show_progress,
)
from kinova_gen3 import KINOVA, evaluate_kinova, kinova_missed, print_kinova
from mjcf_round_trip import MJCF_TARGET, mjcf_max_rel_error
from never_worse_loop import ROBOTS as LOOP_ROBOTS
from never_worse_loop import print_loops, run_loops
from real_data_diagnosis import PANDA, REST_RAD, TX40, load_panda_real, load_tx40, split
from tx40_motor_side import compare_routes, shipped_robot

from identification.calibration.identify_route import identify_recordings
from identification.calibration.lugre_recordings import split_findings
from identification.calibration.trajectory_data import prepare_recording
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories, predict_torque
from identification.metrics import r2, rmse
from psdm_casadi import derive_psdm
from psdm_casadi.cli.blas_threads import blas_thread_limit
from psdm_casadi.oracle import PinocchioOracle

GAZ_MODEL = DEFAULT_DATA_ROOT / "reference" / "panda_gaz2019_model"
GAZ_SOURCES = ("CoriolisMatrix.cpp", "MassMatrix.cpp", "GravityVector.cpp", "FrictionTorque.cpp")  # longest first
GAZ_FLAGS = ("-std=c++14", "-O1", "-fPIC", "-DNDEBUG")
SHIM_FLAGS = ("-std=c++14", "-O2", "-fPIC", "-DNDEBUG")
SHIM_NAME = "gaz2019_shim.cpp"
LIBRARY_NAME = "libgaz2019.so"
BUILD_INFO = "build.json"
COMPILE_TIMEOUT_S = 3600.0


def load_tx40_coupled(folder: Path = TX40):
    """``load_tx40`` (the hand-converted joint-side recording) with the transmission of the robot file ``psdm
    identify`` reads the TX40 with (``examples/staubli_tx40.toml``): its coupled wrist, whose coupling terms the route
    fits and judges (``coupled_drives``). Only those read it: the recording is joint-side already."""
    robot, recording = load_tx40(folder)
    return replace(robot, transmission=shipped_robot(folder).transmission), recording


ROBOTS = {"tx40": (TX40, load_tx40_coupled), "panda": (PANDA, load_panda_real)}
# The TX40's torques are motor currents times gear ratios: the rotors' inertia is in them, so drive inertias
# are identified. The Panda's are its link-side joint torque sensors (tau_J, after the gearbox): the rotors
# are on the other side of the sensor, so a drive-inertia column can only fit something else (unconstrained,
# it comes out negative on joints 3-7, e.g. Ia4 = -0.20 kg m^2 at 6.7 sigma), and is not identified.
OPTIONS = {
    "tx40": TrajectoryOptions(friction=("fc", "fv", "offset")),
    "panda": TrajectoryOptions(friction=("fc", "fv", "offset"), drive_inertia=False),
}
CONSISTENT_TOLERANCE = 1.10  # ours may be at most 10 % above the consistent fit without the envelope on a joint
OPTIONS_MARGIN = 1.02  # the defaults may be at most 2 % above the hand-picked options on a joint
MAX_SECONDS = 60.0
TARGETS = {
    "consistent": "min mass-matrix eigenvalue > 0 and min pseudo-inertia eigenvalue > 0",
    "rmse_vs_consistent": f"validation RMSE of ours <= {CONSISTENT_TOLERANCE:g} x the consistent fit without the "
    "envelope on every joint (what the envelope costs)",
    "rmse_vs_published": "Panda: validation RMSE of ours (default options) < the published model (Gaz et al. "
    "2019) on every joint (defaults_beat_published_every_joint)",
    "rmse_vs_options": f"validation RMSE of ours (defaults) <= {OPTIONS_MARGIN:g} x the hand-picked OPTIONS on every "
    "joint",
    "seconds": f"derive + identify < {MAX_SECONDS:g} s per robot",
    "mjcf_max_rel_error": f"MJCF export: MuJoCo's mj_inverse on the written file vs the model's torque without Coulomb "
    f"and offsets <= {MJCF_TARGET:g} relative on the validation states",
    "tx40_motor_side_equal": "TX40: the shipped motor-side files read through examples/staubli_tx40.toml give the "
    "hand-converted route's model (1e-9 relative)",
    "kinova_models": "Kinova Gen3: identify on defaults from the joint-torque sensors and from currents, every link "
    "plausible (mass within 5x the robot file's, centre of mass within reach), no link of either fit at its mass "
    "bound (the example states Kinova's inertials and the tool), no further payload > 0.4 kg found by diagnose",
    "loop_never_worse": "identify -> diagnose --apply (defaults): every joint's validation RMSE at the end <= after "
    "identify + the stated noise margin (never_worse_loop)",
}

# Our own code: evaluates the published functions for n samples stored row by row, (n, 7) in C order.
SHIM_SOURCE = """\
// psdm-casadi benchmark shim: tau = M(q) ddq + C(q, dq) dq + g(q) + tau_f(dq) of Gaz et al.'s Panda model.
#include "franka_model.h"

extern "C" int gaz2019_n_dof(void) { return NUMBER_OF_JOINTS; }

extern "C" void gaz2019_inverse_dynamics(long n, const double *q, const double *dq, const double *ddq,
                                         double *tau) {
    for (long k = 0; k < n; ++k) {
        const Eigen::Vector7d qk = Eigen::Map<const Eigen::Vector7d>(q + NUMBER_OF_JOINTS * k);
        const Eigen::Vector7d dqk = Eigen::Map<const Eigen::Vector7d>(dq + NUMBER_OF_JOINTS * k);
        const Eigen::Vector7d ddqk = Eigen::Map<const Eigen::Vector7d>(ddq + NUMBER_OF_JOINTS * k);
        const Eigen::Vector7d out = MassMatrix(qk) * ddqk + CoriolisMatrix(qk, dqk) * dqk + GravityVector(qk)
                                    + Friction(dqk);
        Eigen::Map<Eigen::Vector7d>(tau + NUMBER_OF_JOINTS * k) = out;
    }
}
"""


class BuildError(RuntimeError):
    """The published model could not be compiled or loaded; the message says why."""


def default_build_dir() -> Path:
    """``$XDG_CACHE_HOME/psdm-casadi/gaz2019`` (``~/.cache/...`` by default): outside the repository."""
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "psdm-casadi" / "gaz2019"


def find_eigen() -> Path:
    """Eigen's include folder: the cmeel-eigen wheel's (cmeel.prefix/include/eigen3), else the system's."""
    paths = sysconfig.get_paths()
    bases = [Path(paths[key]) / "cmeel.prefix" / "include" / "eigen3" for key in ("purelib", "platlib")]
    for folder in (*bases, Path("/usr/include/eigen3"), Path("/usr/local/include/eigen3")):
        if (folder / "Eigen" / "Core").exists():
            return folder
    raise BuildError(
        "Eigen headers not found (cmeel.prefix/include/eigen3 or /usr/include/eigen3); pip install cmeel-eigen"
    )


def find_compiler() -> str:
    compiler = os.environ.get("CXX") or "c++"
    path = shutil.which(compiler)
    if path is None:
        raise BuildError(f"no C++ compiler '{compiler}' on PATH (set CXX or apt-get install g++)")
    return path


def build_key(compiler: str, gaz_model: Path = GAZ_MODEL) -> str:
    """Hash of the published sources and header, the shim, the flags and the compiler's version."""
    digest = hashlib.sha256()
    for path in [gaz_model / "include" / "franka_model.h", *(gaz_model / "src" / name for name in GAZ_SOURCES)]:
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    version = subprocess.run([compiler, "--version"], capture_output=True, text=True, check=False).stdout
    digest.update("\0".join([SHIM_SOURCE, *GAZ_FLAGS, *SHIM_FLAGS, version]).encode())
    return digest.hexdigest()[:16]


def _compile(command: list, name: str) -> float:
    start = time.perf_counter()
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=COMPILE_TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired as exc:
        raise BuildError(f"compiling {name} did not finish in {COMPILE_TIMEOUT_S:g} s") from exc
    if done.returncode != 0:
        tail = " | ".join((done.stderr or done.stdout).strip().splitlines()[-6:])
        raise BuildError(f"{Path(command[0]).name} failed on {name} (exit {done.returncode}): {tail}")
    return time.perf_counter() - start


def build_published_model(build_dir: Path, jobs: int, log, gaz_model: Path = GAZ_MODEL) -> dict:
    """Compile the published model and the shim into a shared library, cached by :func:`build_key`.

    Returns ``{"library": path, "seconds": wall time of this call, "cached": bool, "build_seconds": wall time
    of the build that made the library, "compile_seconds": {file: s}}`` (the last two from the build's
    ``build.json`` when cached; None if it has none).
    Raises BuildError with the reason when a file is absent or the compiler fails.
    """
    start = time.perf_counter()
    missing = [p for p in (gaz_model / "include" / "franka_model.h", *(gaz_model / "src" / n for n in GAZ_SOURCES))
               if not p.exists()]  # fmt: skip
    if missing:
        raise BuildError(f"published model sources absent: {', '.join(str(p) for p in missing)}")
    compiler, eigen = find_compiler(), find_eigen()
    target = build_dir / build_key(compiler, gaz_model)
    library = target / LIBRARY_NAME
    if library.exists():
        info = json.loads((target / BUILD_INFO).read_text()) if (target / BUILD_INFO).exists() else {}
        return {"library": library, "seconds": time.perf_counter() - start, "cached": True,
                "build_seconds": info.get("build_seconds"), "compile_seconds": info.get("compile_seconds")}  # fmt: skip
    build_dir.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f"{target.name}.", dir=build_dir))  # renamed to target when complete
    try:
        (work / SHIM_NAME).write_text(SHIM_SOURCE)
        includes = [f"-I{gaz_model / 'include'}", f"-I{eigen}"]
        units = [(name, gaz_model / "src" / name, GAZ_FLAGS) for name in GAZ_SOURCES]
        units.append((SHIM_NAME, work / SHIM_NAME, SHIM_FLAGS))
        log(f"building the published Panda model with {Path(compiler).name} on {jobs} cores into {target} ...")
        with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
            commands = {name: [compiler, *flags, *includes, "-c", str(src), "-o", str(work / f"{name}.o")]
                        for name, src, flags in units}  # fmt: skip
            futures = {name: pool.submit(_compile, command, name) for name, command in commands.items()}
            times = {name: future.result() for name, future in futures.items()}
        objects = [str(work / f"{name}.o") for name, _, _ in units]
        _compile([compiler, "-shared", "-o", str(work / LIBRARY_NAME), *objects], LIBRARY_NAME)
        for obj in objects:
            Path(obj).unlink()
        seconds = time.perf_counter() - start
        info = {"build_seconds": seconds, "compile_seconds": times, "compiler": compiler, "jobs": jobs}
        (work / BUILD_INFO).write_text(json.dumps(info, indent=1))
        try:
            work.rename(target)
        except OSError:  # another run finished the same build first
            if not library.exists():
                raise
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return {"library": library, "seconds": seconds, "cached": False, "build_seconds": seconds, "compile_seconds": times}


class PublishedModel:
    """Gaz et al.'s identified Panda model from the shared library of :func:`build_published_model`."""

    def __init__(self, library: Path):
        try:
            self._lib = ctypes.CDLL(str(library))
        except OSError as exc:
            raise BuildError(f"cannot load {library}: {exc}") from exc
        array = np.ctypeslib.ndpointer(dtype=np.float64, ndim=2, flags="C_CONTIGUOUS")
        self._lib.gaz2019_inverse_dynamics.argtypes = [ctypes.c_long, array, array, array, array]
        self._lib.gaz2019_inverse_dynamics.restype = None
        self.n_dof = int(self._lib.gaz2019_n_dof())

    def inverse_dynamics(self, q, qd, qdd) -> np.ndarray:
        """Joint torques [N m], (n_samples, 7), of states (n_samples, 7) each."""
        q, qd, qdd = (np.ascontiguousarray(x, dtype=np.float64) for x in (q, qd, qdd))
        if not q.shape == qd.shape == qdd.shape or q.ndim != 2 or q.shape[1] != self.n_dof:
            raise ValueError(f"q, qd, qdd must all have shape (n_samples, {self.n_dof}); got {q.shape}.")
        tau = np.empty_like(q)
        self._lib.gaz2019_inverse_dynamics(q.shape[0], q, qd, qdd, tau)
        return tau


def min_mass_eigenvalue(robot, standard, n_configurations: int, rng) -> float:
    """Smallest eigenvalue of M(q) (Pinocchio crba with ``standard``) over random q within the joint limits."""
    low = np.where(np.isfinite(robot.q_min), robot.q_min, -np.pi)
    high = np.where(np.isfinite(robot.q_max), robot.q_max, np.pi)
    q = rng.uniform(low, high, size=(n_configurations, robot.n_dof))
    return float(np.linalg.eigvalsh(PinocchioOracle(robot, standard).crba(q)).min())


def evaluate_robot(key: str, loader, published, args) -> dict:
    """Identify on the training part and compare the predictions on the prepared validation part."""
    robot, recording = loader()
    train, validation = split(recording)
    start, cpu = time.perf_counter(), time.process_time()
    model = derive_psdm(robot)
    derived = time.perf_counter()
    route = identify_recordings(robot, model, [train])  # the defaults of 'psdm identify' (no --validate: the
    fit, choice = route.fit, route.choice  # held-out part stays out)
    written = len(route.calibrated.document["drive"]["names"])  # a kept coupling's columns follow the fit's own:
    plain = split_findings(fit, len(fit.drive_names) - written)[0] if route.coupled.kept else fit  # its MJCF
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    hand_picked = identify_trajectories(robot, model, [train], OPTIONS[key])
    unbounded = identify_trajectories(robot, model, [train], replace(route.options, envelope=False))
    ready, cutoff, step = prepare_recording(validation, None, fit.cutoff_hz[0], fit.edge_periods)
    q, qd, qdd, tau = ready.q, ready.qd, ready.qdd, ready.tau
    predictions = {
        "": route.calibrated.predict(model, q, qd, qdd),  # with what the route took (a counterbalance spring)
        "_ols": predict_torque(model, route.start, q, qd, qdd, ols=True),  # the default columns (psdm identify's)
        "_options": predict_torque(model, hand_picked, q, qd, qdd),
        "_consistent": predict_torque(model, unbounded, q, qd, qdd),
        "_prior": PinocchioOracle(robot).rnea(q, qd, qdd),
    }
    if published is not None:
        predictions["_published"] = published.inverse_dynamics(q, qd, qdd)
    result = {"robot": robot.name, "n_dof": robot.n_dof}
    moving = moving_samples(q)
    for suffix, tau_hat in predictions.items():
        result[f"rmse{suffix}"] = np.asarray(rmse(tau, tau_hat)).tolist()
        result[f"r2{suffix}"] = np.asarray(r2(tau, tau_hat)).tolist()
        result[f"rmse_moving{suffix}"] = np.asarray(rmse(tau[:moving], tau_hat[:moving])).tolist()
    result["standstill_share"] = 1.0 - moving / len(q)
    rng = np.random.default_rng(args.seed)
    result.update(
        min_mass_eigenvalue=min_mass_eigenvalue(robot, fit.standard, args.configurations, rng),
        mass_configurations=args.configurations,
        min_pseudo_inertia_eigenvalue=float(fit.min_pseudo_inertia_eigenvalue),
        condition_number=float(fit.condition_number),
        seconds=seconds,
        cpu_seconds=cpu,  # derive + identify, this process only: the wall time also counts other processes' load
        derive_seconds=derived - start,
        identify_seconds=seconds - (derived - start),
        solver_status=fit.solver_status,
        n_base=model.n_base,
        n_train_samples=fit.n_samples,
        n_validation_samples=ready.n_samples,
        cutoff_hz=cutoff,
        decimation=step,
        drive=dict(zip(fit.drive_names, fit.drive.tolist())),
        columns=choice.to_dict(),
        columns_text=route.describe(),
        held_back=[item.to_dict() for item in route.held_back],  # what the pull or the envelope keeps from the data
        counterbalance=route.counterbalance.to_dict(),
        warnings=list(fit.warnings),
        **mjcf_max_rel_error(robot, model, plain, q, qd, qdd),
    )
    return result


def moving_samples(q) -> int:
    """The samples before a standstill at the end (every joint within ``REST_RAD`` of its final angle); all without."""
    moved = np.flatnonzero(np.any(np.abs(q - q[-1]) > REST_RAD, axis=1))
    return int(moved[-1]) + 2 if moved.size else len(q)


def missed_targets(results: dict) -> list:
    """One sentence per missed target, e.g. ``"panda rmse_vs_ols: joint 4 0.250 > 1.1 x 0.221"``."""
    missed = []
    for key, r in results.items():
        if r.get("skipped"):
            continue
        mass, pseudo = r["min_mass_eigenvalue"], r["min_pseudo_inertia_eigenvalue"]
        if not (mass > 0 and pseudo > 0):
            missed.append(
                f"{key} consistent: min mass eigenvalue {mass:.3g}, min pseudo-inertia eigenvalue {pseudo:.3g}"
            )
        for j, (ours, bare) in enumerate(zip(r["rmse"], r["rmse_consistent"])):
            if not ours <= CONSISTENT_TOLERANCE * bare:
                missed.append(f"{key} rmse_vs_consistent: joint {j + 1} {ours:.3g} > {CONSISTENT_TOLERANCE:g} x "
                              f"{bare:.3g} N m")  # fmt: skip
        for j, (ours, hand) in enumerate(zip(r["rmse"], r["rmse_options"])):
            if not ours <= OPTIONS_MARGIN * hand:
                missed.append(f"{key} rmse_vs_options: joint {j + 1} {ours:.3g} > {OPTIONS_MARGIN:g} x {hand:.3g} N m")
        if not r["mjcf_max_rel_error"] <= MJCF_TARGET:
            missed.append(f"{key} mjcf_max_rel_error: {r['mjcf_max_rel_error']:.3g} > {MJCF_TARGET:g}")
        if key == "panda":
            if r.get("rmse_published") is None:
                missed.append(f"panda rmse_vs_published: published model not evaluated ({r.get('published_error')})")
            else:
                for j, (ours, theirs) in enumerate(zip(r["rmse"], r["rmse_published"])):
                    if not ours < theirs:
                        missed.append(f"panda rmse_vs_published: joint {j + 1} {ours:.3g} >= {theirs:.3g} N m")
        if not r["seconds"] < MAX_SECONDS:
            missed.append(f"{key} seconds: {r['seconds']:.1f} >= {MAX_SECONDS:g}")
    return missed


def print_robot(key: str, r: dict) -> None:
    if r.get("skipped"):
        print(f"\n{key}: skipped ({r['reason']})")
        return
    print(
        f"\n{key} ({r['robot']}, {r['n_dof']} joints, {r['n_base']} base parameters): validation RMSE [N m] and R^2 "
        f"on the last 30 % ({r['n_validation_samples']} samples after a {r['cutoff_hz']:g} Hz filter, "
        f"decimation {r['decimation']}; trained on {r['n_train_samples']})"
    )
    names = {
        "": "ours",
        "_ols": "OLS",
        "_consistent": "no envelope",
        "_options": "options",
        "_prior": "prior",
        "_published": "published",
    }
    rows = []
    for j in range(r["n_dof"]):
        row = {"joint": j + 1}
        for suffix, label in names.items():
            values = r.get(f"rmse{suffix}")
            row[label] = values[j] if values is not None else "-"
            values = r.get(f"r2{suffix}")
            row[f"R2 {label}"] = values[j] if values is not None else "-"
        rows.append(row)
    print_table(rows, ["joint", *names.values(), *(f"R2 {label}" for label in names.values())])
    if r["standstill_share"] > 0.01:
        print(f"the validation part ends in a standstill ({100 * r['standstill_share']:.0f} % of its samples); RMSE "
              "[N m] on the moving samples before it:")  # fmt: skip
        moving = ["", "_ols", "_consistent", "_options"]
        rows = [{"joint": j + 1, **{names[k]: r[f"rmse_moving{k}"][j] for k in moving}} for j in range(r["n_dof"])]
        print_table(rows, ["joint", *(names[k] for k in moving)])
    print(
        f"min mass eigenvalue {r['min_mass_eigenvalue']:.4g} kg m^2 ({r['mass_configurations']} random "
        f"configurations), min pseudo-inertia eigenvalue {r['min_pseudo_inertia_eigenvalue']:.3g}, condition "
        f"number {r['condition_number']:.3g}, derive {r['derive_seconds']:.1f} s + identify "
        f"{r['identify_seconds']:.1f} s = {r['seconds']:.1f} s wall, {r['cpu_seconds']:.1f} s CPU "
        f"({r['solver_status']})"
    )
    print(f"MJCF export: mj_inverse vs the model, max relative error {r['mjcf_max_rel_error']:.3g} (frictionloss at fc "
          f"on {100 * r['mjcf_friction_saturated']:.0f} % of the sliding samples)")  # fmt: skip
    if key == "panda":
        if r.get("rmse_published") is None:
            print(f"published model (Gaz et al. 2019): not evaluated: {r['published_error']}")
        else:
            built = r["published_original_build_seconds"]
            files = r["published_compile_seconds"] or {}
            detail = ", ".join(f"{name} {seconds:.0f} s" for name, seconds in files.items())
            when = (
                f"cached (looked up in {r['published_build_seconds']:.2f} s); " if r["published_build_cached"] else ""
            )
            took = "unknown" if built is None else f"{built:.1f} s"
            print(f"published model (Gaz et al. 2019): {when}build took {took}" + (f" ({detail})" if detail else ""))
    print("ours: default options, columns chosen from the training part: " + "; ".join(r["columns_text"]))
    print(
        "prior: the URDF's inertias by Pinocchio rnea, no friction; OLS: the weighted least squares on our columns; "
        "no envelope: the consistent fit on our columns without the envelope; "
        "options: the hand-picked OPTIONS (offset on every joint, drive inertias on the TX40 only)"
    )
    if r["warnings"]:
        print("warnings: " + " | ".join(r["warnings"]))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=[*ROBOTS, "kinova"], choices=[*ROBOTS, "kinova"])
    parser.add_argument("--build-dir", type=Path, default=None,
                        help="cache folder of the published model's build (outside the repository; "
                             "default ~/.cache/psdm-casadi/gaz2019)")  # fmt: skip
    parser.add_argument("--jobs", type=int, default=2, help="compiler processes for the published model (default 2)")
    parser.add_argument("--configurations", type=int, default=10_000, help="random q for the mass eigenvalue")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    add_data_root_argument(parser)
    parser.add_argument("--no-loop", action="store_true", help="skip identify -> diagnose --apply (loop_never_worse)")
    args = parser.parse_args(argv)
    show_progress()
    build_dir = (args.build_dir or default_build_dir()).expanduser().resolve()
    if build_dir == ROOT or ROOT in build_dir.parents:
        print(f"--build-dir must be outside the repository {ROOT}; got {build_dir}", file=sys.stderr)
        return 2
    if args.jobs < 1 or args.configurations < 1:
        print("--jobs and --configurations must be >= 1", file=sys.stderr)
        return 2

    def log(message):
        print(message, file=sys.stderr, flush=True)

    results = {}
    for key in [key for key in args.robots if key in ROBOTS]:
        folder, loader = ROBOTS[key]
        folder = at_data_root(folder, args.data_root)
        loader = loader_at(loader, folder)
        if not folder.exists():
            log(f"{key}: data absent in {folder}; skipped")
            results[key] = {"skipped": True, "reason": f"data absent in {folder}"}
            continue
        published, extra = None, {}
        if key == "panda":  # built before the timed identification, so that it does not share the cores
            try:
                build = build_published_model(build_dir, args.jobs, log, at_data_root(GAZ_MODEL, args.data_root))
                published = PublishedModel(build["library"])
                extra = {"published_build_seconds": build["seconds"], "published_build_cached": build["cached"],
                         "published_original_build_seconds": build["build_seconds"],
                         "published_compile_seconds": build["compile_seconds"], "published_error": None}  # fmt: skip
                log(f"published model: {'cached' if build['cached'] else 'built'} in {build['seconds']:.1f} s "
                    f"({build['library']})")  # fmt: skip
            except BuildError as exc:
                log(f"published model unavailable: {exc}")
                extra = {"rmse_published": None, "r2_published": None, "published_error": str(exc)}
        with blas_thread_limit():
            results[key] = {**evaluate_robot(key, loader, published, args), **extra}
    kinova = evaluate_kinova(log, at_data_root(KINOVA, args.data_root)) if "kinova" in args.robots else None
    if all(r.get("skipped") for r in results.values()) and (kinova is None or kinova["skipped"]):
        log("no dataset found under " + str(at_data_root(TX40.parent, args.data_root)))
        return 2
    missed = missed_targets(results) + kinova_missed(kinova)
    motor_side = None
    if not results.get("tx40", {"skipped": True}).get("skipped"):
        log("tx40: identifying the shipped motor-side files through examples/staubli_tx40.toml ...")
        tx40 = at_data_root(TX40, args.data_root)
        motor_side = compare_routes(tx40, loader_at(load_tx40, tx40), split, OPTIONS["tx40"])
        if not motor_side["equal"]:
            worst = motor_side["max_relative_difference"]
            missed.append(f"tx40 tx40_motor_side_equal: relative difference {worst:.3g}")
    looped = [key for key in args.robots if key in LOOP_ROBOTS]
    loops = {} if args.no_loop or not looped else run_loops(looped, log, args.data_root)
    if loops and not loops["loop_never_worse"]:
        missed += [f"{key} loop_never_worse: {r['rmse_end']} > {r['rmse_identify']} + {r['margin']}"
                   for key, r in loops["loop"].items() if not r.get("skipped") and not r["never_worse"]]  # fmt: skip
    with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):  # stdout is pure JSON with --json
        for key, r in results.items():
            print_robot(key, r)
        if motor_side is not None:
            print(f"\ntx40 read as shipped (motor side, coupled wrist, 5 kHz without time) vs hand-converted: largest "
                  f"relative parameter difference {motor_side['max_relative_difference']:.3g}")  # fmt: skip
        print_kinova(kinova)
        if loops:
            print_loops(loops["loop"])
        print("\ntargets:")
        for name, text in TARGETS.items():
            failed = [m for m in missed if m.split(" ", 2)[1].rstrip(":") == name]
            print(f"  [{'MISSED' if failed else 'met'}] {text}" + "".join(f"\n      {m}" for m in failed))
        print("all met" if not missed else f"NOT met: {len(missed)} target check(s) missed")
    if args.json:
        panda = results.get("panda", {})
        beat = None if panda.get("rmse_published") is None else all(
            ours < theirs for ours, theirs in zip(panda["rmse"], panda["rmse_published"]))  # fmt: skip
        payload = {"robots": results, "targets": TARGETS, "targets_met": not missed, "targets_missed": missed,
                   "defaults_beat_published_every_joint": beat,
                   "tx40_motor_side_equal": None if motor_side is None else motor_side["equal"],
                   "tx40_motor_side": motor_side, "kinova_models": kinova,
                   **loops}  # fmt: skip
        print(json.dumps(payload, default=float))
    return 0 if not missed else 1


if __name__ == "__main__":
    sys.exit(main())
