"""Which friction the model keeps where the friction changed between the training recordings, and the training
torques moved to it, so the rigid body is fitted beside each recording's own friction.

``friction_drift`` names the joints whose friction changed between the recordings. The data decide the friction the
model keeps on each (``FrictionDrift.kept``):

- where the recording files log the joints' temperatures and these explain the drift (``temperature_law``), the
  friction of the joint's law in temperature at the held-out recordings' temperature (kept where it predicts them no
  worse than the best recording's friction, else that friction, with both RMSE said), else at the latest recording's;
- else, with held-out recordings, the training recording whose friction (beside the check's shared rigid body)
  predicts the held-out torque of that joint best: the conditions the model will be used in (a warm arm, today's
  wear);
- without them, the latest training recording (the recordings' order as given: pass them oldest first), the arm as
  it is now.

Before the fit, each drifting joint's torque in each training recording is moved by the check's friction difference
``D_j(qd) (b_r - b_kept)`` (``drift_correction``, which the model file records so that a refit repeats it):
the shared fit then sees one friction per joint, the kept one, and the rigid body the per-recording fit found, not a
compromise that absorbs the drift. ``mode`` ``"report"`` names the drift and fits as before; ``"off"`` skips the check.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from identification.calibration.drift_correction import DriftCorrection, JointShift
from identification.calibration.friction_drift import DriftCheck, check_friction_drift, finite_list, recording_names
from identification.calibration.temperature_law import TemperatureLaw, temperature_law
from identification.calibration.trajectory_data import drive_columns, prepare_recording
from psdm_casadi.errors import ParameterError

__all__ = ["DRIFT_MODES", "FrictionDrift", "KeptFriction", "check_drift_mode", "judge_friction_drift"]

#: ``--friction-drift``: auto (name it and fit beside it), report (name it only), off (no check).
DRIFT_MODES = ("auto", "report", "off")
#: What to do next, said with a named drift.
NEXT_STEP = (
    "warm the robot up before recording (run its exciting motion until the joints' friction settles, tens of "
    "minutes for a cold gearbox) or record at the temperature it works at, and identify on recordings taken in the "
    "conditions the model will be used in"
)


def check_drift_mode(mode: str) -> None:
    if mode not in DRIFT_MODES:
        raise ParameterError(f"friction_drift must be one of {DRIFT_MODES}; got {mode!r}.")


@dataclass(frozen=True)
class KeptFriction:
    """The friction the model keeps on a drifting joint: its coefficients ``values`` (as ``JointFriction.names``),
    ``source`` (a recording's name, or ``at 38.2 °C``), ``basis`` (``"temperature"``, ``"held-out"``, ``"latest"``),
    the held-out RMSE [N m] of each recording's friction (``held_out_rmse``, empty without held-out recordings) and
    the law in temperature (``law``, or None) read at ``at`` (the held-out recordings' temperature or the latest
    recording's)."""

    joint: int
    values: np.ndarray
    source: str
    basis: str
    held_out_rmse: tuple = ()
    law: TemperatureLaw | None = None
    at: str = ""
    law_rmse: float | None = None

    def reason(self) -> str:
        if self.basis == "temperature":
            slopes = ", ".join(f"{v:+.3g}/°C" for v in self.law.slopes)
            return (f"from its friction's straight line in the logged temperature ({slopes}) at {self.at} temperature"
                    + (" (clamped to the training range's reach)" if self.law.clamped else ""))  # fmt: skip
        if self.basis == "held-out" and self.law_rmse is not None:
            return (f"its friction predicts the held-out recordings best on that joint ({min(self.held_out_rmse):.3g} "
                    f"N m; its line in the logged temperature: {self.law_rmse:.3g} N m, not kept)")  # fmt: skip
        if self.basis == "held-out":
            return "its friction predicts the held-out recordings best on that joint"
        return "the latest training recording, in the order given"


@dataclass(frozen=True, eq=False)
class FrictionDrift:
    """What identify found and decided about friction that changed between the training recordings.

    ``check`` the per-recording fit (``friction_drift``); ``kept`` the friction the model keeps on each drifting
    joint (``KeptFriction``); ``temperatures`` each training recording's logged mean temperature per joint (empty:
    none logged); ``corrected`` whether the fit saw the torques moved to the kept friction (``mode`` ``"auto"``) by
    ``correction`` (``drift_correction``: what a refit of the model file repeats; None without a named drift)."""

    mode: str = "auto"
    check: DriftCheck = field(default_factory=DriftCheck)
    kept: tuple = ()
    temperatures: tuple = ()
    corrected: bool = False
    correction: DriftCorrection | None = None

    @property
    def named(self) -> bool:
        return bool(self.check.drifting)

    def describe(self) -> str:
        """The drift per joint with each recording's friction, what the model keeps and why, the next step (lines);
        or why there is none (``""`` when off or with one recording)."""
        names = self.check.recordings
        if self.mode == "off" or len(names) < 2:
            return ""
        if self.check.reason:
            return f"friction drift: not checked ({self.check.reason})"
        if not self.named:
            return (f"friction drift: none between the {len(names)} training recordings: each joint's friction per "
                    "recording agrees within its uncertainty and the scatter of its parts")  # fmt: skip
        joints = [f.drift and f"  {f.sentence()}{self._temperatures(f.joint)}" for f in self.check.joints]
        logged = "their joints' temperatures logged" if self.temperatures else "no temperature logged"
        lines = [f"FRICTION DRIFT between the training recordings ({' -> '.join(names)}, in the order given; "
                 f"{logged}), beyond noise and estimation uncertainty:", *filter(None, joints)]  # fmt: skip
        groups: dict = {}
        for kept in self.kept:
            groups.setdefault((kept.source, kept.reason()), []).append(str(kept.joint + 1))
        for (source, reason), joints in groups.items():
            what = f"{source}'s friction" if source in names else f"the friction {source}"
            lines.append(f"  the model keeps {what} on joint(s) {', '.join(joints)} ({reason})")
        lines.append("  its rigid body fitted beside each recording's own friction (the drifting joints' training "
                     "torques moved to the kept friction), so the drift does not leak into the inertial parameters"
                     if self.corrected else "  fitted with one friction over every recording (friction drift: "
                     "report)")  # fmt: skip
        if self.corrected and any(kept.basis == "temperature" for kept in self.kept):
            lines.append("  the model file keeps each line's slopes (drive.temperature): validate, diagnose and "
                         "the exported inverse_dynamics_at_temperature read the friction at the joints' "
                         "temperature")  # fmt: skip
        lines.append(f"  next: {NEXT_STEP}")
        return "\n".join(lines)

    def _temperatures(self, joint: int) -> str:
        if not self.temperatures:
            return ""
        return f"; logged at {' -> '.join(f'{t[joint]:.1f}' for t in self.temperatures)} °C"

    def to_dict(self) -> dict:
        names = list(self.check.recordings)
        return {
            "mode": self.mode,
            "checked": not self.check.reason and len(names) > 1 and self.mode != "off",
            "reason": self.check.reason,
            "recordings": names,
            "order": "as given",
            "temperatures_c": [t.tolist() for t in self.temperatures],
            "named": [f.joint + 1 for f in self.check.drifting],
            "joints": [f.to_dict(names) for f in self.check.joints],
            "kept": [_kept_dict(k, self.check) for k in self.kept],
            "corrected": self.corrected,
            "correction": None if self.correction is None else self.correction.to_dict(),
            "next_step": NEXT_STEP if self.named else "",
        }


def _kept_dict(kept: KeptFriction, check: DriftCheck) -> dict:
    names = next(f.names for f in check.drifting if f.joint == kept.joint)
    return {"joint": kept.joint + 1, "source": kept.source, "basis": kept.basis, "reason": kept.reason(),
            "values": dict(zip(names, finite_list(kept.values))),
            "held_out_rmse": dict(zip(check.recordings, finite_list(kept.held_out_rmse))),
            "temperature_law": None if kept.law is None else kept.law.to_dict(names)}  # fmt: skip


def judge_friction_drift(robot, model, recordings, fit, validation=(), configurations=None, mode: str = "auto",
                         kt=None, temperatures=None) -> tuple:  # fmt: skip
    """``(training recordings for the fit, FrictionDrift)``: the check (``friction_drift``) with the shape of
    ``fit``, the friction kept on each drifting joint, and with ``mode`` ``"auto"`` the recordings with those joints'
    torques moved to it (module docstring); the recordings unchanged otherwise. ``temperatures``: ``(per training
    recording, per held-out recording)`` mean temperatures per joint [°C] (``data.temperature``; None where a file
    logs none)."""
    check_drift_mode(mode)
    recordings = list(recordings)
    if mode == "off" or len(recordings) < 2:
        return recordings, FrictionDrift(mode=mode, check=DriftCheck(recordings=recording_names(recordings)))
    check = check_friction_drift(robot, model, recordings, fit, configurations)
    training, held_out = temperatures if temperatures is not None else ((), ())
    logged = tuple(np.asarray(t, dtype=float) for t in training) if _all_logged(training, len(recordings)) else ()
    if not check.drifting:
        return recordings, FrictionDrift(mode=mode, check=check, temperatures=logged)
    rmse = _held_out_parts(model, check, validation, kt, fit)
    target = np.mean(held_out, axis=0) if _all_logged(held_out, len(validation)) and validation else None
    kept = tuple(_kept(friction, k, check, rmse, logged, target) for k, friction in enumerate(check.drifting))
    drift = FrictionDrift(mode, check, kept, logged, corrected=mode == "auto", correction=_correction(check, kept))
    if mode != "auto":
        return recordings, drift
    return [drift.correction.moved(raw, k, kt, check.motions[k]) for k, raw in enumerate(recordings)], drift


def _all_logged(temperatures, count: int) -> bool:
    return count > 0 and len(temperatures or ()) == count and all(t is not None for t in temperatures)


def _kept(friction, k: int, check: DriftCheck, parts, logged, target) -> KeptFriction:
    """The friction kept on one drifting joint (module docstring): the law in temperature (with held-out recordings,
    where it predicts them no worse than the best recording's friction), else the held-out recordings' best, else the
    latest recording's."""
    j, names = friction.joint, check.recordings
    present = [r for r in range(len(names)) if np.all(np.isfinite(friction.values[r]))]
    held = () if parts is None else tuple(_rmse(parts[k], v) if r in present else float("inf")
                                          for r, v in enumerate(friction.values))  # fmt: skip
    law, refused = None, None
    if logged:
        at = float(target[j]) if target is not None else float(logged[present[-1]][j])
        law = temperature_law(friction.values[present], friction.stds[present], [logged[r][j] for r in present], at)
        if law is not None and held and (refused := _rmse(parts[k], law.values)) > min(held) * (1 + 1e-9):
            law = None  # the line read there predicts the held-out recordings worse than a recording's friction
        elif law is not None:
            where = "the held-out recordings'" if target is not None else "the latest recording's"
            return KeptFriction(j, law.values, f"at {law.target:.1f} °C", "temperature", held, law, where)
    if held:
        best = int(np.argmin(held))
        return KeptFriction(j, friction.values[best], names[best], "held-out", held, law_rmse=refused)
    return KeptFriction(j, friction.values[present[-1]], names[present[-1]], "latest")


def _correction(check: DriftCheck, kept) -> DriftCorrection:
    """The correction to the ``kept`` friction in the check's shape and preparation (``drift_correction``)."""
    terms, _, velocity, vs, dv = check.shape
    own = {f.joint: f.values for f in check.drifting}
    joints = tuple(JointShift(k.joint, next(f.names for f in check.drifting if f.joint == k.joint), own[k.joint],
                              np.asarray(k.values, dtype=float)) for k in kept)  # fmt: skip
    stribeck = None if vs is None or "fs" not in terms else tuple(map(float, vs))  # as ``drive_columns`` reads it
    return DriftCorrection(check.recordings, joints, float(velocity), stribeck,
                           None if dv is None else tuple(map(float, dv)), *check.preparation)  # fmt: skip


def _friction(check: DriftCheck, qd, qdd) -> np.ndarray:
    """The drive columns of the check's shape (n_samples, n_dof, drive columns)."""
    terms, inertia, velocity, vs, dv = check.shape
    return drive_columns(qd, qdd, terms, inertia, velocity, vs, dv)


def _held_out_parts(model, check: DriftCheck, validation, kt, fit):
    """Per drifting joint ``(measured torque, the check's rigid body and shared columns, the joint's own friction
    columns)`` over the held-out recordings' measured samples, so that any friction of that joint is judged there
    (``_rmse``); None without held-out recordings."""
    if not validation:
        return None
    n_base, shared = check.layout["n_base"], check.layout["shared"]
    parts = [([], [], []) for _ in check.drifting]
    cutoff = min(fit.cutoff_hz) if fit.cutoff_hz else None
    for recording in validation:
        ready = prepare_recording(recording, kt, cutoff, fit.edge_periods)[0]
        drive = _friction(check, ready.qd, ready.qdd)
        common = model.regressor(ready.q, ready.qd, ready.qdd) @ check.x[:n_base] + drive[:, :, shared] @ check.x[
            n_base : n_base + len(shared)]  # fmt: skip
        for k, friction in enumerate(check.drifting):
            j, columns = friction.joint, check.layout["per_joint"][friction.joint]
            measured = np.isfinite(ready.tau[:, j])
            for part, values in zip(parts[k], (ready.tau[measured, j], common[measured, j],
                                                drive[measured][:, j][:, columns])):  # fmt: skip
                part.append(values)
    if not all(part[0] and sum(len(x) for x in part[0]) for part in parts):
        return None
    return [tuple(np.concatenate(x) for x in part) for part in parts]


def _rmse(part, values) -> float:
    """The held-out RMSE [N m] of one joint's friction ``values`` (``_held_out_parts``)."""
    tau, common, columns = part
    return float(np.sqrt(np.mean((tau - common - columns @ np.asarray(values, dtype=float)) ** 2)))
