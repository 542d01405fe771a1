"""The TX40 read as shipped (motor side, coupled wrist, no time column) against today's hand-converted route.

``examples/staubli_tx40.toml`` states the transmission and the recording layout; ``load_robot_recording``
reads the dataset folder with it. ``real_data_diagnosis.load_tx40`` is the hand conversion of the
dataset's README. Both are identified on their first 70 % with the options of ``real_identification``;
the models must be the same (``tx40_motor_side_equal``: every parameter vector within 1e-9 relative).

    python benchmarks/tx40_motor_side.py [--json]        (also run by real_identification.py)
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import tomllib
from bench_support import ROOT, add_data_root_argument, at_data_root, loader_at, show_progress

from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.robot_recordings import load_robot_recording
from psdm_casadi import derive_psdm
from psdm_casadi.robot_file import robot_from_mapping

ROBOT_FILE = ROOT / "examples" / "staubli_tx40.toml"
URDF_NAME = "tx40_mdh_modified.urdf"
TOLERANCE = 1e-9  # relative, per parameter vector (inf-norm of the difference over the inf-norm of the values)


def shipped_robot(folder: Path):
    """The example robot file with its URDF taken from ``folder`` (wherever the datasets are)."""
    data = tomllib.loads(ROBOT_FILE.read_text())
    data["urdf"]["path"] = str(Path(folder) / URDF_NAME)
    return robot_from_mapping(data, source=ROBOT_FILE)


def compare_routes(folder: Path, hand_loader, split, options: TrajectoryOptions) -> dict:
    """Identify the hand-converted and the shipped recording; the largest relative difference of the models.

    ``hand_loader()`` gives (robot, joint-side recording) of the hand route; ``split`` cuts a recording into
    training and validation parts.
    """
    start = time.perf_counter()
    hand_robot, hand = hand_loader()
    robot = shipped_robot(folder)
    shipped = load_robot_recording(folder, robot)
    model = derive_psdm(hand_robot)
    fits = [
        identify_trajectories(r, model, [split(rec)[0]], options) for r, rec in ((hand_robot, hand), (robot, shipped))
    ]
    differences = {}
    for name in ("theta", "theta_ols", "drive", "standard"):
        ours, theirs = (np.asarray(getattr(fit, name), dtype=float) for fit in fits[::-1])
        differences[name] = float(np.abs(ours - theirs).max() / max(np.abs(theirs).max(), 1e-300))
    signals = {k: float(np.abs(getattr(shipped, k) - getattr(hand, k)).max()) for k in ("t", "q", "tau")}
    worst = max(differences.values())
    return {"equal": bool(worst <= TOLERANCE), "max_relative_difference": worst, "relative_difference": differences,
            "signal_max_abs_difference": signals, "tolerance": TOLERANCE,
            "robot_file": str(ROBOT_FILE.relative_to(ROOT)), "seconds": time.perf_counter() - start}  # fmt: skip


def main(argv=None) -> int:
    from real_data_diagnosis import TX40, load_tx40, split
    from real_identification import OPTIONS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    add_data_root_argument(parser)
    args = parser.parse_args(argv)
    show_progress()
    folder = at_data_root(TX40, args.data_root)
    if not folder.exists():
        print(f"TX40 data absent in {folder}", file=sys.stderr)
        return 2
    result = compare_routes(folder, loader_at(load_tx40, folder), split, OPTIONS["tx40"])
    if args.json:
        print(json.dumps({"tx40_motor_side_equal": result["equal"], "tx40_motor_side": result}))
    else:
        print(f"TX40 as shipped vs hand-converted: largest relative difference {result['max_relative_difference']:.3g} "
              f"({'equal' if result['equal'] else 'NOT equal'} within {TOLERANCE:g}); per vector "
              + ", ".join(f"{k} {v:.2g}" for k, v in result["relative_difference"].items()))  # fmt: skip
    return 0 if result["equal"] else 1


if __name__ == "__main__":
    sys.exit(main())
