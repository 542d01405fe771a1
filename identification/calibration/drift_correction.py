"""The training torques of the joints whose friction drifted between the recordings, moved to the friction the model
keeps: one correction for identify (before its fit) and for a refit of its model file (``diagnose --apply``).

``drift_choice`` names the drifting joints and the friction kept on each. Recording ``r``'s torque on drifting joint
``j`` is moved by ``D_j(qd) (b_r - b_kept)``: ``D_j`` the joint's friction columns in the shape the check fitted
(``trajectory_data.friction_term``: Coulomb smoothing, Stribeck velocity, viscous exponent) along the recording's
prepared motion (filtered at the check's cutoff, its edges trimmed), interpolated onto the recording's own samples; a
recording of currents by ``1 / kt``. The model file records it all (``identification.friction_drift.correction``), so a
refit of the file on its own training recordings, read again raw from disk, trains on the torques identify trained
on, not on the drift identify kept out of the rigid body. A file written before the correction was recorded has none:
its refit cannot repeat it (``refit_training`` says so).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from identification.calibration.coulomb_width import joint_width, positive_widths
from identification.calibration.friction_drift import finite_list
from identification.calibration.trajectory_data import friction_term, prepare_recording

__all__ = ["DriftCorrection", "JointShift"]


@dataclass(frozen=True)
class JointShift:
    """One drifting joint (0-based ``joint``): its friction coefficients ``names`` (``fc3``, ``fv3``, ...), each
    training recording's ``own`` values (recordings, coefficients; NaN for a recording that does not measure it) and
    the ``kept`` ones."""

    joint: int
    names: tuple
    own: np.ndarray
    kept: np.ndarray


@dataclass(frozen=True, eq=False)
class DriftCorrection:
    """The correction of the training ``recordings`` (their names, in the order identify was given them) on the
    ``joints`` (``JointShift``), in the check's friction shape (``coulomb_velocity``, one or one per joint;
    ``stribeck_velocity`` and ``viscous_exponent`` per joint, or None) along the motion prepared at ``cutoff_hz`` with
    ``edge_periods`` trimmed (module docstring)."""

    recordings: tuple
    joints: tuple
    coulomb_velocity: float | tuple
    stribeck_velocity: tuple | None
    viscous_exponent: tuple | None
    cutoff_hz: float | None
    edge_periods: float

    def index(self, name) -> int | None:
        """The position of the training recording ``name``; None where it is not one, or not told apart by name."""
        return self.recordings.index(name) if list(self.recordings).count(name) == 1 else None

    def shift(self, index: int, qd) -> np.ndarray:
        """(n_samples, n_dof) [N m]: the torque recording ``index`` carries beyond the kept friction along the joint
        velocities ``qd`` (0 on the joints that do not drift, and where it does not measure a joint)."""
        qd = np.asarray(qd, dtype=float)
        out = np.zeros_like(qd)
        for shift in self.joints:
            own = shift.own[index]
            if not np.all(np.isfinite(own)):
                continue  # a recording that does not measure this joint's torque
            out[:, shift.joint] = self.columns(shift, qd) @ (own - shift.kept)
        return out

    def columns(self, shift: JointShift, qd) -> np.ndarray:
        """(n_samples, len(shift.names)): the drifting joint's friction columns in the check's shape along the joint
        velocities ``qd`` (n_samples, n_dof) [rad/s]."""
        j = shift.joint
        vs = None if self.stribeck_velocity is None else float(self.stribeck_velocity[j])
        dv = None if self.viscous_exponent is None else float(self.viscous_exponent[j])
        qd = np.asarray(qd, dtype=float)
        v = joint_width(self.coulomb_velocity, j)
        return np.column_stack([friction_term(name.rstrip("0123456789"), qd[:, j], v, vs, dv)
                                for name in shift.names])  # fmt: skip

    def with_recording(self, name: str, own) -> DriftCorrection:
        """This correction with one more training recording ``name`` whose friction on each drifting joint is
        ``own`` (one row per ``joints`` entry, as ``JointShift.names``; NaN where it does not measure the joint):
        a recording identify did not see, its friction fitted beside the model (``new_recording_drift``)."""
        joints = tuple(dataclasses.replace(s, own=np.vstack([s.own, np.asarray(row, dtype=float)[None, :]]))
                       for s, row in zip(self.joints, own))  # fmt: skip
        return dataclasses.replace(self, recordings=(*self.recordings, name), joints=joints)

    def moved(self, raw, index: int, kt=None, motion=None):
        """``raw``, the training recording ``index``, with each drifting joint's torque moved to the kept friction (in
        its own signal: a current over ``kt``). ``motion``: its prepared ``(t, qd, qdd)`` where the caller has it
        (identify's check), else prepared here as the check prepared it."""
        if motion is None:
            ready = prepare_recording(raw, kt, self.cutoff_hz, self.edge_periods)[0]
            motion = (ready.t, ready.qd, ready.qdd)
        t, qd, _ = motion
        change = self.shift(index, qd)
        delta = np.column_stack([np.interp(raw.t, t, change[:, j]) for j in range(raw.n_dof)])
        if raw.tau is not None:
            return raw.with_tau(raw.tau - delta)
        return raw.with_signals(current=raw.current - delta / np.asarray(kt, dtype=float))

    def to_dict(self) -> dict:
        return {
            "recordings": list(self.recordings),
            "joints": [
                {
                    "joint": s.joint + 1,
                    "names": list(s.names),
                    "own": [finite_list(v) for v in s.own],
                    "kept": finite_list(s.kept),
                }
                for s in self.joints
            ],  # fmt: skip
            "coulomb_velocity": self.coulomb_velocity,
            "stribeck_velocity": None if self.stribeck_velocity is None else list(self.stribeck_velocity),
            "viscous_exponent": None if self.viscous_exponent is None else list(self.viscous_exponent),
            "cutoff_hz": self.cutoff_hz,
            "edge_periods": self.edge_periods,
        }

    @classmethod
    def from_dict(cls, data) -> DriftCorrection | None:
        """The correction a model file records (``to_dict``); None where it records none (a file written before it
        was recorded)."""
        if not isinstance(data, dict) or not data.get("joints"):
            return None
        joints = tuple(JointShift(int(s["joint"]) - 1, tuple(s["names"]), _array(s["own"]), _array(s["kept"]))
                       for s in data["joints"])  # fmt: skip
        vs, dv = data.get("stribeck_velocity"), data.get("viscous_exponent")
        cutoff = data.get("cutoff_hz")
        width = positive_widths(data["coulomb_velocity"], "identification.friction_drift.correction.coulomb_velocity")
        return cls(tuple(data["recordings"]), joints, width,
                   None if vs is None else tuple(map(float, vs)), None if dv is None else tuple(map(float, dv)),
                   None if cutoff is None else float(cutoff), float(data["edge_periods"]))  # fmt: skip


def _array(values) -> np.ndarray:
    return np.array([[np.nan if v is None else v for v in row] if isinstance(row, list) else
                     (np.nan if row is None else row) for row in values], dtype=float)  # fmt: skip
