"""A 7-joint cobot (KUKA LBR iiwa 14-like) from its vendor URDF, logged as its controller logs it over a session in
which the joints warm up: a case of ``unseen_cases`` (``cobot_warming_currents``).

The vendor URDF has fixed joints (world, flange, ``tool0``), mesh geometry the user does not have and CAD inertials;
the arm as built weighs 4-14 % more per link (cables, covers) and its drives have rotors the URDF lacks. The robot
file adds the gear ratios and the datasheet's motor torque constants, joint 4's 10 % high. The controller logs
motor-side positions and motor currents at 500 Hz with jittered wall-clock stamps and a dropped 80 ms stretch. Three
recordings of one ten-minute session: at 0 s and 300 s (this one carrying a known 4 kg load, stated in its sidecar)
for training, at 560 s held out. The friction falls as the joints warm, ``1 + 0.35 exp(-t / 200 s)`` times the
warm arm's, so the training recordings carry 1.07-1.35 times the friction of the held-out one. The controller logs
the joints' temperature ``Temp1..7`` every 0.5 s (NaN between), ``45 - 20 exp(-t / 200 s)`` °C: the friction is a
straight line in it, which identify can read and keep in the model file (``drive.temperature``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from unseen_cases import Case, friction_shapes

from identification.virtual.current_arm import faded_sines
from identification.virtual.effects import Payload
from identification.virtual.lugre_exact import LuGreArrays, steady_state_friction
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.robot import load_robot

__all__ = ["joint_temperature", "session_recording", "warming_cobot"]

PI = np.pi
#: (origin xyz, rpy) of joints A1..A7 (the iiwa 14's kinematics)
JOINTS = (((0, 0, 0.1575), (0, 0, 0)), ((0, 0, 0.2025), (PI / 2, 0, PI)), ((0, 0.2045, 0), (PI / 2, 0, PI)),
          ((0, 0, 0.2155), (PI / 2, 0, 0)), ((0, 0.1845, 0), (-PI / 2, PI, 0)), ((0, 0, 0.2155), (PI / 2, 0, 0)),
          ((0, 0.081, 0), (-PI / 2, PI, 0)))  # fmt: skip
LIMITS = ((2.96, 1.48, 320), (2.09, 1.48, 320), (2.96, 1.74, 176), (2.09, 1.30, 176), (2.96, 2.27, 110),
          (2.09, 2.36, 40), (3.05, 2.36, 40))  # fmt: skip  # (position [rad], speed [rad/s], effort [N m])
#: CAD inertials of links 0..7: (mass, centre of mass, principal moments)
CAD = ((5.0, (-0.1, 0, 0.07), (0.05, 0.06, 0.03)), (4.0, (0, -0.03, 0.12), (0.1, 0.09, 0.02)),
       (4.0, (0.0003, 0.059, 0.042), (0.05, 0.018, 0.044)), (3.0, (0, 0.03, 0.13), (0.08, 0.075, 0.01)),
       (2.7, (0, 0.067, 0.034), (0.03, 0.01, 0.029)), (1.7, (0.0001, 0.021, 0.076), (0.02, 0.018, 0.005)),
       (1.8, (0, 0.0006, 0.0004), (0.005, 0.0036, 0.0047)), (0.3, (0, 0, 0.02), (0.001, 0.001, 0.001)))  # fmt: skip
BUILT = (1.0, 1.08, 1.12, 1.05, 1.14, 1.04, 1.09, 1.1)  # the built arm's masses over CAD's (cables, covers)
GEAR = (160, 160, 160, 160, 100, 160, 160)
MOTOR_KT = (0.105, 0.105, 0.082, 0.082, 0.056, 0.046, 0.046)  # [N m/A], the datasheet's and the truth
KT_STATED = (1.0, 1.0, 1.0, 1.10, 1.0, 1.0, 1.0)  # the robot file's over the truth: joint 4 reads 10 % high
ROTOR = (0.55, 0.55, 0.32, 0.32, 0.12, 0.06, 0.06)  # reflected rotor inertia [kg m^2]
FC, FV = (1.6, 1.6, 1.1, 1.1, 0.6, 0.35, 0.35), (3.0, 3.0, 2.0, 2.0, 1.2, 0.6, 0.6)  # warm friction
CURRENT_NOISE = 0.02  # [A]
#: (file stem, start in the session [s], length [s], known load or None); the last is held out
RUNS = (("session_0000s", 0.0, 30.0, None), ("session_0300s", 300.0, 30.0, {"mass": 4.0, "com": [0.0, 0.01, 0.08]}),
        ("session_0560s", 560.0, 20.0, None))  # fmt: skip
COLD_C, WARM_C, WARMING_S = 25.0, 45.0, 200.0  # the joints' temperature from cold to warm [°C], its time constant [s]
TEMPERATURE_EVERY = 250  # a temperature reading every 250 logged samples (0.5 s): NaN between, as a slow logger's


def _urdf(scale, shift) -> str:
    """The URDF text: CAD inertials times ``scale`` per link, links 2-6's centres of mass moved by ``shift``."""
    out = [
        '<?xml version="1.0"?>',
        '<robot name="lbr_iiwa_14_r820">',
        '<link name="world"/>',
        '<joint name="world_joint" type="fixed"><parent link="world"/><child link="lbr_link_0"/></joint>',
    ]
    for i, (mass, com, moments) in enumerate(CAD):
        c = np.asarray(com) + (shift if 1 < i < 7 else 0.0)
        ixx, iyy, izz = (scale[i] * m for m in moments)
        mesh = f'<geometry><mesh filename="package://lbr_description/meshes/iiwa14/link_{i}.stl"/></geometry>'
        out.append(
            f'<link name="lbr_link_{i}"><inertial><origin xyz="{c[0]:.4f} {c[1]:.4f} {c[2]:.4f}"/>'
            f'<mass value="{mass * scale[i]:.4f}"/><inertia ixx="{ixx:.5f}" ixy="0" ixz="0" iyy="{iyy:.5f}" '
            f'iyz="0" izz="{izz:.5f}"/></inertial><visual>{mesh}</visual><collision>{mesh}</collision></link>'
        )
        if i < 7:
            (x, y, z), (r, p, w) = JOINTS[i]
            low, speed, effort = LIMITS[i]
            out.append(f'<joint name="lbr_A{i + 1}" type="revolute"><parent link="lbr_link_{i}"/>'
                       f'<child link="lbr_link_{i + 1}"/><origin xyz="{x} {y} {z}" rpy="{r} {p} {w}"/>'
                       f'<axis xyz="0 0 1"/><limit lower="{-low}" upper="{low}" effort="{effort}" '
                       f'velocity="{speed}"/></joint>')  # fmt: skip
    out += ['<joint name="lbr_joint_ee" type="fixed"><parent link="lbr_link_7"/><child link="lbr_link_ee"/>'
            '<origin xyz="0 0 0.045"/></joint><link name="lbr_link_ee"/>',
            '<joint name="flange_tool0" type="fixed"><parent link="lbr_link_ee"/><child link="tool0"/></joint>'
            '<link name="tool0"/>', "</robot>"]  # fmt: skip
    return "\n".join(out)


