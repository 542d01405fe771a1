"""Wall and CPU time of identification on default settings, by stage, before and after: and the same answer.

Cases (``--robots``): the virtual Denso (``psdm simulate`` sine experiments, 20 s to train and 10 s to validate,
currents with the robot file's torque constants), the Franka Panda's shared recording (Gaz et al. 2019, first 70 %
trains, the rest validates, as ``real_identification``; skipped when ``../shared`` is absent) and the 12-joint
example arm (``examples/serial_arm_12.toml``, the recursive form; sums of sines with Pinocchio's torques plus
Coulomb and viscous friction, 40 s and 15 s). Each runs what ``psdm identify`` runs, timed by stage:

- ``derive``: ``derive_psdm``;
- ``prepare``: read (the Denso's CSV files) and ``prepare_recordings`` of the training recording;
- ``regressor``: the base regressor of the prepared training samples (``stribeck.base_regressors``);
- ``column_choice``: ``choose_columns`` (friction shape, offsets and drive inertias per joint, block
  cross-validation);
- ``fit``: ``identify_trajectories`` with the chosen columns (Stribeck velocities, weighted least squares, the
  consistent fit by Ipopt);
- ``column_check``: each column the held-out data alone decided checked on the written model (``column_check``; no
  validation recording here, so by block cross-validation of the training recording: 2 x 4 fold fits per column);
  a revision without it: nothing;
- ``validation``: the validation recording prepared and predicted (``predict_torque``), per-joint RMSE.

With ``--ref REV`` the same script runs on ``git archive REV`` in a child process, so both columns are measured
side by side on the same machine; the table then states the speed-up and whether the answer is the same: chosen
columns equal, the largest relative difference of the base, drive and standard parameters, and of the validation
RMSE (targets: equal, 1e-9, 1e-9; exit 1 otherwise). The answer is only comparable with a revision whose other code
is the same: the speed work's own reference is its start, 856267a, with the later commits of others applied, i.e.
``main`` with the speed commits reverted (``git revert --no-commit`` of them in a scratch worktree, committed there).
Default ``--ref none``: this tree only.
One BLAS thread, as ``psdm`` commands run (``cli.blas_threads``). CPU seconds are this process's: on a loaded
machine the wall time also counts the others' work.

Usage::

    python benchmarks/identify_speed.py [--robots denso panda arm12] [--ref REV] [--json]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_support import DEFAULT_DATA_ROOT, DENSO_FILE, ROOT, add_data_root_argument, at_data_root, print_table

#: The revision this work started from (before the fast regressor, its cache and the per-joint Stribeck rows).
START = "856267a"
STAGES = ("derive", "prepare", "regressor", "column_choice", "fit", "column_check", "validation")
ROBOTS = ("denso", "panda", "arm12")
TARGET_RELATIVE = 1e-9


@contextlib.contextmanager
def timed(stages: dict, name: str):
    wall, cpu = time.perf_counter(), time.process_time()
    yield
    stages[name] = {"wall": time.perf_counter() - wall, "cpu": time.process_time() - cpu}


def denso_case(folder: Path):
    """(robot, training and validation recordings) of the virtual Denso, simulated into ``folder``."""
    from identification.data.robot_recordings import load_robot_recording
    from psdm_casadi.cli import main
    from psdm_casadi.robot_file import load_robot

    robot = load_robot(DENSO_FILE)
    paths = []
    for name, duration, seed in (("train", 20, 1), ("validate", 10, 2)):
        out = folder / name
        args = ["simulate", "denso_vs6556g", "--experiment", "sine", "--duration", str(duration), "--seed", str(seed)]
        with open(os.devnull, "w") as quiet:
            stdout, sys.stdout = sys.stdout, quiet
            try:
                main([*args, "--out", str(out), "--json"])
            finally:
                sys.stdout = stdout
        paths.append(out / "sine.csv")
    return robot, paths, lambda path: load_robot_recording(path, robot)


def panda_case(data_root: Path):
    from real_data_diagnosis import PANDA, load_panda_real, split

    folder = at_data_root(PANDA, data_root)
    if not folder.exists():
        return None
    robot, recording = load_panda_real(folder)
    train, validation = split(recording)
    return robot, [train, validation], lambda recording: recording


#: The friction of every joint of the 12-joint arm's recordings: Coulomb [N m], viscous [N m s/rad].
FC, FV = 2.0, 3.0


def mid_range_sines(robot, duration: float, seed: int, rate: float = 200.0):
    """A recording of ``robot``: four sines per joint about mid-range (within half its range, speed and acceleration
    limits), its torque Pinocchio's ``rnea`` plus ``FC tanh(qd / 0.01) + FV qd`` (exact, no noise)."""
    from identification.data.recording import Recording
    from psdm_casadi.oracle import PinocchioOracle

    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    mid, half = 0.5 * (robot.q_min + robot.q_max), 0.5 * (robot.q_max - robot.q_min)
    q, qd, qdd = (np.empty((t.size, robot.n_dof)) for _ in range(3))
    for j in range(robot.n_dof):
        w, phase = rng.uniform(0.2, 1.0, 4) * 2 * np.pi, rng.uniform(0, 2 * np.pi, 4)
        amp = min(0.5 * half[j], 0.5 * robot.qd_max[j] / w.max(), 0.5 * robot.qdd_max[j] / w.max() ** 2) / 2
        angle = np.outer(t, w) + phase
        q[:, j] = mid[j] + amp * np.sin(angle).sum(1)
        qd[:, j] = amp * (w * np.cos(angle)).sum(1)
        qdd[:, j] = -amp * (w**2 * np.sin(angle)).sum(1)
    tau = PinocchioOracle(robot).rnea(q, qd, qdd) + FC * np.tanh(qd / 0.01) + FV * qd
    return Recording(t=t, q=q, tau=tau, name=f"{robot.name}_{seed}")


