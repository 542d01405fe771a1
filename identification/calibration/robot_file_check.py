"""Never worse than the robot file: identify's model judged per joint against the model it replaces.

A model ``psdm identify`` hands over replaces the robot file. The robot file alone states no friction (or a guess),
so the honest model it replaces is its rigid body with the friction a plain fit gives: the same drive columns as the
identified model (friction shape, the chosen torque offsets and drive inertias, the same Coulomb smoothing and
Stribeck velocities), fitted per joint by least squares on the training recordings with the file's rigid body held
(``file_friction``), bounded as identify bounds its own (``consistent_fit.drive_lower_bounds``: friction and drive
inertias >= 0, offsets free). Each joint's friction acts on that joint alone, so this is one small least squares per
joint. Unbounded, a joint that moves one way only in training let the fit trade Coulomb and viscous friction with the
offset into a friction identify's model cannot have (a negative viscous friction) and a baseline far worse than the
file alone on the held-out motion; bounded, zero friction stays feasible, so on the training recordings the baseline
is never worse than the file's rigid body alone.

training recordings (prepared as the fit prepares them) -> ``file_friction`` (the file's rigid body + friction)
-> on each held-out recording, both models' residuals on the same samples -> ``never_worse.JointComparison`` (the
never-worse margin of ``never_worse``: the paired difference's bootstrap standard error, never below its floor),
plus the estimation allowance -> ``FileCheck``: the joints on which the identified model is worse than the robot file
beyond that margin, with the numbers and what to do.

The estimation allowance (``estimation_allowance``): the identified model estimates the rigid body's base parameters
that the baseline takes from the file, so even an exact robot file is beaten by no identification: per joint, the
identified RMSE may exceed the baseline's ``b`` by ``sqrt(b^2 + v) - b``, ``v`` the variance of its rigid-body torque
on the held-out motion from the fit's covariance of the base parameters given the drive parameters, before the joint
is called worse (a fit without a covariance: ``sqrt(1 + p / N) - 1`` of ``b``). On the virtual Denso with the file as
the truth the identified model is over the never-worse margin alone on some joints and within both; a 2 N m error of
one joint's Coulomb friction is over both. The uniform rule it replaces allowed every joint of the Kinova Gen3 (trained
on 6.7 s) 39.5 %, which hid a joint 6 46 % worse than the file with friction fitted.

The baseline per joint is the best the robot file offers (``FileCheck.baselines``, ``BASELINE_RULE``): its rigid
body with the friction fitted, or the file alone where that predicts the held-out recordings better (a friction fitted
to a training motion on which the joint turns one way only can be worse than none where it reverses: the Kinova
trained on opti_traj_testing2, joint 1). The report and the model file say which.

A worse joint that moves one way only in training has its friction held to the robot file's fit and the model fitted
again (``one_way_friction``: the held-out recordings decide that hold, and the model file says so). A joint still
worse is held to what the robot file predicts there, its friction at its baseline's and then the links it carries at
the file's, where that leaves fewer joints worse and none new (``worse_joint_hold``; the held-out recordings decide
it, and the record says so). What is still worse after that is written and said, in the report and as a warning, with
the route to the cheaper model: ``psdm diagnose`` of the robot file fits its friction (and the physics it finds
missing) on the file's rigid body, and ``--apply`` writes it under the never-worse gate.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.consistent_fit import drive_lower_bounds
from identification.calibration.envelope_report import DIAGNOSE_COMMAND
from identification.calibration.estimation_allowance import (
    joint_allowance,
    prediction_variance,
    rigid_body_covariance,
    uniform_allowance,
)
from identification.calibration.never_worse import (
    MARGIN_FLOOR,
    JointComparison,
    paired_rmse_margin,
    pooled_comparison,
)
from identification.calibration.trajectory_checks import MIN_REVERSAL_FRACTION
from identification.calibration.trajectory_data import drive_column_joint, drive_columns, fit_shape
from identification.calibration.trajectory_fit import torque_constants
from identification.data.excitation_check import one_way_joints

__all__ = ["ALLOWANCE_RULES", "BASELINES", "BASELINE_RULE", "FileCheck", "FileFriction", "check_against_file",
           "file_friction", "joint_fits"]  # fmt: skip

#: The baseline per joint, stored (``FileCheck.baselines``) and said in the report.
BASELINES = {"friction": "the robot file's rigid body with its friction fitted", "alone": "the robot file alone"}
BASELINE_RULE = ("per joint the better of the robot file's rigid body with its friction fitted (friction and drive "
                 "inertias >= 0, offsets free, on the training recordings) and the robot file alone, by the RMSE on "
                 "the held-out recordings")  # fmt: skip
#: The stored rule of the estimation allowance, by whether the fit states its parameters' covariance.
ALLOWANCE_RULES = {
    True: "margin = never-worse margin + sqrt(b^2 + v) - b per joint [N m]: b the RMSE before, v the mean over the "
    "held-out samples of the identified torque's variance from the fit's parameter covariance",
    False: "margin = never-worse margin + (sqrt(1 + p / N) - 1) x RMSE before (the fit states no covariance)",
}


@dataclass(frozen=True, eq=False)
class FileFriction:
    """The robot file's rigid body with a plain friction fit: per joint the drive coefficients of its columns."""

    fit: object  # the identified TrajectoryFit whose drive columns are reused, or one per joint (``joint_fits``)
    coefficients: tuple  # per joint: (column indices, coefficients)

    def predict(self, oracle, q, qd, qdd) -> np.ndarray:
        """Joint torques [N m] of the file's rigid body plus this friction."""
        out = oracle.rnea(q, qd, qdd)
        columns = _joint_drive_columns(joint_fits(self.fit, out.shape[1]), qd, qdd)
        for j, (keep, x) in enumerate(self.coefficients):
            out[:, j] += columns[j][:, j, keep] @ x
        return out


