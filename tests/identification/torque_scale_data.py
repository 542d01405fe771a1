"""A small virtual cobot logging motor currents, a known payload on one recording, torque constants off on some joints.

The user's robot file states ``[transmission] gear_ratios`` and ``motor_kt`` (the datasheet's, times ``kt_error``
per joint) with rough links; the recordings are the true arm's motor currents, so a joint whose ``kt_error`` is
1.15 records 15 % too much torque. ``run1`` carries nothing, ``run2`` a known 3 kg payload (sidecar), ``val1``
nothing. The files come from ``identification.virtual.current_arm`` as ``benchmarks/torque_constant.py``'s 7-joint
cobot's do; four joints keep it fast.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from identification.virtual.current_arm import CurrentArm, CurrentRun, write_current_recordings
from psdm_casadi.description import DriveParameters, LinkInertia
from psdm_casadi.robot import from_dh

ROWS = [(0.0, -math.pi / 2, 0.31, 0.0), (0.35, 0.0, 0.0, 0.0), (0.30, 0.0, 0.0, 0.0), (0.0, math.pi / 2, 0.1, 0.0)]
TRUE_MASS = [4.6, 4.1, 2.7, 1.3]
TRUE_COM = [[0.0, -0.03, 0.02], [-0.17, 0.0, 0.02], [-0.14, 0.01, 0.0], [0.0, 0.02, -0.03]]
GEAR = [101, 101, 101, 81]
MOTOR_KT = [0.12, 0.12, 0.095, 0.07]
ROTOR = [0.6, 0.6, 0.35, 0.12]
PAYLOAD = {"mass": 3.0, "com": [0.0, 0.01, 0.07]}
CURRENT_NOISE = 0.03  # [A] at the motor
COLUMNS = "t=timestamp,q=q_,i=i_"


@dataclass
class ScaleCase:
    """The files of one case and the truth behind them."""

    robot: Path
    run1: Path
    run2: Path
    val1: Path
    kt_error: tuple


def _truth():
    links = tuple(
        LinkInertia(mass=m, com=np.array(c, float), inertia=np.diag([0.012, 0.011, 0.006]) * m)
        for m, c in zip(TRUE_MASS, TRUE_COM)
    )
    limits = [dict(q_min=-2.5, q_max=2.5, qd_max=2.2, qdd_max=10.0, tau_max=150.0) for _ in ROWS]
    robot = from_dh(ROWS, gravity=(0, 0, -9.81), name="kt cobot truth", drive_inertia=(True,) * len(ROWS),
                    links=links, rotor_inertia=np.array(ROTOR), limits=limits)  # fmt: skip
    drives = tuple(
        DriveParameters(kt=1.0, fc=f, fs=1.25 * f, vs=0.04, fv=v, sigma0=1e4, sigma1=30.0)
        for f, v in zip([3.0, 2.8, 1.9, 0.8], [4.0, 3.5, 2.2, 0.8])
    )
    return replace(robot, drives=drives), limits


def cobot() -> CurrentArm:
    """The true arm and what its user's file states: datasheet masses (rough), COMs at the joints, no rotors."""
    truth, limits = _truth()
    names = tuple(f"j{i + 1}" for i in range(len(ROWS)))
    return CurrentArm(truth=truth, rows=tuple(ROWS), limits=tuple(limits), joint_names=names,
                      file_mass=(4.0, 4.5, 3.0, 1.5), gear=tuple(GEAR), motor_kt=tuple(MOTOR_KT), name="kt cobot",
                      current_noise=CURRENT_NOISE)  # fmt: skip


def write_case(folder: Path, kt_error, seed: int = 0, seconds: float = 10.0, extras=()) -> ScaleCase:
    """Write the robot file and the three recordings into ``folder`` (``extras``: effects of the true arm the file
    does not state, ``write_current_recordings``)."""
    folder.mkdir(parents=True, exist_ok=True)
    arm = cobot()
    robot = folder / "cobot.toml"
    robot.write_text(arm.robot_file(kt_error))
    runs = (CurrentRun("run1", seconds), CurrentRun("run2", seconds, PAYLOAD), CurrentRun("val1", 0.7 * seconds))
    paths = write_current_recordings(folder, arm, runs, np.random.default_rng(seed), extras=extras)
    return ScaleCase(robot, *paths, kt_error=tuple(kt_error))
