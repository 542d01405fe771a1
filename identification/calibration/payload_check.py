"""A payload the calibrated model does not have, in new recordings: the residual regressed on a flange body.

A calibrated arm recorded again with a tool, a gripper or a part in its hand shows a residual that is the
load's own torque: the columns of a body fixed to the flange (``payload_fit.FlangeRegressor``) times its
10 inertial parameters. :func:`new_payload` fits them to the residual of the model's prediction (each joint
weighted by its residual variance) and names the load when it explains much of the residual with a mass
many standard deviations above zero. ``psdm validate`` reports it beside the RMSE, so that a worse validation is
read as "carries 2.5 kg" rather than as a worse model.

Its standard deviations hold two parts. The noise's: each joint's residual variance grown by its correlation time
(``residual_correlation.residual_correlation_time``: the recording is filtered and oversampled, so the samples are
not independent). And the model's own: the residual is the load's torque plus the calibrated arm's estimation
error, which the flange body takes up in part; the covariance of the model's base and drive parameters the file
states (``parameter_covariance``) is propagated through the flange fit. A file written before that block has only
their standard deviations, propagated as if independent, which states that part too wide (the parameters of one
fit are correlated, and their errors partly cancel in the torque). On the virtual Denso calibrated on two 8 s
recordings (5 calibrations x 6 validation recordings with a 0.8 kg load) the noise alone held the truth within 2
standard deviations in 20 of 30 (RMS z 1.74); with the model's part from the standard deviations 30 of 30 but RMS z
0.72, from the covariance 30 of 30 with RMS z 0.94 (``test_payload_check_coverage``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from identification.calibration.model_preparation import model_preparation
from identification.calibration.parameter_covariance import stated_covariance
from identification.calibration.payload_fit import Estimable, FlangeRegressor
from identification.calibration.residual_correlation import residual_correlation_time
from identification.calibration.trajectory_data import choose_filter, drive_columns, file_shape
from identification.data.preprocessing import central_difference, resample_uniform, zero_phase_filter
from identification.data.recording import Recording
from identification.metrics import r2, rmse

__all__ = ["MIN_DROP", "MIN_Z", "NewPayload", "model_columns", "new_payload", "validation_with_payload", "without_load"]

MIN_DROP = 0.2  # the flange body must remove this fraction of the weighted residual
MIN_Z = 5.0  # and its mass be this many (correlation-grown) standard deviations above zero


@dataclass(frozen=True)
class NewPayload:
    """The load a recording appears to carry beyond the model's arm: mass [kg], centre of mass in the flange
    frame [m], their standard deviations, and the fraction of the weighted residual it explains; ``parameters`` its
    10 inertial parameters about the flange origin as fitted and ``covariance`` theirs (10 x 10), which judge whether
    it is a body at all (``held_out_load``)."""

    recording: str
    mass: float
    mass_std: float
    com: tuple
    com_std: tuple
    residual_drop: float
    parameters: np.ndarray = field(default_factory=lambda: np.full(10, np.nan), repr=False, compare=False)
    covariance: np.ndarray = field(default_factory=lambda: np.full((10, 10), np.nan), repr=False, compare=False)

    def to_dict(self) -> dict:
        return {"recording": self.recording, "mass": self.mass, "mass_std": self.mass_std, "com": list(self.com),
                "com_std": list(self.com_std), "residual_drop": self.residual_drop}  # fmt: skip

    def sentence(self) -> str:
        """One line for the command's output, with the fix."""
        com = ", ".join(f"{v:.3f}" for v in self.com)
        return (f"{self.recording} appears to carry {self.mass:.3g} +- {self.mass_std:.2g} kg at the flange (centre "
                f"of mass [{com}] m in the flange frame) that the model does not have: the load explains "
                f"{100 * self.residual_drop:.0f} % of the residual. If the arm carried it, identify with it "
                '(a sidecar {"unknown": "tool"} beside the recording, or its known mass).')  # fmt: skip


def model_columns(calibrated, model, prepared) -> tuple:
    """(columns (samples, joints, k), covariance (k, k)) of a calibrated model's own base and drive parameters on a
    prepared recording: the error of the model's prediction the flange check allows for (module docstring). The
    file's covariance (``parameter_covariance``), else its standard deviations as independent (a file written before
    it); a parameter without a stated one (NaN: not estimated) adds none."""
    drive = calibrated.document["drive"]
    own = drive_columns(prepared.qd, prepared.qdd, tuple(drive["friction_terms"]),
                        tuple(j - 1 for j in drive["inertia_joints"]), calibrated.coulomb_widths,
                        *file_shape(drive))  # fmt: skip
    columns = np.concatenate([model.regressor(prepared.q, prepared.qd, prepared.qdd), own], axis=2)
    std = np.concatenate([calibrated.document["base"].get("std", []), drive.get("std", [])]).astype(float)
    if std.shape != (columns.shape[2],):  # a file that does not state them all: no allowance
        return columns[:, :, :0], np.zeros((0, 0))
    covariance = stated_covariance(calibrated.document, std.size)
    return columns, np.diag(np.nan_to_num(std, nan=0.0) ** 2) if covariance is None else covariance