def arm12_case():
    """The 12-joint example arm: ``mid_range_sines``, 40 s to train and 15 s to validate."""
    from psdm_casadi.robot_file import load_robot

    robot = load_robot(ROOT / "examples" / "serial_arm_12.toml")
    recordings = [mid_range_sines(robot, duration, seed) for duration, seed in ((40.0, 0), (15.0, 1))]
    return robot, recordings, lambda recording: recording


def run_case(robot, sources, read) -> dict:
    """Every stage of identify on default settings; times and the answer."""
    from identification.calibration.column_choice import choose_columns
    from identification.calibration.stribeck import base_regressors
    from identification.calibration.trajectory_data import prepare_recording, prepare_recordings
    from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories, predict_torque
    from identification.metrics import rmse
    from psdm_casadi.derive import derive_psdm

    stages = {}
    with timed(stages, "derive"):
        model = derive_psdm(robot)
    with timed(stages, "prepare"):
        train, validation = (read(source) for source in sources)
        kt = None if train.tau is not None else np.array([d.kt for d in robot.drives], dtype=float)
        prepared = prepare_recordings(robot, [train], kt)[2]
    with timed(stages, "regressor"):
        base_regressors(model, prepared)
    with timed(stages, "column_choice"):
        choice = choose_columns(robot, model, [train])
    with timed(stages, "fit"):
        fit = identify_trajectories(robot, model, [train], choice.options(TrajectoryOptions()))
    with timed(stages, "column_check"):
        choice, fit = checked(robot, model, train, choice, fit)
    with timed(stages, "validation"):
        ready = prepare_recording(validation, kt, fit.cutoff_hz[0])[0]
        error = rmse(ready.tau, predict_torque(model, fit, ready.q, ready.qd, ready.qdd))
    columns = choice.to_dict()
    return {
        "stages": stages,
        "total": {key: sum(s[key] for s in stages.values()) for key in ("wall", "cpu")},
        "columns": {k: columns[k] for k in ("friction_shapes", "offset_joints", "inertia_joints")},
        "parameters": np.concatenate([fit.theta, fit.drive, np.ravel(fit.standard)]).tolist(),
        "rmse": np.asarray(error, dtype=float).tolist(),
    }


def checked(robot, model, train, choice, fit) -> tuple:
    """(choice, fit) after identify's check of the columns the held-out data alone decided, as ``identify_route``
    runs it without validation recordings (a revision without ``column_check``: as chosen)."""
    from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories

    try:
        from identification.calibration.column_check import check_departures, written_model_judge
    except ImportError:
        return choice, fit
    if not choice.departures:
        return choice, fit
    options, cutoffs = TrajectoryOptions(), [c for c in fit.cutoff_hz if c]
    judge = written_model_judge((robot, model, [train], options, None), [], min(cutoffs) if cutoffs else None)
    if isinstance(judge, str):
        return choice, fit
    return check_departures(choice, fit, lambda c: identify_trajectories(robot, model, [train], c.options(options)),
                            judge)  # fmt: skip


def command_scope():
    """What ``psdm identify`` runs inside: the regressor memory of one command (``state_cache.remembering``; a
    revision without it: nothing)."""
    try:
        from psdm_casadi.state_cache import remembering
    except ImportError:
        return contextlib.nullcontext()
    return remembering()


