"""The MJCF round trip of an identification, for the real-data benchmarks (key ``mjcf_max_rel_error``).

The fit is written as a calibrated model, exported as MJCF (``codegen.mjcf_export``) and MuJoCo's ``mj_inverse``
on the file is compared with the model's torque without its Coulomb term and offsets on the validation states
(``codegen.mjcf_check``; target <= 1e-9 relative).
"""

from __future__ import annotations

import numpy as np

from codegen.mjcf_check import mjcf_round_trip
from codegen.mjcf_export import render_mjcf
from identification.calibration.calibrated_model import CalibratedModel

MAX_ROWS = 2000  # validation states compared (evenly spaced): mj_inverse runs in a Python loop
MJCF_TARGET = 1e-9


def mjcf_max_rel_error(robot, model, fit, q, qd, qdd) -> dict:
    """``{"mjcf_max_rel_error", "mjcf_friction_saturated"}`` of the fit's MJCF on states (n, n_dof)."""
    calibrated = CalibratedModel.from_fit(robot, model, fit, robot_source=robot.source)
    rows = np.unique(np.linspace(0, len(q) - 1, min(MAX_ROWS, len(q))).astype(int))
    result = mjcf_round_trip(calibrated, model, render_mjcf(calibrated, robot), q[rows], qd[rows], qdd[rows])
    return {"mjcf_max_rel_error": result.max_rel_error, "mjcf_friction_saturated": result.friction_saturated}
