"""Small robots with published PSDM counts, for tests and documentation (standard DH, no drive inertia).

Gravity is given the way the method's authors give it, as the unit up-vector; the acceleration of
gravity is then -9.806132 times that vector.
"""

from __future__ import annotations

import math

import numpy as np

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