@dataclass(frozen=True, eq=False)
class FileCheck:
    """The identified model against the robot file (with friction) on the held-out recordings, per joint.

    ``comparison`` pools the recordings (``never_worse.pooled_comparison``); ``before`` is the robot file with its
    friction fitted, ``after`` the identified model. It is None when the check was not made (``reason`` says why:
    no held-out recording, no links in the robot file, a payload the file does not carry).
    """

    comparison: JointComparison | None = None
    recordings: int = 0
    reason: str = ""
    each: tuple = ()  # one JointComparison per held-out recording (its ``before``: the robot file with friction)
    allowance: np.ndarray | None = None  # the estimation allowance per joint [N m] (part of ``comparison.margin``)
    parameters: int = 0  # p: the base parameters the identified model estimates and the baseline takes from the file
    samples: tuple = ()  # N per joint: its independent training samples (the uniform rule's, without a covariance)
    one_way: tuple = ()  # the joints (0-based) that move one way only in the training recordings
    from_covariance: bool = True  # the allowance from the fit's covariance (else the uniform sqrt(1 + p / N) - 1)
    held: tuple = ()  # the joints (0-based) whose friction identify held to the robot file's fit (``one_way_friction``)
    baselines: tuple = ()  # per joint, the baseline judged against: "friction" (fitted) or "alone" (``BASELINES``)
    held_links: tuple = ()  # the links (0-based) identify held at the robot file's (``worse_joint_hold``)
    carried: tuple = ()  # the joints (0-based) that keep ``default``'s verdict (``keeping_verdicts``)
    default: FileCheck | None = None  # the default model's check, whose verdict those joints keep
    trial: JointComparison | None = None  # this model against the default model, pooled over the held-out recordings

    @property
    def worse(self) -> tuple:
        """The joints (0-based) on which the identified model is worse than the robot file beyond the margin; on a
        joint of ``carried``, the default model's verdict (``keeping_verdicts``)."""
        if self.comparison is None:
            return ()
        kept = set(self.carried) & set(() if self.default is None else self.default.worse)
        return tuple(sorted({j for j in self.comparison.worse if j not in self.carried} | kept))

    def keeping_verdicts(self, default: FileCheck, trial: JointComparison, joints) -> FileCheck:
        """This check with ``joints`` (0-based) keeping the ``default`` model's verdict against the robot file: the
        joints this model (LuGre friction, ``lugre_trial``) predicts within the paired margin of the default model it
        replaces (``trial``: this model against that one). The two predict such a joint alike to the noise, and the
        default model's check is the one that judges it (``lugre_trial``'s rule); this check reads it through the file
        with the noise of both comparisons and, on a LuGre joint, a baseline of its own (the file with the Stribeck
        friction the LuGre fit starts from). The numbers of both are kept and said where the verdicts differ."""
        if self.comparison is None or default.comparison is None:
            return self
        return replace(self, carried=tuple(sorted(int(j) for j in joints)), default=default, trial=trial)

    def _carried_text(self) -> str:
        """Per carried joint whose own reading differs from the default model's verdict: both readings, and why the
        default model's is the verdict ("" where none differs)."""
        if self.default is None:
            return ""
        own, theirs = set(self.comparison.worse), set(self.default.worse)
        c, d, t = self.comparison, self.default.comparison, self.trial
        return "; ".join(
            f"joint {j + 1} keeps the default steady-state model's verdict ({'worse' if j in theirs else 'not worse'}: "
            f"{d.before[j]:.4g} -> {d.after[j]:.4g} N m, margin {d.margin[j]:.2g}), since this model predicts it as "
            f"that one does (within their paired margin: {t.before[j]:.4g} -> {t.after[j]:.4g} N m, margin "
            f"{t.margin[j]:.2g}); read through the robot file with its own baseline it is {c.before[j]:.4g} -> "
            f"{c.after[j]:.4g} N m (margin {c.margin[j]:.2g})"
            for j in self.carried
            if (j in own) != (j in theirs)
        )

    @property
    def above(self) -> tuple:
        """The joints (0-based) whose identified RMSE exceeds the robot file's by more than the floor and the estimation
        allowance, the bootstrap's noise left out: worse by the measured numbers, though maybe by chance. Where the data
        do not determine a parameter, holding it is the default, and this decides it (``one_way_friction``)."""
        if self.comparison is None:
            return ()
        c = self.comparison
        with np.errstate(invalid="ignore"):
            above = c.after > c.before * (1.0 + MARGIN_FLOOR) + self._extra
        return tuple(int(j) for j in np.flatnonzero(above))

    def describe(self) -> str:
        """One sentence: never worse on every joint, or which joints are worse with the numbers and what to do."""
        if self.comparison is None:
            return f"against the robot file: not checked ({self.reason})"
        c, held = self.comparison, f"{self.recordings} held-out recording(s)"
        allowance, carried = self._allowance_text(), self._carried_text()
        carried = f"; {carried}" if carried else ""
        if not self.worse:
            above = [j for j in range(len(c.after)) if c.after[j] > c.before[j] + c.margin[j] - self._extra[j]
                     and j not in self.carried]  # fmt: skip
            within = f"; above it within that allowance: {c.text(above)}" if above else ""
            return (f"against the robot file ({self._baseline_text()}): no joint worse on {held} beyond "
                    f"{allowance} (RMSE {_numbers(c.after)} against {_numbers(c.before)} N m{within}"
                    f"{carried})")  # fmt: skip
        joints = ", ".join(str(j + 1) for j in self.worse)
        return (f"against the robot file ({self._baseline_text()}): WORSE on joint(s) {joints} on {held} "
                f"beyond {allowance}: {c.text(self.worse)} (file baseline -> identified{carried}). The model is "
                f"written as identified, "
                f"but on those joints the robot file (its validation table's file baseline, not the robot file alone) "
                f"predicts the held-out motion better: '{DIAGNOSE_COMMAND}' scores "
                f"that model and names what it finds missing. {self._remedy()}")  # fmt: skip

    def _baseline_text(self) -> str:
        """Which baseline the joints were judged against (``BASELINES``): the file's rigid body with friction fitted,
        or on some joints the file alone where that predicts the held-out recordings better."""
        alone = [j for j, b in enumerate(self.baselines) if b == "alone"]
        if not alone:
            return "its rigid body, friction fitted"
        joints = ", ".join(str(j + 1) for j in alone)
        return (f"its rigid body, friction fitted; on joint(s) {joints} the robot file alone, which predicts the "
                "held-out motion better there than with the friction fitted on the training recordings")  # fmt: skip

    def _remedy(self) -> str:
        """What to record: the worse joints that never reversed first (their friction is a constant there)."""
        one_way = [j for j in self.one_way if j in self.worse]
        if not one_way:
            return ("To identify those joints better, record more of their motion (more --data recordings, over the "
                    "held-out speeds) and identify again")  # fmt: skip
        joints = ", ".join(str(j + 1) for j in one_way)
        held = [j for j in one_way if j in self.held]
        held = (f" Their friction is held to the robot file's fit on joint(s) {', '.join(str(j + 1) for j in held)} "
                "already, so what is left is the rigid body the training motion does not fix."
                if held else "")  # fmt: skip
        return (
            f"Joint(s) {joints} move one way only in the training recording(s) (both ways on less than "
            f"{MIN_REVERSAL_FRACTION:.0%} of the samples): there their Coulomb and viscous friction trade with "
            f"the rigid body and an offset.{held} Record them reversing (more --data recordings) and identify again"
        )

    def _allowance_text(self) -> str:
        if not self.from_covariance:
            rule = "/".join(f"{uniform_allowance(self.parameters, n):.1%}" for n in self.samples)
            return (f"the never-worse margin plus {rule} for estimating {self.parameters} rigid-body parameters "
                    f"from {'/'.join(f'{n:.0f}' for n in self.samples)} independent samples per joint (the fit "
                    "states no covariance)")  # fmt: skip
        return (f"the never-worse margin plus what estimating the {self.parameters} rigid-body parameters costs on "
                f"the held-out motion (from the fit's covariance: {_numbers(self._extra)} N m)")  # fmt: skip

    @property
    def _extra(self) -> np.ndarray:
        """The estimation allowance per joint [N m] (part of ``comparison.margin``)."""
        return np.zeros(len(self.comparison.before)) if self.allowance is None else np.asarray(self.allowance)

    def _kept_dict(self) -> dict | None:
        """The ``verdict_kept`` block: the carried joints, the rule, both verdicts and the numbers behind them."""
        if self.default is None or not self.carried:
            return None
        d, t = self.default.comparison, self.trial
        return {"joints": [j + 1 for j in self.carried], "rule": KEPT_RULE,
                "default_worse_joints": [j + 1 for j in self.default.worse],
                "own_worse_joints": [j + 1 for j in self.comparison.worse],
                "default_rmse_file": _floats(d.before), "default_rmse": _floats(d.after),
                "default_margin": _floats(d.margin), "trial_margin": _floats(t.margin)}  # fmt: skip

    def to_dict(self) -> dict:
        if self.comparison is None:
            return {"checked": False, "reason": self.reason}
        return _json({"checked": True, "recordings": self.recordings, **self.comparison.to_dict(),
                "worse_joints": [j + 1 for j in self.worse], "verdict_kept": self._kept_dict(),
                "estimation_allowance": [float(v) for v in self._extra],
                "estimation_allowance_rule": ALLOWANCE_RULES[self.from_covariance],
                "estimated_parameters": self.parameters, "independent_samples_per_joint": list(self.samples),
                "one_way_joints": [j + 1 for j in self.one_way], "baselines": list(self.baselines),
                "baseline_rule": BASELINE_RULE, "held_links": [i + 1 for i in self.held_links]})  # fmt: skip