def new_payload(robot, prepared, predicted, name: str | None = None, own=None) -> NewPayload | None:
    """The :class:`NewPayload` a prepared recording appears to carry beyond ``predicted`` (the model's torques on
    its samples), or None when the residual does not show one (module docstring). ``own``: the model's own columns
    and their covariance (:func:`model_columns`), allowed for in the load's; None: the noise's alone."""
    residual = np.asarray(prepared.tau, dtype=float) - np.asarray(predicted, dtype=float)
    measured = np.all(np.isfinite(residual), axis=0)  # a joint without torque (NaN): no weight
    residual = np.where(measured, residual, 0.0)
    columns = FlangeRegressor(robot)(prepared.q, prepared.qd, prepared.qdd)  # (samples, joints, 10)
    weights = np.where(measured, 1.0 / np.maximum(residual.var(axis=0), 1e-300), 0.0)
    gram = np.einsum("n,snc,snd->cd", weights, columns, columns)
    moment = np.einsum("n,snc,sn->c", weights, columns, residual)
    estimable = Estimable(gram)
    if not estimable.unit(0):
        return None
    scale = np.sqrt(np.clip(np.diag(gram), 1e-300, None))
    inverse = np.linalg.pinv(gram / np.outer(scale, scale), rcond=1e-12, hermitian=True) / np.outer(scale, scale)
    x = inverse @ moment
    drop = float(moment @ x) / float(np.einsum("n,sn,sn->", weights, residual, residual))
    after = residual - columns @ x
    full = _covariance(inverse, columns, weights, after, np.linalg.matrix_rank(gram), own)
    covariance = full[:4, :4]
    mass, mass_std = float(x[0]), float(np.sqrt(max(covariance[0, 0], 0.0)))
    if not (drop > MIN_DROP and mass > MIN_Z * mass_std):
        return None
    com = x[1:4] / mass
    com_std = []
    for axis in range(3):  # delta method: d(h/m) = dh/m - h dm/m^2
        gradient = np.zeros(4)
        gradient[0], gradient[1 + axis] = -x[1 + axis] / mass**2, 1.0 / mass
        com_std.append(float(np.sqrt(max(gradient @ covariance @ gradient, 0.0))))
    label = name or prepared.name or "the recording"
    return NewPayload(label, mass, mass_std, tuple(float(v) for v in com), tuple(com_std), drop, x, full)


def _covariance(inverse, columns, weights, after, rank, own) -> np.ndarray:
    """Of the flange body's weighted fit: the noise's part (each joint's residual variance ``after`` grown by its
    correlation time) plus, with ``own``, the model's parameters' propagated through the fit (module docstring)."""
    dof = max(after.shape[0] - rank / after.shape[1], 1.0)  # per joint: its share of the fitted parameters
    noise = np.einsum("sn,sn->n", after, after) / dof * residual_correlation_time(after)
    covariance = inverse @ np.einsum("n,snc,snd->cd", weights**2 * noise, columns, columns) @ inverse
    if own is not None and len(own[1]):
        gain = inverse @ np.einsum("n,snc,snd->cd", weights, columns, np.asarray(own[0], dtype=float))
        covariance = covariance + gain @ np.asarray(own[1], dtype=float) @ gain.T
    return covariance


def validation_with_payload(robot, calibrated, model, recording, kt=None, payload=None) -> tuple:
    """(RMSE, R^2, prepared recording, prediction) of a calibrated model on a raw recording that carries
    ``payload`` (10 inertial parameters about the flange, or None): the model's prediction
    (``CalibratedModel.predict_recording``, as ``psdm validate``) plus the load's torque.

    The load's torque is the one :func:`without_load` takes off the raw recording, as the preparation passes it: the
    one path of every command that judges a model on a loaded recording (``psdm validate``, identify's report and
    ``psdm diagnose MODEL``, which diagnoses the arm's torque ``without_load`` leaves). A load evaluated on the prepared
    positions instead, as this did, skips the preparation's filter that the diagnosis's load passes, and the two
    commands gave two errors of the same model on the same held-out part (a cobot's joint 2: 0.3071 and 0.3053 N m).
    """
    prepared, predicted = calibrated.predict_recording(model, recording, kt)
    if payload is not None:
        cutoff = model_preparation(calibrated.document).cutoff_hz
        arm, _ = calibrated.predict_recording(model, without_load(robot, recording, payload, kt, cutoff), kt)
        predicted = predicted + (prepared.tau - arm.tau)  # the load's torque, prepared as the recorded torque is
    return rmse(prepared.tau, predicted), r2(prepared.tau, predicted), prepared, predicted


def without_load(robot, recording, body, kt=None, cutoff_hz=None) -> Recording:
    """A raw recording with the torque of a load it states (``body``: 10 inertial parameters about the flange, the
    flange-body columns of :class:`payload_fit.FlangeRegressor`) taken off its joint torque: the arm's own torque,
    for a diagnosis of the arm and its refit (``psdm diagnose MODEL`` on recordings with a payload sidecar).

    The load's torque is evaluated at the full rate on the positions filtered as the identification filters them
    (``trajectory_data.choose_filter`` at ``cutoff_hz``) and their central differences: a smooth torque, which the
    preparation's filter then passes as it passes the recorded one. ``kt`` converts a recording of currents.
    """
    rec = recording if recording.is_uniform(1e-6) else resample_uniform(recording)
    rate = 1.0 / rec.dt
    cutoff, _ = choose_filter(rate, cutoff_hz)
    q = zero_phase_filter(rec.q, rate, cutoff)
    qd, qdd = central_difference(rec.t, q)
    load = FlangeRegressor(robot)(q, qd, qdd) @ np.asarray(body, dtype=float)
    return Recording(t=rec.t, q=rec.q, tau=rec.joint_torque(kt) - load, name=rec.name)
