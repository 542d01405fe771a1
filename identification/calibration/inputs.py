"""Input checks shared by the calibration steps: models, vectors, recordings, experiments, known tools."""

from __future__ import annotations

import numpy as np

from identification.calibration.payload import payload_static_torque, payload_torque
from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, RecordingError, ShapeError
from psdm_casadi.model import PSDMModel

__all__ = ["check_model", "vector", "recordings", "experiments", "tool_torque"]


def check_model(model, owner):
    """Raise :class:`ParameterError` unless ``model`` is a PSDMModel (``owner`` names the estimator)."""
    if not isinstance(model, PSDMModel):
        raise ParameterError(f"{owner}.model must be a PSDMModel; got {type(model).__name__}. Use derive_psdm(robot).")


def vector(value, size, owner, field, unit):
    """``value`` as ``size`` finite floats, shape (size,); :class:`ShapeError` names ``owner.field`` and ``unit``."""
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (size,) or not np.all(np.isfinite(arr)):
        raise ShapeError(f"{owner}.{field} must be {size} finite values [{unit}]; got shape {arr.shape}.")
    return arr


def recordings(data, owner):
    """``data`` (a Recording or a sequence of them) as a list of preprocessed recordings (qd and qdd present)."""
    items = [data] if isinstance(data, Recording) else list(data)
    if not items or not all(isinstance(r, Recording) for r in items):
        raise ParameterError(f"{owner}.fit data must be a Recording or a non-empty sequence of Recordings.")
    for rec in items:
        if rec.qd is None or rec.qdd is None:
            raise RecordingError(
                f"Recording.qd/qdd are missing ({rec.name}); {owner} needs them. Run preprocess(recording) first."
            )
    return items


def experiments(data, kind, owner, n_dof):
    """``data`` (one ``kind`` experiment or a sequence of them) as a list, each with a joint in 0..n_dof-1.

    ``kind`` is an experiment class with a ``joint`` field (MotorExperiment, FrictionExperiment).
    """
    items = [data] if isinstance(data, kind) else list(data)
    if not items or not all(isinstance(e, kind) for e in items):
        raise ParameterError(f"{owner}.fit data must be a {kind.__name__} or a sequence of them.")
    for e in items:
        if not (0 <= e.joint < n_dof):
            raise ParameterError(f"{kind.__name__}.joint must be in 0..{n_dof - 1}; got {e.joint!r}.")
    return items


def tool_torque(robot, tool, rec, static):
    """Torques [N m] of the known load ``tool`` along ``rec`` (gravity alone if ``static``).

    Shape (n_samples, n_dof).
    """
    if tool is None:
        return np.zeros_like(rec.q)
    if robot is None:
        raise ParameterError("the tool torque needs the robot; pass robot= together with tool=.")
    if static:
        return payload_static_torque(robot, tool, rec.q)
    return payload_torque(robot, tool, rec.q, rec.qd, rec.qdd)
