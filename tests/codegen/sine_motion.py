"""A robot's joints along sums of sines about mid-range: the motion the export tests record torques along.

(The virtual robot's sine experiment turns about zero clipped into the ranges, where some joints, as the Panda's,
cannot move; inverse dynamics of an analytic reference along this motion is all those tests need.)
"""

from __future__ import annotations

import numpy as np


def sines_about_mid_range(robot, t, rng, band, scale):
    """(q, qd, qdd) at times ``t``: per joint three sines of frequencies drawn in ``band`` [Hz] and random phases,
    their amplitudes ``scale / 3`` of the half range, less where the acceleration limit asks."""
    omega = 2 * np.pi * rng.uniform(*band, size=(3, robot.n_dof))
    phase = rng.uniform(0.0, 2 * np.pi, size=(3, robot.n_dof))
    amplitude = scale / 3 * np.minimum(0.5 * (robot.q_max - robot.q_min), robot.qdd_max / omega.max(axis=0) ** 2)
    angle = omega[None] * t[:, None, None] + phase[None]
    q = 0.5 * (robot.q_min + robot.q_max) + amplitude * np.sin(angle).sum(axis=1)
    qd = amplitude * (omega * np.cos(angle)).sum(axis=1)
    qdd = -amplitude * (omega**2 * np.sin(angle)).sum(axis=1)
    return q, qd, qdd
