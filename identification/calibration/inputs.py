"""Input checks shared by the calibration step estimators (steps, friction_step): models, vectors, recordings, tool torque."""

from __future__ import annotations

import numpy as np

from psdm_casadi.errors import ParameterError, RecordingError, ShapeError
from psdm_casadi.model import PSDMModel

from identification.calibration.payload import payload_static_torque, payload_torque
from identification.data.recording import Recording


def check_model(model, owner):
    if not isinstance(model, PSDMModel):
        raise ParameterError(f"{owner}.model must be a PSDMModel; got {type(model).__name__}. Use derive_psdm(robot).")


def vector(value, size, owner, field, unit):
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (size,) or not np.all(np.isfinite(arr)):
        raise ShapeError(f"{owner}.{field} must be {size} finite values [{unit}]; got shape {arr.shape}.")
    return arr


def recordings(data, owner):
    items = [data] if isinstance(data, Recording) else list(data)
    if not items or not all(isinstance(r, Recording) for r in items):
        raise ParameterError(f"{owner}.fit data must be a Recording or a non-empty sequence of Recordings.")
    for rec in items:
        if rec.qd is None or rec.qdd is None:
            raise RecordingError(f"Recording.qd/qdd are missing ({rec.name}); {owner} needs them. "
                                 "Run preprocess(recording) first.")
    return items


def tool_torque(robot, tool, rec, static):
    if tool is None:
        return np.zeros_like(rec.q)
    if robot is None:
        raise ParameterError("the tool torque needs the robot; pass robot= together with tool=.")
    if static:
        return payload_static_torque(robot, tool, rec.q)
    return payload_torque(robot, tool, rec.q, rec.qd, rec.qdd)
