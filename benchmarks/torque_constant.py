"""A 7-joint cobot on motor currents whose robot file states a torque constant off: found from a known payload?

The arm (a DH table, links, rotors, LuGre drives) records motor currents at 1 kHz; its user's robot file states
rough links, the gear ratios and ``[transmission] motor_kt`` times ``kt_error`` per joint. ``run1`` carries nothing,
``run2`` a known 3 kg payload (sidecar), ``val1`` nothing. Cases: ``kt_off`` (joint 2's ``motor_kt`` 15 % high,
joint 4's 10 % low) and ``kt_right``. For each, the default commands

    psdm identify cobot7.toml --data run1.csv run2.csv --validate val1.csv --columns ... --out model.json
    psdm diagnose cobot7.toml --train run2.csv --validate val1.csv --columns ...        (unless --quick)

and the table gives each joint's torque scale found (``identification.torque_scale``) against the truth (``z``: its
error in standard deviations), the joints named off, and the per-joint validation RMSE of identify's model (in the
true arm's torque: the currents times the right constants). ``same_as_right_file``: the largest ratio of the
``kt_off`` RMSE over the ``kt_right`` one (1: the error left no trace in the model).

    python benchmarks/torque_constant.py [--seed 0] [--quick] [--json]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from identification.virtual.current_arm import CurrentArm, CurrentRun, write_current_recordings
from psdm_casadi.cli import main as cli
from psdm_casadi.description import DriveParameters, LinkInertia
from psdm_casadi.robot import from_dh

try:
    from bench_support import print_json, print_table
except ImportError:  # run as benchmarks.torque_constant
    from benchmarks.bench_support import print_json, print_table

PI = math.pi
ROWS = [(0, -PI / 2, 0.31, 0), (0, PI / 2, 0, 0), (0.05, PI / 2, 0.36, 0), (-0.05, -PI / 2, 0, 0),
        (0, PI / 2, 0.33, 0), (0.07, -PI / 2, 0, 0), (0, 0, 0.12, 0)]  # fmt: skip
TRUE_MASS = [4.6, 4.1, 3.2, 2.7, 1.8, 1.3, 0.55]
TRUE_COM = [[0, -0.03, 0.02], [0, 0.02, 0.07], [0.01, 0.03, -0.04], [-0.02, -0.05, 0.0], [0, 0.03, -0.02],
            [0.02, 0, 0.01], [0, 0, -0.02]]  # fmt: skip
USER_MASS = [4.0, 4.5, 2.8, 3.0, 1.6, 1.5, 0.5]
GEAR = [101, 101, 101, 101, 81, 81, 51]
MOTOR_KT = [0.12, 0.12, 0.095, 0.095, 0.07, 0.07, 0.05]
ROTOR = [0.6, 0.6, 0.35, 0.35, 0.12, 0.12, 0.04]
QD_MAX = [2.2, 2.2, 2.6, 2.6, 3.1, 3.1, 3.1]
TAU_MAX = [140, 140, 80, 80, 30, 30, 12]
FC = [3.0, 2.8, 2.0, 1.9, 0.9, 0.8, 0.4]
FV = [4.0, 3.5, 2.5, 2.2, 0.9, 0.8, 0.4]
PAYLOAD = {"mass": 3.0, "com": [0.0, 0.01, 0.07]}
CURRENT_NOISE = 0.03  # [A] at the motor
COLUMNS = "t=timestamp,q=q_actual_,i=i_motor_"
CASES = {"kt_off": (1.0, 1.15, 1.0, 0.9, 1.0, 1.0, 1.0), "kt_right": (1.0,) * 7}


def _truth():
    shape = np.diag([0.012, 0.011, 0.006])
    links = tuple(LinkInertia(mass=m, com=np.array(c, float), inertia=shape * m * (1 + 0.2 * (i % 3)))
                  for i, (m, c) in enumerate(zip(TRUE_MASS, TRUE_COM)))  # fmt: skip
    limits = [dict(q_min=-2.8, q_max=2.8, qd_max=QD_MAX[i], qdd_max=10.0, tau_max=TAU_MAX[i]) for i in range(7)]
    drives = tuple(DriveParameters(kt=1.0, fc=f, fs=1.25 * f, vs=0.04, fv=v, sigma0=1e4, sigma1=30.0)
                   for f, v in zip(FC, FV))  # fmt: skip
    robot = from_dh(ROWS, gravity=(0, 0, -9.81), name="cobot7 truth", drive_inertia=(True,) * 7, links=links,
                    rotor_inertia=np.array(ROTOR), limits=limits)  # fmt: skip
    return replace(robot, drives=drives), limits


def cobot7() -> CurrentArm:
    """The true arm and what its user's file states (``kt_error`` aside)."""
    truth, limits = _truth()
    names = ("base_yaw", "shoulder", "upper_roll", "elbow", "fore_roll", "wrist_pitch", "flange_roll")
    return CurrentArm(truth=truth, rows=tuple(ROWS), limits=tuple(limits), joint_names=names,
                      file_mass=tuple(USER_MASS), gear=tuple(GEAR), motor_kt=tuple(MOTOR_KT), name="Acme Cobot 7",
                      current_noise=CURRENT_NOISE)  # fmt: skip


