"""Small robots with published PSDM counts, for tests and documentation (standard DH, no drive inertia).

Gravity is given the way the method's authors give it, as the unit up-vector; the acceleration of
gravity is then -9.806132 times that vector.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from psdm_casadi.description import DriveParameters, LinkInertia
from psdm_casadi.robot import GRAVITY_STANDARD, RobotDescription, from_dh


def _gravity(up) -> np.ndarray:
    return -GRAVITY_STANDARD * np.asarray(up, dtype=float)


def two_link(reduced: bool = False) -> RobotDescription:
    """Planar 2R arm, links 1.2 m and 1.1 m, up-vector (0, 1, 0): p = 18, l = 6 (p = 10, l = 4 reduced).

    ``reduced=True`` keeps only m, r_x and I_zz of each link.
    """
    zero = [f"{p}{i}" for i in (1, 2) for p in ("ry", "rz", "Ixx", "Iyy", "Ixy", "Ixz", "Iyz")] if reduced else []
    return from_dh(
        [(1.2, 0, 0, 0), (1.1, 0, 0, 0)],
        gravity=_gravity([0, 1, 0]),
        zero_parameters=zero,
        name="two-link planar" + (" (m, rx, Izz)" if reduced else ""),
    )


def scara() -> RobotDescription:
    """SCARA RRPR, up-vector (0, 0, 1): p = 69, l = 8."""
    return from_dh(
        [(0.25, 0, 0.4, 0), (0.15, math.pi, 0, 0), (0, 0, 0, 0), (0, 0, 0, 0)],
        kinds=["revolute", "revolute", "prismatic", "revolute"],
        gravity=_gravity([0, 0, 1]),
        name="SCARA",
    )


def kr6() -> RobotDescription:
    """KUKA Agilus KR6, up-vector (0, 0, 1): p = 6086, l = 36."""
    pi = math.pi
    return from_dh(
        [
            (0.025, -pi / 2, 0.183, 0),
            (-0.315, 0, 0, 0),
            (-0.035, pi / 2, 0, 0),
            (0, -pi / 2, 0.365, 0),
            (0, pi / 2, 0, 0),
            (0, 0, 0.080, 0),
        ],
        gravity=_gravity([0, 0, 1]),
        name="KUKA KR6 Agilus",
    )


def serial_arm(n_dof: int = 12) -> RobotDescription:
    """An all-revolute serial arm of any size (standard DH), with link inertias, rotor inertias and drives.

    The rows repeat a pattern of offsets and twists of +-pi/2 and pi/3 so that no two consecutive
    axes are parallel or intersect everywhere: a generic arm, for tests and the derivation benchmark
    of robots beyond the sum form's 8 joints (``examples/serial_arm_12.toml`` is ``serial_arm(12)``).
    Up-vector (0, 0, 1); links lighter towards the tip; LuGre drives of one kind on every joint.
    """
    pi = math.pi
    pattern = [(0.05, -pi / 2, 0.30), (0.25, 0.0, 0.0), (0.04, pi / 2, 0.0), (0.0, -pi / 3, 0.22)]
    rows = [(a, alpha, d, 0.0) for a, alpha, d in (pattern[i % len(pattern)] for i in range(n_dof))]
    links, rotors = [], []
    for i in range(n_dof):
        mass = max(6.0 * 0.85**i, 0.5)
        sign = 1.0 if i % 2 == 0 else -1.0
        inertia = np.diag([0.010, 0.008, 0.006]) * mass + np.array([[0, 1, 0], [1, 0, 0], [0, 0, 0]]) * 1e-3 * sign
        links.append(LinkInertia(mass=mass, com=np.array([-0.02 * sign, 0.03, 0.05]), inertia=inertia))
        rotors.append(1.5 * 0.9**i)  # reflected rotor inertia as real drives have: the virtual robot stays stable
    robot = from_dh(
        rows,
        gravity=_gravity([0, 0, 1]),
        drive_inertia=(True,) * n_dof,
        links=tuple(links),
        rotor_inertia=np.array(rotors),
        limits=[{"tau_max": 400.0 * 0.8**i} for i in range(n_dof)],
        name=f"serial arm {n_dof}",
    )
    drive = DriveParameters(kt=5.0, fc=2.0, fs=2.5, vs=0.02, fv=3.0, dv=1.0, sigma0=1e4, sigma1=10.0)
    return replace(robot, drives=(drive,) * n_dof)
