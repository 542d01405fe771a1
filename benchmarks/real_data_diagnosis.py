"""Missing-physics diagnosis on real recordings: Staubli TX40 (FIGAROH) and Franka Panda (Gaz et al. 2019).

Reads the third-party data from ../shared/datasets (``--data-root PATH``: PATH/datasets; never copied),
converts it to joint-side recordings, splits each into a training part (first 70 % of the motion) and two
validation parts (the halves of the rest), runs ``diagnose`` with the robot's URDF as the prior (a finding is kept
only if it holds on both validation parts), prints the findings and writes report.md, report.json, plots and the
augmented model per robot into OUT_DIR/<robot>/. Robots whose data are absent are skipped.
``unstable_findings_reported_as_missing_physics`` counts reported findings whose torque, taken out of the final
model, does not lower their joints' error on one of the two validation parts (target 0); the candidates found
unstable are listed per robot (``unstable``).

Then, unless ``--no-loop``, identify -> diagnose --apply with default options on both robots (``never_worse_loop``):
key ``loop_never_worse``.

    python benchmarks/real_data_diagnosis.py OUT_DIR [--json] [--overwrite] [--data-root PATH] [--no-loop]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from pathlib import Path

import numpy as np
from bench_support import DEFAULT_DATA_ROOT, add_data_root_argument, at_data_root, load_panda, show_progress

from identification.data.recording import Recording
from identification.diagnosis import DiagnosisOptions, diagnose
from psdm_casadi.robot import load_robot

DATASETS = DEFAULT_DATA_ROOT / "datasets"
TX40 = DATASETS / "staubli_tx40_figaroh"
PANDA = DATASETS / "panda_gaz2019"
TRAIN_FRACTION = 0.7
REST_RAD = 1e-3  # a joint within this of its final angle is at rest [rad]


def load_tx40(folder: Path = TX40):
    """TX40 joint-side recording (README: q = N_q^-1 theta_m, q2 -= pi/2, q3 += pi/2, tau = N_tau tau_m)."""
    theta_m = np.loadtxt(folder / "pos_read_data.csv", delimiter=",", skiprows=1)
    tau_m = np.loadtxt(folder / "curr_data.csv", delimiter=",", skiprows=1)
    ratios = np.array([32.0, 32.0, 45.0, -48.0, 45.0, 32.0])
    n_q, n_tau = np.diag(ratios), np.diag(ratios)
    n_q[5, 4] = 32.0
    n_tau[4, 5] = 32.0
    q = np.linalg.solve(n_q, theta_m.T).T
    q[:, 1] -= np.pi / 2
    q[:, 2] += np.pi / 2
    tau = tau_m @ n_tau.T
    t = np.arange(q.shape[0]) * 2e-4
    return load_robot(folder / "tx40_mdh_modified.urdf"), Recording(t=t, q=q, tau=tau, name="staubli_tx40_figaroh")


def load_panda_real(folder: Path = PANDA):
    t = np.loadtxt(folder / "exciting_traj_time.txt")
    q = np.loadtxt(folder / "exciting_traj_positions.txt").reshape(-1, 7)
    tau = np.loadtxt(folder / "exciting_traj_torques.txt").reshape(-1, 7)
    keep = np.concatenate([[True], np.diff(t) > 0])
    return load_panda(), Recording(t=t[keep], q=q[keep], tau=tau[keep], name="panda_gaz2019")


def split(rec):
    """Training part (first ``TRAIN_FRACTION``) and validation part (the rest), as the other real-data benchmarks
    split."""
    cut = int(TRAIN_FRACTION * rec.n_samples)
    return rec.slice(0, cut), rec.slice(cut, None)


def split_two(rec):
    """Training part (first ``TRAIN_FRACTION`` of the motion) and the two halves of the rest (two validation
    recordings); a standstill at the end (the TX40's last 15 %: every joint within ``REST_RAD`` of its final pose) is
    left out, since a validation part must move every joint."""
    moved = np.flatnonzero(np.any(np.abs(rec.q - rec.q[-1]) > REST_RAD, axis=1))
    end = int(moved[-1]) + 2 if moved.size else rec.n_samples
    cut = int(TRAIN_FRACTION * end)
    middle = (cut + end) // 2
    return rec.slice(0, cut), [rec.slice(cut, middle), rec.slice(middle, end)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="output folder (one sub-folder per robot)")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--overwrite", action="store_true")
    parser.add_argument("--cutoff", type=float, default=10.0, help="low-pass cut-off [Hz] (default 10)")
    add_data_root_argument(parser)
    parser.add_argument("--no-loop", action="store_true", help="skip identify -> diagnose --apply (loop_never_worse)")
    args = parser.parse_args(argv)
    show_progress()
    results = {}
    for name, folder, loader in (("staubli_tx40", TX40, load_tx40), ("panda_gaz2019", PANDA, load_panda_real)):
        folder = at_data_root(folder, args.data_root)
        if not folder.exists():
            print(f"{name}: data absent in {folder}; skipped", file=sys.stderr)
            results[name] = {"skipped": True}
            continue
        start = time.perf_counter()
        robot, rec = loader(folder)
        train, validation = split_two(rec)
        report = diagnose(robot, train, validation, DiagnosisOptions(cutoff_hz=args.cutoff, max_effects=6))
        paths = report.save(Path(args.out) / name, overwrite=args.overwrite)
        results[name] = {**report.to_dict(), "seconds": time.perf_counter() - start, "report": str(paths["markdown"])}
        results[name]["findings_not_holding"] = list(report.findings_not_holding)
        results[name].pop("residual_analysis")
        out = sys.stderr if args.json else sys.stdout  # keep stdout pure JSON with --json
        print(f"\n== {name}: {report.summary()}", file=out)
        for f in report.findings:
            print("  - " + f.sentence(), file=out)
        print("  validation RMSE before: " + " ".join(f"{x:.3g}" for x in report.rmse_before), file=out)
        print("  validation RMSE after:  " + " ".join(f"{x:.3g}" for x in report.rmse_after), file=out)
        print("  R^2 before: " + " ".join(f"{x:.3f}" for x in report.r2_before), file=out)
        print("  R^2 after:  " + " ".join(f"{x:.3f}" for x in report.r2_after), file=out)
        for u in report.unstable:
            print("  unstable (not kept): " + u.sentence(), file=out)
        for label, reason in report.rejected:
            print(f"  rejected {label}: {reason}", file=out)
    ran = [r for r in results.values() if not r.get("skipped")]
    results["unstable_findings_reported_as_missing_physics"] = sum(len(r["findings_not_holding"]) for r in ran)
    results["unstable_findings_listed"] = sum(len(r["unstable"]) for r in ran)
    if not args.no_loop:  # identify -> diagnose --apply with default options (never_worse_loop)
        from never_worse_loop import print_loops, run_loops

        loops = run_loops(("tx40", "panda"), lambda text: print(text, file=sys.stderr, flush=True), args.data_root)
        results.update(loops)
        with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):
            print_loops(loops["loop"])
            print(f"loop_never_worse: {loops['loop_never_worse']}")
    if args.json:
        print(json.dumps(results, default=float))
    else:
        print(
            "\nunstable findings reported as missing physics: "
            f"{results['unstable_findings_reported_as_missing_physics']}; listed as unstable: "
            f"{results['unstable_findings_listed']}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