def write_cobot(folder: Path, kt_error, seed: int) -> dict:
    """The robot file and recordings of one case; the same seed gives the same motions for every ``kt_error``."""
    folder.mkdir(parents=True, exist_ok=True)
    arm = cobot7()
    (folder / "cobot7.toml").write_text(arm.robot_file(kt_error))
    runs = (CurrentRun("run1", 14.0), CurrentRun("run2", 14.0, PAYLOAD), CurrentRun("val1", 9.0))
    write_current_recordings(folder, arm, runs, np.random.default_rng(seed), q_prefix="q_actual_", i_prefix="i_motor_")
    return {"robot": folder / "cobot7.toml", "folder": folder}


def _run(args) -> tuple:
    """(exit code, JSON printed) of one command, its progress lines swallowed."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli([*args, "--json"])
    return code, json.loads(out.getvalue()) if code == 0 else {"error": err.getvalue()[-400:]}


def run_case(name: str, folder: Path, seed: int, quick: bool) -> dict:
    kt_error = np.array(CASES[name])
    files = write_cobot(folder / name, kt_error, seed)
    f = files["folder"]
    code, identified = _run(["identify", str(files["robot"]), "--data", str(f / "run1.csv"), str(f / "run2.csv"),
                             "--validate", str(f / "val1.csv"), "--columns", COLUMNS,
                             "--out", str(f / "model.json")])  # fmt: skip
    block = identified.get("torque_scale") or {}
    scale = np.array(block.get("scale", [np.nan] * 7), dtype=float)
    std = np.array([np.inf if s is None else s for s in block.get("std", [None] * 7)], dtype=float)
    row = {"case": name, "seed": seed, "identify_exit": code, "kt_error": kt_error.tolist(),
           "scale": scale.tolist(), "std": [float(s) if np.isfinite(s) else None for s in std],
           "z": [float(v) if np.isfinite(v) else None for v in (scale - kt_error) / std],
           "off": [j + 1 for j, o in enumerate(block.get("off", [])) if o],
           "undetermined": [j + 1 for j, d in enumerate(block.get("determined", [])) if not d],
           "true_off": [j + 1 for j, e in enumerate(kt_error) if abs(e - 1.0) > 1e-9],
           "rmse": identified["validation"][0]["rmse"] if code == 0 else None}  # fmt: skip
    row["found_right"] = row["off"] == row["true_off"]
    if not quick:
        code, diagnosed = _run(["diagnose", str(files["robot"]), "--train", str(f / "run2.csv"), "--validate",
                                str(f / "val1.csv"), "--columns", COLUMNS])  # fmt: skip
        row["diagnose_exit"] = code
        row["diagnose_findings"] = [f"{x['effect']}{x['joints']}" for x in diagnosed.get("findings", [])]
        row["diagnose_rmse_after"] = diagnosed.get("rmse_after")
        row["diagnose_names_kt"] = "motor_kt[" in diagnosed.get("nominal_model", "")
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="identify only (no diagnose)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        rows = [run_case(name, Path(tmp), args.seed, args.quick) for name in CASES]
    off, right = rows
    ratio = None
    if off["rmse"] and right["rmse"]:
        ratio = float(np.max(np.array(off["rmse"]) / np.array(right["rmse"])))
    summary = {"found_right_every_case": all(r["found_right"] for r in rows), "same_as_right_file": ratio}
    if args.json:
        print_json({"rows": rows, **summary})
        return 0
    table = [{"case": r["case"], "off (truth)": f"{r['off']} ({r['true_off']})",
              "scale +/- std (z)": ", ".join(f"{s:.3f}+/-{d:.3f} ({z:+.1f})" if d else f"{s:.3f} (undetermined)"
                                             for s, d, z in zip(r["scale"], r["std"], r["z"])),
              "validation RMSE [N m]": " ".join(f"{v:.3g}" for v in r["rmse"] or [])} for r in rows]  # fmt: skip
    print_table(table, list(table[0]))
    if not args.quick:
        for r in rows:
            after = " ".join(f"{v:.3g}" for v in r["diagnose_rmse_after"] or [])
            print(f"{r['case']}: diagnose ROBOT names the constants: {r['diagnose_names_kt']}; findings "
                  f"{r['diagnose_findings']}; RMSE after {after}")  # fmt: skip
    print(f"found on the right joints in every case: {summary['found_right_every_case']}; kt_off RMSE / kt_right RMSE "
          f"at most {ratio}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
