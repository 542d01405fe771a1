"""A UR10-class cobot from its vendor URDF whose known load changes between recordings, its wrist joint 6 driven by a
7:1 belt: a case of ``unseen_cases`` (``cobot_belt_payload_change``).

The user's robot file is the vendor URDF (example-robot-data's ``ur10_robot.urdf``, no rotors) with the gear ratios
``[101, 101, 101, 101, 101, 7]`` and the motor torque constants; the arm as built weighs 5-12 % more per link (cables,
covers), its centres of mass sit a few millimetres off, its drives have rotors and LuGre friction with a Stribeck
hump. The belt's motor pulley runs out of true: a ripple of 7 periods per turn of joint 6 (0.3 N m), the physics the
diagnosis should name. The controller logs joint positions in degrees and motor currents in mA at 500 Hz, as a
European logger writes CSV (semicolons, decimal commas, units in the header). Two training recordings carry two
known loads, stated in a ``configurations.toml`` (no sidecars): a 1.9 kg gripper (a point mass to its user, a body
to the truth) and the gripper holding a 7.4 kg part (its inertia from CAD); the held-out recording carries the part,
stated in its sidecar. Payload centres of mass are in the last link's frame (the URDF's ``wrist_3_link``, whose tool
axis is +y).
"""

from __future__ import annotations

import json
import sysconfig
from pathlib import Path

import numpy as np
from unseen_cases import Case, _reference, _simulate, friction_shapes

from identification.virtual.effects import Payload, TorqueRipple
from psdm_casadi.robot import load_robot

__all__ = ["belt_cobot"]

LINKS = ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link")
BUILT = (1.06, 1.09, 1.12, 1.05, 1.08, 1.10)  # the built arm's masses over the URDF's
ROTOR = (0.62, 0.62, 0.35, 0.12, 0.12, 0.0123)  # reflected [kg m^2]; joint 6: 2.5e-4 x 7^2 through the belt
GEAR = (101, 101, 101, 101, 101, 7)
MOTOR_KT = (0.125, 0.125, 0.125, 0.09, 0.09, 0.35)  # [N m/A]
FC, FV = (5.0, 5.0, 3.0, 1.2, 1.2, 0.25), (8.0, 8.0, 4.0, 1.5, 1.5, 0.2)  # Coulomb [N m], viscous [N m s/rad]
CURRENT_NOISE = 0.02  # [A] at the motor
GRIPPER = {"mass": 1.9, "com": [0.0, 0.162, 0.0]}
PART = {"mass": 7.4, "com": [0.03, 0.24, 0.0], "inertia": [[0.05, 0.0, 0.0], [0.0, 0.02, 0.0], [0.0, 0.0, 0.05]]}
GRIPPER_INERTIA = np.diag([0.004, 0.002, 0.004])  # the truth's; its user states the gripper as a point mass
RIPPLE = TorqueRipple(joint=5, amplitude=0.3, harmonic=7.0, phase=0.8)
#: (file stem, seconds, load); the last is held out
RUNS = (("gripper_1", 20.0, "gripper"), ("part_1", 20.0, "part"), ("check_part", 10.0, "part"))


def ur10_urdf() -> Path:
    """The example-robot-data UR10 URDF (the vendor's file as ROS users get it)."""
    for base in {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}:
        path = Path(base) / "cmeel.prefix/share/example-robot-data/robots/ur_description/urdf/ur10_robot.urdf"
        if path.exists():
            return path
    raise FileNotFoundError("example-robot-data's ur10_robot.urdf is not installed (pip install example-robot-data)")


