"""A heavy industrial-class arm for the diagnosis benchmark, and CAD-like errors of a robot file's inertia.

``heavy_industrial_arm`` scales the Denso VS-6556G robot file geometrically: lengths by ``LENGTH``, masses by
``MASS`` (so link inertias by ``MASS * LENGTH**2``), reflected rotor inertias by the same factor (the rotors
keep dominating the joint torque, as on large arms with high gear ratios), and friction, torque constants and
torque limits by ``MASS * LENGTH`` (the gravity torque scale). Speeds and accelerations are lowered to those of
a 200 kg-class arm. The result is a six-axis arm of about 1 t whose base joints carry several kN m; a payload
of 100-200 kg at the flange changes their torque by a large fraction.

``cad_error`` returns the same robot with every link's mass, centre of mass and inertia off by 10-20 % (a
random sign per quantity, drawn with a seed), the way CAD values are off from a real arm: the simulation uses
the perturbed robot as the truth and the diagnosis the unperturbed robot file.

The arm is written to a robot file (``write_robot_file``, in a temporary folder removed at exit) and read back, so
its calibrated models can be stored (a model file keeps the robot file's text) and exported.
"""

from __future__ import annotations

import atexit
import dataclasses
import shutil
import tempfile
from pathlib import Path

import numpy as np
from bench_support import DENSO_FILE

from psdm_casadi.robot import LinkInertia, load_robot
from psdm_casadi.robot_writer import write_robot_file

LENGTH = 3.2  # length scale over the Denso VS-6556G
MASS = 45.0  # mass scale
SPEED = 0.4  # speed and acceleration limits relative to the Denso's


def heavy_industrial_arm(folder=None):
    """The scaled Denso (see the module docstring), named ``heavy industrial arm``, read back from the robot file
    ``heavy_industrial_arm.toml`` written in ``folder`` (default: a temporary folder removed at exit)."""
    if folder is None:
        folder = tempfile.mkdtemp(prefix="psdm-heavy-arm-")
        atexit.register(shutil.rmtree, folder, True)
    path = write_robot_file(_scaled_denso(), Path(folder) / "heavy_industrial_arm.toml", overwrite=True)
    return load_robot(path)


def _scaled_denso():
    denso = load_robot(DENSO_FILE)
    inertia_scale, torque_scale = MASS * LENGTH**2, MASS * LENGTH
    joints = tuple(
        dataclasses.replace(
            j,
            a=j.a * LENGTH,
            d=j.d * LENGTH,
            qd_max=j.qd_max * SPEED,
            qdd_max=j.qdd_max * SPEED,
            tau_max=j.tau_max * torque_scale,
        )
        for j in denso.joints
    )
    links = tuple(
        LinkInertia(
            mass=link.mass * MASS, com=np.asarray(link.com) * LENGTH, inertia=np.asarray(link.inertia) * inertia_scale
        )
        for link in denso.links
    )
    drives = tuple(
        dataclasses.replace(
            d,
            kt=d.kt * torque_scale,
            fc=d.fc * torque_scale,
            fs=d.fs * torque_scale,
            fv=d.fv * torque_scale,
            sigma0=d.sigma0 * torque_scale,
            sigma1=d.sigma1 * torque_scale,
        )
        for d in denso.drives
    )
    return dataclasses.replace(
        denso,
        name="heavy industrial arm",
        joints=joints,
        links=links,
        rotor_inertia=np.asarray(denso.rotor_inertia, dtype=float) * inertia_scale,
        drives=drives,
        source=None,
    )


def cad_error(robot, rng, low: float = 0.1, high: float = 0.2):
    """``robot`` with each link's mass, centre of mass and inertia tensor scaled by ``1 +- U(low, high)``."""

    def factor():
        return 1.0 + float(rng.choice([-1.0, 1.0])) * float(rng.uniform(low, high))

    links = tuple(
        LinkInertia(
            mass=link.mass * factor(), com=np.asarray(link.com) * factor(), inertia=np.asarray(link.inertia) * factor()
        )
        for link in robot.links
    )
    return robot.with_links(links)
