"""Friction the training data do not determine, on joints that move one way only: held to the robot file's fit.

On a joint that never reverses in the training recordings its Coulomb friction is a constant there, which the rigid
body's gravity torque and an offset take as well; with a short recording the rigid body is itself hardly fixed, and
the fit trades the two freely. Kinova Gen3 trained on opti_traj_testing2 (2.3 s, only joint 2 reverses, condition
number 1447): the model identify wrote was worse than the robot file with friction fitted on joints 3, 5, 6 of
opti_traj_testing1 (0.24 -> 0.31, 0.14 -> 0.29, 0.19 -> 0.42 N m); a stronger pull towards the file (u = 0.1) left
them worse. The friction fitted beside the rigid body is what goes wrong, so :func:`hold_one_way_friction` holds it:

1. the joints that move one way only (``excitation_check.one_way_joints``, the share ``MIN_REVERSAL_FRACTION`` each
   way) and whose friction is undetermined: a friction parameter's standard deviation (least squares, sandwich) above
   its value in the fit (the report's ``sigma %`` over 100) -- the candidates;
2. with held-out recordings, the robot-file check (``robot_file_check``) of the fit judges: if the fit is worse than
   the robot file (its rigid body, friction fitted) on a one-way joint beyond the never-worse margin, or above it on
   a candidate by more than the estimation allowance (``FileCheck.above``), the candidates and the one-way joints it
   is worse on are held; otherwise the fitted friction stays. Where the data do not determine the friction, holding
   it is the default, and the held-out recordings must show the fitted one no worse to keep it: the bootstrap noise
   of a short held-out recording is wide where the error comes in bursts (Kinova trained on opti_traj_testing1 alone:
   joint 6 0.270 -> 0.501 N m within a margin of 0.27). A one-way joint whose friction the sandwich calls determined
   is held only when worse beyond the margin: the rigid body's gravity parameters and the Coulomb level trade along a
   one-way motion beyond what the standard deviation of either says (trained on opti_traj_testing1 and
   RunTrajectory1: joint 6's friction determined, yet 0.202 -> 0.296 N m on opti_traj_testing2; held, 0.222). The
   held-out recordings then decide the model (which joints are held), so the check that follows is not independent
   of them: the record (``decided_by_held_out``) and the sentence say so. Without held-out recordings nothing can
   tell, and the candidates are held (the robot file's rigid body is no guess of these data's);
3. a held joint's Coulomb and viscous friction are those of the robot file's rigid body fitted to the training data
   (``robot_file_check.file_friction``, Coulomb-viscous: a Stribeck hump is no more determined than the level it sits
   on), and the fit is made again with them held (``held_friction``): the rigid body is fitted to what they leave.
   Beside payloads the robot file's friction is fitted as the robot-file check fits it (``file_judged``): each known
   payload's torque taken off, each recording with an unknown payload left out (the file cannot hold its load); the
   one-way joints are those of every training recording.

Kinova opti_traj_testing2 -> opti_traj_testing1: joints 1, 3, 4, 5, 6, 7 held, validation 0.261 / 0.153 / 0.207 N m
on joints 3, 5, 6 (robot file with friction 0.241 / 0.136 / 0.188), no joint worse than it. ``mode``: ``"auto"``
(above), ``"hold"`` (every one-way joint, determined or not) or ``"fit"`` (the data's friction everywhere).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.held_friction import HELD_TERMS, HeldFriction
from identification.calibration.robot_file_check import file_friction
from identification.calibration.trajectory_checks import MIN_REVERSAL_FRACTION
from identification.calibration.trajectory_data import drive_column_joint
from identification.data.excitation_check import one_way_joints
from psdm_casadi.errors import ParameterError, SolverError

__all__ = ["ONE_WAY_MODES", "OneWayFriction", "check_one_way_mode", "file_friction_values", "hold_one_way_friction",
           "held_options", "undetermined_friction"]  # fmt: skip

logger = logging.getLogger(__name__)

#: ``--one-way-friction``: the data decide (default), hold every one-way joint's friction, or fit it everywhere.
ONE_WAY_MODES = ("auto", "hold", "fit")
#: The friction parameters whose determination is judged.
FRICTION_PARAMETERS = ("fc", "fs", "fv")


def check_one_way_mode(mode: str) -> None:
    """Raise ``ParameterError`` unless ``mode`` is one of ``ONE_WAY_MODES``."""
    if mode not in ONE_WAY_MODES:
        raise ParameterError(f"--one-way-friction must be one of {', '.join(ONE_WAY_MODES)}; got {mode!r}.")


@dataclass(frozen=True)
class OneWayFriction:
    """What identify decided about the friction of the joints that move one way only in training (0-based joints).

    ``undetermined``: per candidate joint, its friction parameters ``(name, value, standard deviation)``; ``held``: the
    ``(name, value)`` pairs held (empty: none); ``worse``: the one-way joints the robot-file check of the fit found
    worse (held-out recordings); ``reason``: why, in words; ``decided_by_held_out``: the held-out recordings decided
    the hold (their check of the fitted friction), so they no longer judge the model held independently;
    ``replaced``: the ``(name, value)`` this step held that a later hold (``worse_joint_hold``) replaced, ``held``
    then holding the value in effect (``replaced_by``).
    """

    mode: str = "auto"
    one_way: tuple = ()
    undetermined: tuple = ()  # ((joint, ((name, value, std), ...)), ...)
    held: tuple = ()
    worse: tuple = ()
    reason: str = ""
    decided_by_held_out: bool = False
    replaced: tuple = ()

    @property
    def held_joints(self) -> tuple:
        return HeldFriction(self.held).joints

    def replaced_by(self, later) -> OneWayFriction:
        """This record with the ``(name, value)`` friction ``later`` held (``worse_joint_hold``) in effect where it
        holds a column this step held at another value: one value per column in the report and the file."""
        new = dict(later)
        changed = tuple((n, v) for n, v in self.held if n in new and abs(new[n] - v) > 1e-12)
        if not changed:
            return self
        held = tuple((n, new.get(n, v)) for n, v in self.held)
        return replace(self, held=held, replaced=self.replaced + changed)

    def describe(self) -> str:
        """One sentence: which joints move one way only, what was held and why, or why nothing was."""
        if not self.one_way:
            return ""
        joints = ", ".join(str(j + 1) for j in self.one_way)
        head = f"friction of the joints that move one way only in training ({joints}): "
        if not self.held:
            return head + self.reason
        values = HeldFriction(self.held).describe()
        decided = (". The held-out recording(s) decided this hold: their check against the robot file that follows "
                   "is not independent of it") if self.decided_by_held_out else ""  # fmt: skip
        then = ""
        if self.replaced:
            was = ", ".join(f"{n} {v:.3g} -> {dict(self.held)[n]:.3g}" for n, v in self.replaced)
            then = (f"; then replaced on joint(s) {', '.join(str(j + 1) for j in HeldFriction(self.replaced).joints)} "
                    f"by the worse-joint hold below ({was}: the values above are those in effect)")  # fmt: skip
        return (f"{head}held, Coulomb-viscous, to the robot file's rigid body's friction fit ({values}; N m, "
                f"N m s/rad) -- {self.reason}{decided}{then}. --one-way-friction fit fits it from the data "
                "instead")  # fmt: skip

    def to_dict(self) -> dict:
        return {"mode": self.mode, "one_way_joints": [j + 1 for j in self.one_way],
                "undetermined": {f"joint {j + 1}": {n: {"value": v, "std": s} for n, v, s in params}
                                 for j, params in self.undetermined},
                "held": {n: v for n, v in self.held}, "held_joints": [j + 1 for j in self.held_joints],
                "worse_joints": [j + 1 for j in self.worse], "reason": self.reason,
                "decided_by_held_out": self.decided_by_held_out,
                "replaced_by_worse_joint_hold": {n: v for n, v in self.replaced}}  # fmt: skip


def undetermined_friction(fit, joints) -> tuple:
    """Of ``joints`` (0-based), those with a friction parameter of ``fit`` (fitted, not held at 0 by the fit) whose
    standard deviation exceeds its value: ``((joint, ((name, value, std), ...)), ...)``."""
    out = []
    for j in joints:
        params = tuple((name, float(fit.drive[k]), float(fit.drive_std[k])) for k, name in enumerate(fit.drive_names)
                       if name.rstrip("0123456789") in FRICTION_PARAMETERS and drive_column_joint(name) == j
                       and fit.drive_std[k] > 0)  # fmt: skip
        if any(s > abs(v) for _, v, s in params):
            out.append((j, params))
    return tuple(out)


def file_friction_values(robot, fit, prepared, joints) -> tuple:
    """``(name, value)`` of the Coulomb and viscous friction of ``joints`` fitted beside the robot file's rigid body
    on the ``prepared`` training recordings, the joints taken Coulomb-viscous."""
    from psdm_casadi.oracle import PinocchioOracle

    drive = np.array(fit.drive, dtype=float)
    vs = np.array(fit.stribeck_velocity, dtype=float) if fit.stribeck_velocity else None
    for j in joints:
        if vs is not None:
            vs[j] = 0.0
            drive[fit.drive_names.index(f"fs{j + 1}")] = 0.0  # held at 0: left out of the file's fit
    flat = replace(fit, drive=drive, stribeck_velocity=() if vs is None else tuple(vs))
    baseline = file_friction(PinocchioOracle(robot), flat, prepared)
    held = []
    for j in joints:
        keep, x = baseline.coefficients[j]
        held += [(fit.drive_names[k], float(v)) for k, v in zip(keep, x)
                 if fit.drive_names[k].rstrip("0123456789") in HELD_TERMS]  # fmt: skip
    return tuple(held)


def held_options(options, held, n_dof: int):
    """``options`` (``TrajectoryOptions``) with ``held`` friction, the held joints Coulomb-viscous (without a Stribeck
    joint left, no static friction at all: a model file's Stribeck velocities have one positive or none)."""
    joints = {drive_column_joint(name) for name, _ in held}
    if "fs" not in options.friction:
        return replace(options, held_friction=tuple(held))
    stribeck = range(n_dof) if options.stribeck_joints is None else options.stribeck_joints
    left = tuple(j for j in stribeck if j not in joints)
    if not left:
        return replace(options, held_friction=tuple(held), stribeck_joints=None,
                       friction=tuple(t for t in options.friction if t != "fs"))  # fmt: skip
    return replace(options, held_friction=tuple(held), stribeck_joints=left)


def hold_one_way_friction(problem, fit, prepared, mode: str = "auto", file_check=None, file_prepared=None) -> tuple:
    """``(fit, OneWayFriction)``: ``fit`` as it is, or made again with the friction of its one-way joints held where
    it is undetermined or the held-out recordings find it worse than the robot file (module docstring). ``problem`` =
    ``(robot, model, recordings, options, configurations, refit)`` where ``refit(options) -> TrajectoryFit``;
    ``prepared``: the training recordings as the fit prepared them (which joints move one way only);
    ``file_check(fit) -> robot_file_check.FileCheck`` of a fit on the held-out recordings (None: none given);
    ``file_prepared``: the training recordings the robot file's friction is fitted on (default ``prepared``; with
    payloads ``file_judged.file_training``: known loads taken off, recordings with an unknown one left out)."""
    robot, options, refit = problem[0], problem[3], problem[5]
    file_prepared = prepared if file_prepared is None else file_prepared
    one_way = tuple(one_way_joints(prepared, range(robot.n_dof), speed=options.coulomb_velocity,
                                   min_fraction=MIN_REVERSAL_FRACTION))  # fmt: skip
    record = OneWayFriction(mode=mode, one_way=one_way)
    if not one_way:
        return fit, replace(record, reason="fitted from the data (every joint moves both ways in training)")
    if mode == "fit":
        return fit, replace(record, reason="fitted from the data (--one-way-friction fit)")
    undetermined = undetermined_friction(fit, one_way)
    candidates = one_way if mode == "hold" else tuple(j for j, _ in undetermined)
    record = replace(record, undetermined=undetermined)
    if robot.links is None:
        return fit, replace(record, reason="fitted from the data (the robot file states no links to hold it to)")
    if not file_prepared:
        return fit, replace(record, reason="fitted from the data (every training recording carries an unknown payload "
                            "the robot file does not: its friction has no recording to be fitted on without that "
                            "load)")  # fmt: skip
    check = None if file_check is None or mode == "hold" else file_check(fit)
    worse = () if check is None else tuple(j for j in check.worse if j in one_way)
    above = () if check is None else tuple(j for j in check.above if j in candidates)
    if check is None and not candidates:
        return fit, replace(record, reason="fitted from the data (each of their friction parameters larger than its "
                                           "standard deviation: the data determine it)")  # fmt: skip
    if check is not None and not worse and not above:
        undetermined_text = (f"undetermined on joint(s) {', '.join(str(j + 1) for j in candidates)}, but"
                             if candidates else "determined by the data, and")  # fmt: skip
        return fit, replace(record, reason=f"fitted from the data: {undetermined_text} no worse there than the robot "
                                           f"file on {check.recordings} held-out recording(s)")  # fmt: skip
    joints = tuple(sorted(set(candidates) | set(worse)))
    held = file_friction_values(robot, fit, file_prepared, joints)
    logger.info("identify: holding the friction of joints %s (one way only, undetermined or worse) to the robot "
                "file's fit ...", ", ".join(str(j + 1) for j in joints))  # fmt: skip
    try:
        held_fit = refit(held_options(options, held, robot.n_dof))
    except SolverError as error:  # the fit it replaces stands, and the report says why
        return fit, replace(record, worse=worse, reason=f"fitted from the data: the fit with joint(s) "
                            f"{', '.join(str(j + 1) for j in joints)} held did not converge ({error})")  # fmt: skip
    reason = _why(mode, candidates, tuple(sorted(set(worse) | set(above))), check)
    return held_fit, replace(record, held=held, worse=worse, reason=reason, decided_by_held_out=check is not None)


def _why(mode, candidates, worse, check) -> str:
    if mode == "hold":
        return "--one-way-friction hold"
    joints = ", ".join(str(j + 1) for j in candidates)
    undetermined = (f"their friction is undetermined on joint(s) {joints} (a standard deviation above its value)"
                    if candidates else "their friction is determined by the data")  # fmt: skip
    if check is None:
        return f"{undetermined}, and no held-out recording tells whether the data's own is better"
    numbers = "; ".join(f"joint {j + 1} {check.comparison.before[j]:.3g} -> {check.comparison.after[j]:.3g} N m"
                        for j in worse)  # fmt: skip
    return (
        f"{undetermined}, and with it fitted the model was worse than the robot file with friction fitted on "
        f"{check.recordings} held-out recording(s) ({numbers}; an undetermined friction is held unless the held-out "
        "recordings find it no worse by more than the estimation allowance, a determined one only when it is worse "
        "beyond the never-worse margin)"
    )