KEPT_RULE = (
    "a joint the identified model (LuGre friction) predicts within the paired margin of the default "
    "steady-state model it replaced, on each held-out recording, keeps that model's verdict against the "
    "robot file (lugre_trial)"
)


def _floats(values) -> list:
    return [float(v) for v in np.atleast_1d(values)]


def _numbers(values) -> str:
    return "/".join("-" if not np.isfinite(v) else f"{v:.3g}" for v in values)  # -: a joint without torque


def _json(value):
    """``value`` with every non-finite float as None (a joint without torque in the held-out recordings)."""
    if isinstance(value, dict):
        return {k: _json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json(v) for v in value]
    return None if isinstance(value, float) and not np.isfinite(value) else value


def _columns(fit, qd, qdd) -> np.ndarray:
    return drive_columns(qd, qdd, fit.friction_terms, fit.inertia_joints, fit.coulomb_velocity, *fit_shape(fit))


def joint_fits(fit, n_dof: int) -> tuple:
    """The fit whose drive columns each joint's friction takes: ``fit`` itself on every joint, or ``fit`` as given
    where it is one per joint (a mixed model's: the Stribeck start on its LuGre joints, its own fit on the others)."""
    return tuple(fit) if isinstance(fit, (tuple, list)) else (fit,) * n_dof