def _files(folder: Path):
    """Write the truth's robot file and the user's; return (user's file, the true robot)."""
    urdf = ur10_urdf()
    vendor = load_robot(urdf)
    body = f'format = "psdm-robot/1"\n[urdf]\npath = "{urdf}"\n\n'
    for name, link, built, rotor in zip(LINKS, vendor.links, BUILT, ROTOR):
        com = np.asarray(link.com) + np.array([0.0, 0.004, -0.005])
        body += (f'[[link]]\nname = "{name}"\nmass = {link.mass * built:.5f}\n'
                 f"com = [{com[0]:.5f}, {com[1]:.5f}, {com[2]:.5f}]\nrotor_inertia = {rotor}\n\n")  # fmt: skip
    body += "".join(f"[[drive]]\nkt = {g * k}\nfc = {fc}\nfs = {1.25 * fc}\nvs = 0.05\nfv = {fv}\n\n"
                    for g, k, fc, fv in zip(GEAR, MOTOR_KT, FC, FV))  # fmt: skip
    (folder / "truth").mkdir(exist_ok=True)
    (folder / "truth" / "truth.toml").write_text(body)
    user = folder / "ur10.toml"
    user.write_text(f'format = "psdm-robot/1"\nname = "ur10 with a belt wrist"\n[urdf]\npath = "{urdf}"\n\n'
                    f"[transmission]\ngear_ratios = {list(GEAR)}\nmotor_kt = {list(MOTOR_KT)}\n\n"
                    '[recording]\nside = { q = "joint", current = "motor" }\n')  # fmt: skip
    return user, load_robot(folder / "truth" / "truth.toml")


def _write_log(path: Path, t, q, current_ma) -> Path:
    """A semicolon CSV with decimal commas and the units in the header (degrees, mA)."""
    header = ["t [s]"] + [f"q{j + 1} [deg]" for j in range(6)] + [f"i{j + 1} [mA]" for j in range(6)]
    rows = [";".join(header)]
    rows += [";".join(f"{v:.6f}".replace(".", ",") for v in row) for row in np.column_stack([t, np.degrees(q),
                                                                                           current_ma])]  # fmt: skip
    path.write_text("\n".join(rows) + "\n")
    return path


def belt_cobot(folder: Path, rng) -> Case:
    """Write the case's files into ``folder`` (the recordings drawn from ``rng``) and return it with its truth."""
    user, truth = _files(folder)
    gain = np.asarray(GEAR, dtype=float) * np.asarray(MOTOR_KT)
    part = Payload(mass=PART["mass"], com=np.array(PART["com"]), inertia=np.array(PART["inertia"]))
    loads = {"gripper": Payload(mass=GRIPPER["mass"], com=np.array(GRIPPER["com"]), inertia=GRIPPER_INERTIA),
             "part": part}  # fmt: skip
    paths, floor = [], None
    for name, seconds, load in RUNS:
        rec, floor = _simulate(truth, _reference(truth, seconds, rng), 1000.0, CURRENT_NOISE * gain, rng,
                               extras=(RIPPLE,), payload=loads[load])  # fmt: skip
        keep = np.arange(0, rec.n_samples, 2)  # logged at 500 Hz
        paths.append(_write_log(folder / f"{name}.csv", rec.t[keep], rec.q[keep], 1000.0 * rec.tau[keep] / gain))
    (folder / "part.payload.json").write_text(json.dumps(PART))
    (folder / "check_part.payload.json").write_text(json.dumps(PART))
    manifest = folder / "configurations.toml"
    manifest.write_text('[[configuration]]\nname = "gripper"\npayload = {mass = 1.9, com = [0.0, 0.162, 0.0]}\n'
                        'recordings = ["gripper_1.csv"]\n\n[[configuration]]\nname = "gripper with part"\n'
                        'payload = "part.payload.json"\nrecordings = ["part_1.csv"]\n')  # fmt: skip
    return Case(
        name="cobot_belt_payload_change",
        what="UR10 vendor URDF (links 5-12 % light, no rotors), motor currents in mA and degrees at 500 Hz (semicolons,"
        " decimal commas), 7:1 belt on J6 with a 7-per-turn ripple, known 1.9 kg then 7.4 kg in a configurations.toml",
        robot=user,
        train=tuple(paths[:-1]),
        validate=paths[-1],
        data=(manifest,),
        true_links=np.array([link.mass for link in truth.links]),
        payload_mass=PART["mass"],
        floor_nm=floor,
        hidden=(("torque_ripple", 6),),
        friction_shapes=friction_shapes(truth),
        effects=(RIPPLE,),
    )
