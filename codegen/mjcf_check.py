"""The MJCF round trip: MuJoCo's inverse dynamics on a written MJCF against the calibrated model's own torque.

``calibrated model ─export_mjcf→ MJCF ─mujoco.mj_inverse→ torque`` must be the model's rigid body, drive inertias,
viscous friction and linear springs (``CalibratedModel.predict`` without the Coulomb term, the torque offsets and
the findings MJCF cannot hold): :func:`mjcf_round_trip` measures the largest relative difference with MuJoCo's
constraints disabled, and then what ``frictionloss`` adds with them enabled. MuJoCo treats friction loss as a
constraint, so that part is not ``fc tanh(qd / v)``: its force is bounded by ``fc`` and opposes the motion (it
saturates at ``fc`` while the joint slides, and is anywhere within ``[-fc, fc]`` near rest).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numpy as np

from codegen.target_holds import is_linear_spring
from identification.calibration.findings import FindingTerm
from psdm_casadi.mjcf import compile_mjcf, route_mujoco_warnings

__all__ = ["MjcfRoundTrip", "mjcf_round_trip", "mujoco_inverse"]


@dataclass(frozen=True)
class MjcfRoundTrip:
    """The comparison of MuJoCo on the written MJCF with the calibrated model (module docstring).

    Attributes
    ----------
    max_rel_error : float
        max |mj_inverse - model| / max |model| with MuJoCo's constraints off (target <= 1e-9).
    friction_excess : float
        Largest ``|f_j| / fc_j - 1`` of the friction-loss force ``f`` (constraints on minus off) over the joints
        with friction: <= 0 up to rounding when MuJoCo's friction loss is bounded by ``fc``.
    friction_saturated : float
        Fraction of the sliding samples (``|qd_j| > 10 v``) at which ``f_j`` is ``fc_j sign(qd_j)`` to 1e-6
        (relative): the model's Coulomb level there.
    n_samples : int
    """

    max_rel_error: float
    friction_excess: float
    friction_saturated: float
    n_samples: int


def mujoco_inverse(mj_model, q, qd, qdd, constraints: bool) -> np.ndarray:
    """``qfrc_inverse`` of MuJoCo per sample, shape (n_samples, nv), with its constraints enabled or disabled."""
    route_mujoco_warnings()
    flags = mj_model.opt.disableflags
    if not constraints:
        mj_model.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    try:
        data = mujoco.MjData(mj_model)
        out = np.empty((len(q), mj_model.nv))
        for k, (qk, qdk, qddk) in enumerate(zip(q, qd, qdd)):
            data.qpos[:], data.qvel[:], data.qacc[:] = qk, qdk, qddk
            mujoco.mj_inverse(mj_model, data)
            out[k] = data.qfrc_inverse
    finally:
        mj_model.opt.disableflags = flags
    return out


def _held_part(calibrated):
    """A copy of the model without what MJCF does not hold as a torque: Coulomb, Stribeck, offsets, other findings."""
    document = copy.deepcopy(calibrated.document)
    drive = document["drive"]
    drive["values"] = [0.0 if name.rstrip("0123456789") in ("fc", "fs", "offset") else value
                       for name, value in zip(drive["names"], drive["values"])]  # fmt: skip
    document["findings"] = [entry for entry in document.get("findings") or [] if entry.get("kind") == "torque"
                            and is_linear_spring(FindingTerm.from_dict(entry.get("term") or {}))]  # fmt: skip
    lugre = drive.pop("lugre", None)
    drive.pop("viscous_exponent", None)  # MJCF's damping is linear: the round trip compares the linear part
    return type(calibrated)(document), lugre


def mjcf_round_trip(calibrated, model, text: str, q, qd, qdd) -> MjcfRoundTrip:
    """Compare ``mj_inverse`` on the MJCF ``text`` with the calibrated model on the samples (module docstring).

    Parameters
    ----------
    calibrated : CalibratedModel
    model : PSDMModel
        The derived model of the calibrated model's robot.
    text : str
        The MJCF written by ``export_mjcf`` / ``render_mjcf``.
    q, qd, qdd : array, shape (n_samples, n_dof)
        States within the joint ranges (MuJoCo's joint limits are constraints).
    """
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    mj_model = compile_mjcf(text, "the written MJCF")  # MuJoCo's compiler, without mesh files (not dynamics)
    held, lugre = _held_part(calibrated)
    expected = held.predict(model, q, qd, qdd)
    if lugre is not None:
        fv = np.array([0.0 if v is None else v for v in lugre["fv"]])  # null: a mixed model's steady-state joint
        expected = expected + fv * qd
    free = mujoco_inverse(mj_model, q, qd, qdd, constraints=False)
    error = float(np.abs(free - expected).max() / max(np.abs(expected).max(), 1e-300))
    friction = mujoco_inverse(mj_model, q, qd, qdd, constraints=True) - free
    fc = np.asarray(mj_model.dof_frictionloss, dtype=float)
    has = fc > 0
    excess = float((np.abs(friction[:, has]) / fc[has] - 1.0).max()) if has.any() else 0.0
    sliding = (np.abs(qd) > 10 * calibrated.coulomb_widths) & has  # per joint
    level = np.abs(friction - fc * np.sign(qd)) <= 1e-6 * np.maximum(fc, 1e-12)
    saturated = float(level[sliding].mean()) if sliding.any() else float("nan")
    return MjcfRoundTrip(error, excess, saturated, len(q))
