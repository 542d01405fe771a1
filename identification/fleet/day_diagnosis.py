"""The diagnosis of a robot-day whose validation error rose unexplained (``day_check``), inside its own task.

It runs the project's diagnosis (:func:`identification.diagnosis.diagnose`) on the day's prepared recordings,
relative to the day's own model: the measured torque (the refitted torque constants times the currents) minus the
refitted tracked terms (springs, ripples, offsets, payload: what the fleet already follows) and with the held rigid
body in place of the robot file's (``Y (theta_held - theta_file)`` subtracted, so that the diagnosis's prior, the
robot file's rigid body, is the baseline's). The diagnosis refits friction (Coulomb + viscous, the daily update's
shape) and looks for what is still missing, not among the friction shapes a Coulomb-viscous model lacks (a Stribeck
peak, smooth Coulomb, pre-sliding: a robot's friction has them on every day, its baseline's too, so they are not what
changed on this one; ``DiagnosisOptions.friction_shapes``). With one recording its first half trains and its second half
validates; with several, the first trains and the others validate.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from identification.fleet.baseline import FRICTION, Baseline
from identification.fleet.update import CHUNK, DayFit, refit_columns, uncached

__all__ = ["DayFinding", "diagnose_day", "residual_recordings"]


@dataclass(frozen=True)
class DayFinding:
    """A missing effect the diagnosis named on a robot-day: its key (``torque_offset``, ``spring``, ...), label,
    joints (1-based), physical parameters, validation gain (fraction of its joint's RMSE removed) and sentence."""

    effect: str
    label: str
    joints: tuple
    parameters: dict
    gain: float
    text: str


def _tracked_torque(baseline: Baseline, model, rec, fit: DayFit) -> np.ndarray:
    """The refitted tracked terms' torque and the held rigid body's difference from the robot file's, in chunks."""
    values = dict(zip(fit.names, fit.values))
    theta_file = model.base_parameters(baseline.robot.nominal_dynamic_parameters())
    delta = baseline.theta - theta_file
    out = np.empty_like(rec.tau)
    for start in range(0, rec.n_samples, CHUNK):
        part = slice(start, start + CHUNK)
        names, _, columns = refit_columns(baseline, rec.q[part], rec.qd[part], rec.qdd[part])
        x = np.array([0.0 if name.rstrip("0123456789") in FRICTION else values[name] for name in names])
        out[part] = columns @ x
        if np.any(delta):
            out[part] += model.inverse_dynamics(rec.q[part], rec.qd[part], rec.qdd[part], delta)
    return out


def residual_recordings(baseline: Baseline, model, prepared: list, currents: bool, fit: DayFit) -> list:
    """The day's prepared recordings with ``tau`` the joint torque the day's model leaves to friction and to what
    it does not model (module docstring)."""
    values = dict(zip(fit.names, fit.values))
    kt = np.array([values.get(f"kt{j + 1}", baseline.kt[j]) for j in range(baseline.robot.n_dof)])
    out = []
    with uncached(model):
        for rec in prepared:
            torque = rec.tau * kt if currents else rec.tau
            out.append(dataclasses.replace(rec, tau=torque - _tracked_torque(baseline, model, rec, fit)))
    return out


def _split(recordings: list) -> tuple:
    if len(recordings) > 1:
        return recordings[0], recordings[1:]
    rec = recordings[0]
    half = rec.n_samples // 2

    return rec.slice(0, half), [rec.slice(half, None)]  # every signal cut alike (currents and temperatures too)


def diagnose_day(baseline: Baseline, model, prepared: list, currents: bool, fit: DayFit) -> tuple:
    """The :class:`DayFinding` of the diagnosis of a robot-day (module docstring); may be empty."""
    from identification.diagnosis.diagnose import DiagnosisOptions, diagnose

    train, validation = _split(residual_recordings(baseline, model, prepared, currents, fit))
    rate = 1.0 / float(np.median(np.diff(train.t)))
    options = DiagnosisOptions(friction="coulomb_viscous", rigid_body="prior", preprocess=False, cutoff_hz=None,
                               rate_hz=rate, sparse=False, cv_folds=0, refine=False,
                               friction_shapes=False)  # fmt: skip
    report = diagnose(baseline.robot, train, validation, options, model=model)
    return tuple(
        DayFinding(
            f.effect,
            f.label,
            tuple(j + 1 for j in f.joints),
            {k: float(v) for k, v in f.parameters.items()},
            float(f.joint_gain()),
            f.sentence(),
        )  # fmt: skip
        for f in report.findings
    )