def _joint_drive_columns(fits, qd, qdd) -> list:
    """Per joint, the drive columns of its fit in ``fits`` (each distinct fit's made once)."""
    made = {}
    for fit in fits:
        if id(fit) not in made:
            made[id(fit)] = _columns(fit, qd, qdd)
    return [made[id(fit)] for fit in fits]


def _joint_columns(fit, joint: int) -> np.ndarray:
    """The drive columns (indices) of ``joint`` the identified fit kept: its own friction terms, an offset or a static
    friction only where the fit did not hold it at 0, its own drive inertia."""
    keep = []
    for k, name in enumerate(fit.drive_names):
        own = drive_column_joint(name) == joint
        held = name.startswith(("offset", "fs")) and fit.drive[k] == 0.0
        if own and not held:
            keep.append(k)
    return np.asarray(keep, dtype=int)


def file_friction(oracle, fit, prepared) -> FileFriction:
    """The robot file's rigid body (``oracle``) with each joint's drive columns of ``fit`` fitted by least squares
    on the ``prepared`` training recordings (joints without torque, NaN, left out), friction and drive inertias >= 0
    and offsets free, as the consistent fit bounds them (``consistent_fit.drive_lower_bounds``; a drive inertia here is
    on top of the file's). Zero is feasible, so per joint its training residual is never above the file's alone.
    ``fit`` may be one per joint (:func:`joint_fits`): each joint takes its own fit's columns."""
    from scipy.optimize import lsq_linear

    residual = np.concatenate([r.tau - oracle.rnea(r.q, r.qd, r.qdd) for r in prepared])
    fits = joint_fits(fit, residual.shape[1])
    rows = [_joint_drive_columns(fits, r.qd, r.qdd) for r in prepared]  # per recording, per joint
    coefficients = []
    for j in range(residual.shape[1]):
        columns = np.concatenate([row[j][:, j] for row in rows])
        keep, ok = _joint_columns(fits[j], j), np.isfinite(residual[:, j])
        lower = drive_lower_bounds(fits[j].drive_names)
        x = []
        if keep.size and ok.any():
            x = lsq_linear(columns[ok][:, keep], residual[ok, j], (lower[keep], np.inf), method="bvls").x
        coefficients.append((keep, np.asarray(x, dtype=float)))
    return FileFriction(fit, tuple(coefficients))