def measure(robots, data_root: Path) -> dict:
    from psdm_casadi.cli.blas_threads import blas_thread_limit

    out = {}
    with tempfile.TemporaryDirectory() as tmp, blas_thread_limit():
        for name in robots:
            case = {"denso": lambda: denso_case(Path(tmp)), "panda": lambda: panda_case(data_root),
                    "arm12": arm12_case}[name]()  # fmt: skip
            if case is None:
                out[name] = {"skipped": "data absent"}
                continue
            with command_scope():
                out[name] = run_case(*case)
    return out


def measure_ref(ref: str, robots, data_root: Path) -> dict:
    """This script's measurement on ``git archive ref``, in a child process."""
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref], check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        env = {**os.environ, "PYTHONPATH": tmp}
        child = [sys.executable, __file__, "--ref", "none", "--measure-only", "--data-root", str(data_root),
                 "--robots", *robots]  # fmt: skip
        done = subprocess.run(child, cwd=tmp, env=env, check=True, capture_output=True, text=True)
    return json.loads(done.stdout)


def relative(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape:
        return float("inf")
    both = np.isfinite(a) & np.isfinite(b)
    return float(np.max(np.abs(a[both] - b[both]) / np.maximum(np.abs(b[both]), 1e-12), initial=0.0))


def compare(after: dict, before: dict) -> dict:
    """Per robot: speed-up of each stage and of the total (CPU and wall), and whether the answer is the same."""
    out = {}
    for name, now in after.items():
        then = before.get(name, {})
        if "stages" not in now or "stages" not in then:
            continue
        out[name] = {
            "speedup_cpu": then["total"]["cpu"] / max(now["total"]["cpu"], 1e-9),
            "speedup_wall": then["total"]["wall"] / max(now["total"]["wall"], 1e-9),
            "same_columns": now["columns"] == then["columns"],
            "parameters_max_rel_difference": relative(now["parameters"], then["parameters"]),
            "rmse_max_rel_difference": relative(now["rmse"], then["rmse"]),
        }
        out[name]["same_answer"] = bool(out[name]["same_columns"]
                                        and out[name]["parameters_max_rel_difference"] <= TARGET_RELATIVE
                                        and out[name]["rmse_max_rel_difference"] <= TARGET_RELATIVE)  # fmt: skip
    return out


def print_report(result: dict) -> None:
    rows = []
    for name, now in result["after"].items():
        if "stages" not in now:
            print(f"{name}: skipped ({now['skipped']})")
            continue
        then = result.get("before", {}).get(name, {}).get("stages")
        for stage in (*STAGES, "total"):
            cell = now["stages"].get(stage) if stage != "total" else now["total"]
            if cell is None:  # a stage this revision does not run
                continue
            row = {"robot": name, "stage": stage, "after cpu": cell["cpu"], "after wall": cell["wall"]}
            old = None if then is None else then.get(stage) if stage != "total" else result["before"][name]["total"]
            if old is not None:
                row.update({"before cpu": old["cpu"], "before wall": old["wall"], "cpu x": old["cpu"] / cell["cpu"]})
            rows.append(row)
    columns = ["robot", "stage", "before cpu", "after cpu", "cpu x", "before wall", "after wall"]
    print_table(rows, columns if "before" in result else ["robot", "stage", "after cpu", "after wall"])
    for name, same in result.get("same", {}).items():
        print(f"{name}: same columns {same['same_columns']}, parameters max rel. difference "
              f"{same['parameters_max_rel_difference']:.2g}, validation RMSE {same['rmse_max_rel_difference']:.2g}; "
              f"total {same['speedup_cpu']:.2f}x CPU, {same['speedup_wall']:.2f}x wall")  # fmt: skip
    print(f"load average {result['load_average']}; before = {result.get('ref')}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", choices=ROBOTS, default=list(ROBOTS))
    parser.add_argument("--ref", default="none", help=f"revision measured as 'before' (e.g. {START}, where this work "
                        "started); none (default): this tree only")  # fmt: skip
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--measure-only", action="store_true", help=argparse.SUPPRESS)
    add_data_root_argument(parser)
    args = parser.parse_args(argv)
    data_root = Path(args.data_root).resolve() if args.data_root else DEFAULT_DATA_ROOT
    if args.measure_only:
        print(json.dumps(measure(args.robots, data_root)))
        return 0
    result = {"load_average": [round(v, 2) for v in os.getloadavg()], "ref": None}
    if args.ref != "none":
        result.update(ref=args.ref, before=measure_ref(args.ref, args.robots, data_root))
    result["after"] = measure(args.robots, data_root)
    if "before" in result:
        result["same"] = compare(result["after"], result["before"])
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print_report(result)
    return 0 if all(s["same_answer"] for s in result.get("same", {}).values()) else 1


if __name__ == "__main__":
    sys.exit(main())
