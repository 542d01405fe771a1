"""Long recordings (issue 17): wall time and peak memory of ``psdm identify`` and ``psdm diagnose`` on hours at 1 kHz.

For each length (default 1, 10 and 60 minutes) a recording of the virtual Denso VS-6556G at 1 kHz is made
without simulating it: q is a sum of sines per joint within half the position, speed and acceleration
limits (qd and qdd analytic), tau is Pinocchio's inverse dynamics (``PinocchioOracle.rnea``, in chunks)
plus the robot file's steady-state LuGre friction and Gaussian sensor noise; it is written as CSV with
``save_recording`` into a temporary folder, deleted at the end. The validation recording of the diagnosis
is a separate recording (another seed) of ``--validation-minutes`` (default 1 minute), or of
``--validation-fraction`` of the training length.

Each command runs in a fresh process started by a small wrapper process that reports the command's wall
time and its peak resident memory (``getrusage(RUSAGE_CHILDREN).ru_maxrss``; the wrapper is small, so its
image does not inflate the figure), imports, model derivation and CSV reading included. The wrapper caps the
command's address space (``--cap-mb``, default 8 GB) so that a command that does not scale fails (and is
reported as failed) instead of exhausting a shared machine:

- identify: ``psdm identify denso_vs6556g --data rec.csv --out model.json`` (the everyday route,
  ``identification.calibration.trajectory_fit``);
- diagnose: ``psdm diagnose denso_vs6556g --train rec.csv --validate val.csv``.

Targets (exit 1 when one is missed): the time grows about linearly (seconds per minute at the longest
length at most 2x those at the second longest), diagnose of the longest recording in under 2 minutes
(when it is 60 minutes), peak memory under 2 GB for both commands at every length.

    python benchmarks/scale.py [--minutes 1 10 60] [--validation-minutes 1 | --validation-fraction 0.2]
                               [--cap-mb 8192] [--json]
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
from bench_support import ROOT, print_table

from identification.data.io import save_recording
from identification.data.recording import Recording
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import load_robot

ROBOT = "denso_vs6556g"
RATE_HZ = 1000.0
TAU_NOISE = 0.1  # N m, standard deviation of the torque sensor noise
N_SINES = 5
CHUNK = 200_000  # samples per inverse-dynamics call (bounds the generator's temporaries)
MAX_PEAK_MB = 2048.0
MAX_DIAGNOSE_60_S = 120.0
MAX_GROWTH = 2.0  # seconds per minute at the longest length / at the second longest

# the wrapper: runs the command given in argv[2:] with its address space capped at argv[1] MB (0: no cap), prints
# its wall time, peak RSS and exit code as JSON
WRAPPER = """
import json, resource, subprocess, sys, time
cap = int(sys.argv[1]) * 2**20
limit = (lambda: resource.setrlimit(resource.RLIMIT_AS, (cap, cap))) if cap else None
start = time.perf_counter()
done = subprocess.run(sys.argv[2:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, preexec_fn=limit)
seconds = time.perf_counter() - start
peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
print(json.dumps({"seconds": seconds, "peak_mb": peak_mb, "code": done.returncode, "stderr": done.stderr[-2000:]}))
"""
PSDM = "import sys; from psdm_casadi.cli import main; sys.exit(main(sys.argv[1:]))"


def sine_design(robot, rng) -> tuple:
    """Amplitudes, angular frequencies and phases (n_dof, N_SINES) and centres (n_dof,) of the joint motion.

    Frequencies 0.05-0.5 Hz; each joint's sum stays within half its position range about a centre with room
    on both sides, and within half its speed and acceleration limits."""
    span = robot.q_max - robot.q_min
    centre = np.clip(0.0, robot.q_min + 0.25 * span, robot.q_max - 0.25 * span)
    omega = 2.0 * np.pi * rng.uniform(0.05, 0.5, (robot.n_dof, N_SINES))
    phase = rng.uniform(0.0, 2.0 * np.pi, (robot.n_dof, N_SINES))
    weight = rng.uniform(0.5, 1.0, (robot.n_dof, N_SINES))
    room = np.minimum(robot.q_max - centre, centre - robot.q_min)
    scale = 0.5 * np.min(
        [
            room / weight.sum(axis=1),
            robot.qd_max / (weight * omega).sum(axis=1),
            robot.qdd_max / (weight * omega**2).sum(axis=1),
        ],
        axis=0,
    )
    return scale[:, None] * weight, omega, phase, centre


def joint_motion(design, t) -> tuple:
    """q, qd, qdd (n_samples, n_dof) of the sum of sines at times ``t``."""
    amplitude, omega, phase, centre = design
    angle = t[:, None, None] * omega[None] + phase[None]
    sin, cos = np.sin(angle), np.cos(angle)
    q = centre + np.einsum("tjk,jk->tj", sin, amplitude)
    qd = np.einsum("tjk,jk->tj", cos, amplitude * omega)
    qdd = -np.einsum("tjk,jk->tj", sin, amplitude * omega**2)
    return q, qd, qdd


def friction_torque(robot, qd) -> np.ndarray:
    """Steady-state LuGre friction of the robot file's drives (n_samples, n_dof) [N m]."""
    out = np.zeros_like(qd)
    for j, d in enumerate(robot.drives or ()):
        v, s = qd[:, j], np.sign(qd[:, j])
        out[:, j] = (d.fc + (d.fs - d.fc) * np.exp(-((v / d.vs) ** 2))) * s + d.fv * np.abs(v) ** d.dv * s
    return out


def make_recording(robot, minutes: float, seed: int, path: Path) -> float:
    """Write a ``minutes`` long 1 kHz recording (t, q, tau) as CSV; return the seconds it took."""
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    design = sine_design(robot, rng)
    n = int(round(minutes * 60.0 * RATE_HZ))
    t = np.arange(n) / RATE_HZ
    q, tau = np.empty((n, robot.n_dof)), np.empty((n, robot.n_dof))
    oracle = PinocchioOracle(robot)
    for lo in range(0, n, CHUNK):
        sl = slice(lo, min(n, lo + CHUNK))
        q[sl], qd, qdd = joint_motion(design, t[sl])
        tau[sl] = oracle.rnea(q[sl], qd, qdd) + friction_torque(robot, qd)
    tau += rng.normal(0.0, TAU_NOISE, tau.shape)
    save_recording(Recording(t=t, q=q, tau=tau, name=path.stem), path, comment=f"scale benchmark, seed {seed}")
    return time.perf_counter() - start


def measure(args: list, cap_mb: int) -> dict:
    """Wall time [s], peak memory [MB] and success of ``psdm args`` in a fresh process (address space capped)."""
    command = [sys.executable, "-c", PSDM, *args]
    done = subprocess.run(
        [sys.executable, "-c", WRAPPER, str(cap_mb), *command], capture_output=True, text=True, cwd=ROOT
    )
    if done.returncode != 0:
        raise RuntimeError(f"the measuring wrapper failed: {done.stderr[-2000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["ok"] = result["code"] == 0
    if not result["ok"]:
        tail = result["stderr"].strip().splitlines()[-1:] or [""]
        print(f"psdm {args[0]} exited {result['code']}: {tail[0]}", file=sys.stderr)
    return result


def run(minutes: list, validation: tuple, cap_mb: int, verbose: bool) -> dict:
    """Make the recordings of each length, time both commands on them; ``validation`` is ("minutes", m) or
    ("fraction", f) of the training length."""
    robot = load_robot(ROBOT)
    out = {name: {"minutes": [], "seconds": [], "peak_mb": [], "ok": []} for name in ("identify", "diagnose")}
    folder = Path(tempfile.mkdtemp(prefix="psdm_scale_"))
    try:
        for m in minutes:
            train, held_out = folder / f"rec_{m:g}min.csv", folder / f"val_{m:g}min.csv"
            val_minutes = validation[1] if validation[0] == "minutes" else validation[1] * m
            made = make_recording(robot, m, 1, train) + make_recording(robot, val_minutes, 2, held_out)
            if verbose:
                print(f"{m:g} min (+ {val_minutes:g} min validation): written in {made:.1f} s", file=sys.stderr)
            jobs = {
                "identify": ["identify", ROBOT, "--data", str(train), "--out", str(folder / f"model_{m:g}.json")],
                "diagnose": ["diagnose", ROBOT, "--train", str(train), "--validate", str(held_out)],
            }
            for name, job in jobs.items():
                result = measure(job, cap_mb)
                if verbose:
                    print(f"{m:g} min: {name} {result['seconds']:.1f} s, {result['peak_mb']:.0f} MB", file=sys.stderr)
                for key in ("seconds", "peak_mb", "ok"):
                    out[name][key].append(result[key])
                out[name]["minutes"].append(m)
            for path in (train, held_out):
                path.unlink()
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return out


def check_targets(results: dict) -> list:
    """(target, measured, passed) for every target that the measured lengths allow to check."""
    checks = []
    for name, r in results.items():
        minutes, seconds = r["minutes"], r["seconds"]
        failed = [f"{m:g}" for m, ok in zip(minutes, r["ok"]) if not ok]
        checks.append(
            (f"{name}: every run succeeds", "failed at " + ", ".join(failed) + " min" if failed else "all", not failed)
        )
        if len(minutes) >= 2:  # a failed run's time (until it failed) does not count
            ratio = (seconds[-1] / minutes[-1]) / (seconds[-2] / minutes[-2])
            label = f"{name}: s/min at {minutes[-1]:g} min <= {MAX_GROWTH:g}x s/min at {minutes[-2]:g} min"
            ok = ratio <= MAX_GROWTH and r["ok"][-1] and r["ok"][-2]
            checks.append((label, f"{ratio:.2f}x" + ("" if r["ok"][-1] and r["ok"][-2] else " (failed run)"), ok))
        peak = max(r["peak_mb"])
        checks.append((f"{name}: peak memory < {MAX_PEAK_MB:.0f} MB", f"{peak:.0f} MB", peak < MAX_PEAK_MB))
    d = results["diagnose"]
    if 60 in d["minutes"]:
        k = d["minutes"].index(60)
        s, ok = d["seconds"][k], d["ok"][k]
        value = f"{s:.1f} s" + ("" if ok else " (failed)")
        checks.append((f"diagnose: 60 min in < {MAX_DIAGNOSE_60_S:.0f} s", value, ok and s < MAX_DIAGNOSE_60_S))
    return checks


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, nargs="+", default=[1, 10, 60])
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--validation-minutes", type=float, default=1.0, help="length of the validation recording")
    group.add_argument("--validation-fraction", type=float, default=None, help="validation length / training length")
    parser.add_argument("--cap-mb", type=int, default=8192, help="address-space cap of each command [MB] (0: none)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    minutes = sorted(int(m) if float(m).is_integer() else m for m in args.minutes)
    validation = ("minutes", args.validation_minutes)
    if args.validation_fraction is not None:
        validation = ("fraction", args.validation_fraction)
    results = run(minutes, validation, args.cap_mb, verbose=not args.json)
    checks = check_targets(results)
    if args.json:
        print(json.dumps(results))
    else:
        rows = []
        for name, r in results.items():
            for m, s, p, ok in zip(r["minutes"], r["seconds"], r["peak_mb"], r["ok"]):
                rows.append({"command": name, "minutes": m, "samples": int(m * 60 * RATE_HZ), "seconds": s,
                             "s_per_min": s / m, "peak_mb": p, "ok": "yes" if ok else "FAILED"})  # fmt: skip
        print_table(rows, ["command", "minutes", "samples", "seconds", "s_per_min", "peak_mb", "ok"])
        print()
    for label, value, ok in checks:  # on stderr with --json, so stdout holds the one JSON object
        print(f"{'ok  ' if ok else 'MISS'} {label}: {value}", file=sys.stderr if args.json else sys.stdout)
    return 0 if all(ok for _, _, ok in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