def _files(folder: Path):
    """Write the vendor URDF, the user's robot file and the truth's; return (user's file, the true robot)."""
    (folder / "lbr_iiwa14.urdf").write_text(_urdf((1.0,) * 8, np.zeros(3)))
    (folder / "truth").mkdir(exist_ok=True)
    (folder / "truth" / "built.urdf").write_text(_urdf(BUILT, np.array([0.0, 0.004, -0.006])))
    body = f'format = "psdm-robot/1"\n[urdf]\npath = "{folder / "truth" / "built.urdf"}"\n\n'
    body += "".join(f'[[link]]\nname = "lbr_link_{i + 1}"\nrotor_inertia = {r}\n\n' for i, r in enumerate(ROTOR))
    body += "".join(f"[[drive]]\nkt = {g * k}\nfc = {fc}\nfs = {1.2 * fc}\nvs = 0.05\nfv = {fv}\n\n"
                    for g, k, fc, fv in zip(GEAR, MOTOR_KT, FC, FV))  # fmt: skip
    (folder / "truth" / "truth.toml").write_text(body)
    stated = [round(k * e, 6) for k, e in zip(MOTOR_KT, KT_STATED)]
    user = folder / "iiwa14.toml"
    user.write_text(f'format = "psdm-robot/1"\nname = "lbr_iiwa14"\n[urdf]\npath = "lbr_iiwa14.urdf"\n\n'
                    f"[transmission]\ngear_ratios = {list(GEAR)}\nmotor_kt = {stated}\n\n"
                    '[recording]\nside = { q = "motor", current = "motor" }\n')  # fmt: skip
    return user, load_robot(folder / "truth" / "truth.toml")