def check_against_file(
    robot, model, calibrated, fit, prepared, validation, options, samples=None, columns=None
) -> FileCheck:
    """``FileCheck`` of the identified ``calibrated`` model (its ``fit``) against the robot file with friction fitted
    on the ``prepared`` training recordings, on the raw held-out ``validation`` recordings (module docstring).

    ``samples``: the independent training samples in all (the pull's ``effective_samples``), shared among the joints
    as their own rows (``TrajectoryFit.joint_samples``: a joint whose rows of a recording were left out, a dead torque
    channel, has fewer); default each joint's rows, as if each were independent (a smaller allowance). ``columns``:
    the fit whose drive columns the file's friction is fitted with (default ``fit``): a LuGre model's fit has no
    friction columns (its friction is the LuGre block), and the file is given the Stribeck columns that friction
    started from (``lugre_identify``); or one per joint (:func:`joint_fits`, None: ``fit``'s), a mixed model's: the
    Stribeck start on its LuGre joints and its own columns on its steady-state ones, each joint judged against the file
    with the friction shape the model gives it."""
    from psdm_casadi.oracle import PinocchioOracle

    if not validation:
        return FileCheck(reason="no held-out recording: pass --validate with a recording of another motion to compare "
                         "each joint with the robot file's rigid body")  # fmt: skip
    if robot.links is None:
        return FileCheck(reason="the robot file states no links")
    oracle = PinocchioOracle(robot)
    chosen = tuple(fit if c is None else c for c in joint_fits(columns, robot.n_dof))
    baseline = file_friction(oracle, chosen, prepared)
    covariance = rigid_body_covariance(model, fit)
    residuals = []  # per held-out recording: (prepared recording, model's, file + friction's, file alone's)
    for recording in validation:
        kt = torque_constants(robot, options, [recording])
        ready, predicted = calibrated.predict_recording(model, recording, kt)
        alone = oracle.rnea(ready.q, ready.qd, ready.qdd)
        friction = baseline.predict(oracle, ready.q, ready.qd, ready.qdd)
        residuals.append((ready, ready.tau - predicted, ready.tau - friction, ready.tau - alone))
    use_alone = _alone_better(residuals)
    comparisons, each = [], []
    for ready, model_error, friction_error, alone_error in residuals:
        before, after, se = paired_rmse_margin(np.where(use_alone, alone_error, friction_error), model_error)
        comparisons.append(JointComparison.from_noise(before, after, se))
        if covariance is not None:
            each.append(joint_allowance(before, prediction_variance(model, covariance, ready)))
    rows = np.asarray(fit.joint_samples or (fit.n_samples,) * robot.n_dof, dtype=float)  # a fit of before: one count
    per_joint = rows if samples is None else samples * rows / max(float(rows.sum()), 1.0)
    pooled = pooled_comparison(comparisons)
    if covariance is not None:  # the mean over the recordings that hold the joint, as ``pooled.before``
        each = np.array(each)
        held = np.isfinite(each)
        allowance = np.where(held, each, 0.0).sum(axis=0) / np.maximum(held.sum(axis=0), 1)
    else:
        allowance = np.array([uniform_allowance(model.n_base, n) for n in per_joint]) * np.nan_to_num(pooled.before)
    pooled = replace(pooled, margin=pooled.margin + allowance)
    one_way = one_way_joints(prepared, range(robot.n_dof), speed=options.coulomb_velocity,
                             min_fraction=MIN_REVERSAL_FRACTION)  # fmt: skip
    return FileCheck(pooled, len(validation), each=tuple(comparisons), allowance=allowance, parameters=model.n_base,
                     samples=tuple(per_joint.tolist()), one_way=tuple(one_way), from_covariance=covariance is not None,
                     baselines=tuple("alone" if a else "friction" for a in use_alone))  # fmt: skip


def _alone_better(residuals) -> np.ndarray:
    """Per joint, whether the robot file alone (no friction) has a lower RMSE on the held-out recordings (the mean
    over the recordings that hold the joint, as ``pooled_comparison``) than its rigid body with friction fitted: the
    baseline is the best the robot file offers there (module docstring)."""
    with np.errstate(invalid="ignore"):
        rmse = np.array([[np.sqrt(np.mean(e**2, axis=0)) for e in r[2:]] for r in residuals])  # (recording, 2, dof)
    held = np.isfinite(rmse).all(axis=1)
    mean = np.where(held[:, None, :], rmse, 0.0).sum(axis=0) / np.maximum(held.sum(axis=0), 1)
    return (mean[1] < mean[0]) & (held.sum(axis=0) > 0)
