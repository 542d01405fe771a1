"""A small virtual cobot logging motor currents, a known payload on one recording, torque constants off on some joints.

The user's robot file states ``[transmission] gear_ratios`` and ``motor_kt`` (the datasheet's, times ``kt_error``
per joint) with rough links; the recordings are the true arm's motor currents, so a joint whose ``kt_error`` is
1.15 records 15 % too much torque. ``run1`` carries nothing, ``run2`` a known 3 kg payload (sidecar), ``val1``
nothing. (Adapted from the project's new-user trial generator of a 7-joint cobot; four joints keep it fast.)
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from identification.virtual.effects import Payload
from identification.virtual.simulation import SimulationOptions, simulate_recording
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


def _robot_file(limits, kt_error) -> str:
    """The user's file: datasheet masses (rough), COMs at the joint, no rotors, gears and (erroneous) motor_kt."""
    text = ['format = "psdm-robot/1"', 'name = "kt cobot"', 'convention = "standard"', "gravity = [0.0, 0.0, -9.81]"]
    for i, (a, alpha, d, theta) in enumerate(ROWS):
        text += ["", "[[joint]]", f'name = "j{i + 1}"', f"a = {a}", f"alpha = {alpha!r}", f"d = {d}",
                 f"theta = {theta}", *(f"{k} = {v}" for k, v in limits[i].items())]  # fmt: skip
    for m in [4.0, 4.5, 3.0, 1.5]:
        text += ["", "[[link]]", f"mass = {m}", "com = [0.0, 0.0, 0.0]", f"inertia = [{0.01 * m}, {0.01 * m}, "
                 f"{0.006 * m}, 0.0, 0.0, 0.0]"]  # fmt: skip
    stated = [k * e for k, e in zip(MOTOR_KT, kt_error)]
    text += ["", "[transmission]", f"gear_ratios = {GEAR}", f"motor_kt = {stated}", "", "[recording]",
             'side = { q = "joint", tau = "motor", current = "motor" }', ""]  # fmt: skip
    return "\n".join(text)


def _reference(robot, duration: float, rng):
    """Sum of three sines per joint within half its limits, faded in and out."""
    t = np.arange(0.0, duration + 1e-9, 1e-3)
    fade = 0.5 * (1.0 - np.cos(np.pi * np.minimum(1.0, np.minimum(t, duration - t))))
    q = np.zeros((t.size, robot.n_dof))
    for j in range(robot.n_dof):
        omega = 2.0 * np.pi * rng.uniform(0.1, 0.5, 3)
        phase, weight = rng.uniform(0.0, 2.0 * np.pi, 3), rng.uniform(0.5, 1.0, 3)
        scale = 0.5 * min(robot.q_max[j] / weight.sum(), robot.qd_max[j] / (weight * omega).sum(),
                          robot.qdd_max[j] / (weight * omega**2).sum())  # fmt: skip
        x = (scale * weight * np.sin(np.outer(t, omega) + phase)).sum(axis=1)
        q[:, j] = fade * (x - x[0])
    return t, q


def write_case(folder: Path, kt_error, seed: int = 0, seconds: float = 10.0) -> ScaleCase:
    """Write the robot file and the three recordings into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    truth, limits = _truth()
    robot = folder / "cobot.toml"
    robot.write_text(_robot_file(limits, kt_error))
    paths = []
    for name, duration, load in (("run1", seconds, None), ("run2", seconds, PAYLOAD), ("val1", 0.7 * seconds, None)):
        payload = None if load is None else Payload(mass=load["mass"], com=np.array(load["com"]))
        options = SimulationOptions(rate=1000.0, record_tau=True, record_current=False, tau_noise_std=0.0,
                                    payload=payload, q_noise_std=0.0)  # fmt: skip
        rec, _ = simulate_recording(truth, _reference(truth, duration, rng), options, rng)
        gain = np.array(GEAR) * np.array(MOTOR_KT)
        current = rec.tau / gain + rng.normal(0.0, CURRENT_NOISE, rec.tau.shape)
        header = ["timestamp"] + [f"q_{j + 1}" for j in range(truth.n_dof)] + [f"i_{j + 1}" for j in range(4)]
        path = folder / f"{name}.csv"
        np.savetxt(path, np.column_stack([rec.t, rec.q, current]), delimiter=",", header=",".join(header),
                   comments="", fmt="%.9g")  # fmt: skip
        if load is not None:
            path.with_suffix(".payload.json").write_text(json.dumps(load))
        paths.append(path)
    return ScaleCase(robot, *paths, kt_error=tuple(kt_error))