def joint_temperature(session_s):
    """[°C] The joints' temperature at ``session_s`` seconds into the session: ``45 - 20 exp(-t / 200 s)``, so the
    friction above the warm arm's, ``0.35 exp(-t / 200 s)``, is ``0.35 (45 - T) / 20``: a straight line in T."""
    return WARM_C - (WARM_C - COLD_C) * np.exp(-np.asarray(session_s, dtype=float) / WARMING_S)


def session_recording(folder: Path, robot, name: str, start: float, duration: float, load, rng) -> tuple:
    """Write one recording of the session (``start`` [s] into it, ``duration`` [s], a known ``load`` or None) as the
    controller logs it, its joints' temperature every ``TEMPERATURE_EVERY`` samples (NaN between, rounded to 0.1 °C);
    return (its path, the floor [N m] per joint: current noise, LuGre's dynamics and the warming, as RMS)."""
    lugre = LuGreArrays.from_drives(robot.drives)
    gain = np.asarray(GEAR, dtype=float) * np.asarray(MOTOR_KT)
    payload = None if load is None else Payload(mass=load["mass"], com=np.asarray(load["com"]))
    options = SimulationOptions(rate=1000.0, record_tau=True, record_current=False, tau_noise_std=0.0,
                                payload=payload, q_noise_std=0.0)  # fmt: skip
    rec, truth = simulate_recording(robot, faded_sines(robot, duration, rng), options, rng)
    steady = steady_state_friction(truth.qd, lugre)
    warming = 0.35 * np.exp(-(start + rec.t) / WARMING_S)[:, None] * steady  # the friction above the warm arm's
    keep = np.arange(0, rec.n_samples, 2)  # logged at 500 Hz ...
    keep = keep[(rec.t[keep] < 0.55 * duration) | (rec.t[keep] >= 0.55 * duration + 0.08)]  # ... 80 ms dropped
    stamps = np.maximum.accumulate(rec.t[keep] + rng.normal(0.0, 1.5e-4, keep.size))
    stamps[1:] = np.maximum(stamps[1:], stamps[:-1] + 1e-6)  # a logger's clock never runs back
    current = (rec.tau + warming)[keep] / gain + rng.normal(0.0, CURRENT_NOISE, (keep.size, gain.size))
    temperature = np.full((keep.size, 7), np.nan)
    read = np.arange(0, keep.size, TEMPERATURE_EVERY)
    temperature[read] = np.round(joint_temperature(start + rec.t[keep][read]), 1)[:, None]
    header = ["time", *(f"motor_pos_{j + 1}" for j in range(7)), *(f"motor_current_{j + 1}" for j in range(7)),
              *(f"Temp{j + 1}" for j in range(7))]  # fmt: skip
    path = folder / f"{name}.csv"
    data = np.column_stack([stamps + 1765000000.0 + start, rec.q[keep] * np.asarray(GEAR), current, temperature])
    np.savetxt(path, data, delimiter=",", header=",".join(header), comments="",
               fmt=["%.6f"] + ["%.8g"] * 14 + ["%.1f"] * 7)  # fmt: skip
    if load is not None:
        path.with_suffix(".payload.json").write_text(json.dumps(load))
    dynamic = truth.tau_friction - steady  # LuGre's departure from its steady state
    return path, np.sqrt((CURRENT_NOISE * gain) ** 2 + np.mean(dynamic**2, axis=0) + np.mean(warming**2, axis=0))


def warming_cobot(folder: Path, rng) -> Case:
    """Write the case's files into ``folder`` (the recordings drawn from ``rng``) and return it with its truth."""
    user, robot = _files(folder)
    paths, floor = [], None
    for name, start, duration, load in RUNS:
        path, floor = session_recording(folder, robot, name, start, duration, load, rng)
        paths.append(path)
    return Case(
        name="cobot_warming_currents",
        what="iiwa14-like vendor URDF (meshes absent, CAD masses 4-14 % low, no rotors), motor-side q and currents"
        " at 500 Hz, jitter, 80 ms gap, joint 4 kt 10 % high, friction 1.35x -> 1x over the session (Temp1..7 logged),"
        " 4 kg stated",
        robot=user,
        train=tuple(paths[:-1]),
        validate=paths[-1],
        extra=("--columns", "t=time,q=motor_pos_,i=motor_current_"),
        true_links=np.array([link.mass for link in robot.links]),
        payload_mass=4.0,
        floor_nm=floor,
        friction_shapes=friction_shapes(robot),
    )
