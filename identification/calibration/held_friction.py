"""Friction held at given values in a fit: its torque taken off the prepared recordings, its columns left out.

``TrajectoryOptions.held_friction`` names drive columns (``fc<j>``, ``fv<j>``) and the value each is held at (a joint
whose friction the data do not determine: ``one_way_friction``). The fit (``trajectory_fit.identify_trajectories``)
then sees the torque the held friction leaves, ``tau - D_held f_held``, fits every other parameter to it with the held
columns out of both the least-squares and the consistent fit, and reports the held values as the columns'
estimates (standard deviation 0: not estimated). A held joint's friction is Coulomb-viscous (its smoothing velocity
the fit's): a Stribeck hump is no more determined than the Coulomb level it sits on.

A model file states what identify held (``identification.one_way_friction.held``); every command that refits the
file's model keeps it: ``HeldFriction.of_document`` reads it with the file's smoothing velocity, for the refit of
``diagnose --apply`` (``recalibrate``) and the nominal model of ``diagnose MODEL`` (``DiagnosisOptions.held_friction``),
whose every fit explains the torque the held friction leaves (``HeldFriction.torque``, the one friction ``psdm
validate`` predicts). The nominal model of ``diagnose MODEL`` also holds the file's torque offsets (``offset<j>``,
``HeldFriction.of_model_file``): a diagnosis's nominal carries the file's columns, so its "before" is the file's and no
finding is the offset found again; a spring is then tested against the nominal model with its offset. An offset
identify itself read as no sensor's (``counterbalance_record``: a counterbalance it could not keep as a spring) is no
zero error: ``diagnose MODEL`` leaves it to the diagnosis (``without_offsets``), which names it. A file's
drive inertia below 0 (``Ia<j>``: a torque measured behind the gearbox, which holds less than the robot file's rotor)
is held likewise, ``Ia_j qdd_j``: the robot a diagnosis starts from holds rotor inertias >= 0 only
(``drive_inertia_split``, the one rule ``calibrated_model.calibrated_robot`` and ``of_model_file`` share), so the
nominal model predicts such a file as ``psdm validate`` does. So is a drive inertia the file fitted as a column of its
own (outside the base parameters, ``separate_inertia``), and the nominal robot then has no rotor there
(``without_held_rotors``): a diagnosis that recalibrates the rigid body fits the base parameters again, which cannot
hold it, and would find it missing.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.coulomb_width import file_coulomb_widths, joint_width, positive_widths, width_value
from identification.calibration.trajectory_data import drive_column_joint, friction_term
from psdm_casadi.errors import ParameterError

__all__ = ["CONSTANT_FEATURE", "HELD_TERMS", "HeldFriction", "check_held_friction", "drive_inertia_split",
           "held_friction_columns", "subtract_held_friction", "with_held_values", "baseline_columns",
           "without_held_rotors"]  # fmt: skip

#: The friction terms that may be held: Coulomb and viscous (a held joint is Coulomb-viscous).
HELD_TERMS = ("fc", "fv")
#: A finding's feature that is a constant torque on its joint, one column with the joint's offset: a spring's
#: (``spring_c_j``, a polynomial's ``c_j``).
CONSTANT_FEATURE = re.compile(r"(spring_)?c_\d+")
#: What a diagnosis's nominal model may hold besides: a model file's torque offsets and drive inertias below 0
#: (``HeldFriction.of_model_file``).
CARRIED_TERMS = (*HELD_TERMS, "offset", "Ia")


def _term(name: str) -> str:
    return name.rstrip("0123456789")


@dataclass(frozen=True)
class HeldFriction:
    """Friction held at given values: ``values`` ``((name, value), ...)`` of ``fc<j>``/``fv<j>`` columns, the Coulomb
    term smoothed over ``coulomb_velocity`` [rad/s] (one width, or a tuple per joint: ``coulomb_width``) and the
    viscous term a power ``viscous_exponent`` of the speed per joint (``()`` or 1: linear)
    (``trajectory_data.friction_term``, as the model file predicts)."""

    values: tuple = ()
    coulomb_velocity: float | tuple = 0.05
    viscous_exponent: tuple = ()

    def __post_init__(self):
        values = tuple((str(name), float(value)) for name, value in self.values)
        for name, value in values:
            if _term(name) not in CARRIED_TERMS or not np.isfinite(value):
                raise ParameterError(f"HeldFriction.values must be (name, finite value) pairs of the columns "
                                     f"{CARRIED_TERMS}, e.g. ('fc3', 0.2); got {(name, value)!r}.")  # fmt: skip
        width = positive_widths(self.coulomb_velocity, "HeldFriction.coulomb_velocity")
        object.__setattr__(self, "coulomb_velocity", width)
        exponents = tuple(float(dv) for dv in self.viscous_exponent)
        if not all(np.isfinite(dv) and dv > 0 for dv in exponents):
            raise ParameterError(f"HeldFriction.viscous_exponent must be positive per joint (1: linear viscous "
                                 f"friction); got {self.viscous_exponent!r}.")  # fmt: skip
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "viscous_exponent", exponents)

    @classmethod
    def of_document(cls, document: dict) -> HeldFriction:
        """What a calibrated-model file's identification held (``identification.one_way_friction.held``, then
        ``identification.worse_joints.held_friction``, ``worse_joint_hold``; none in files without them), with the
        file's smoothing velocity and viscous exponents (identify's held joints are linear, ``with_held_values``; a
        file that states another exponent for one is predicted with it, as ``psdm validate`` predicts it)."""
        identification, drive = document.get("identification", {}), document["drive"]
        held = dict((identification.get("one_way_friction") or {}).get("held") or {})
        held.update((identification.get("worse_joints") or {}).get("held_friction") or {})
        exponents = tuple(drive.get("viscous_exponent") or ())
        robot = document.get("robot")  # a document without one (a part of a file): the widths as they are stated
        n_dof = len(robot["joint_names"]) if robot else np.size(drive.get("coulomb_velocity", 0.0))
        widths = file_coulomb_widths(drive, n_dof)
        return cls(tuple(held.items()), width_value(widths), exponents)

    @classmethod
    def of_model_file(cls, document: dict) -> HeldFriction:
        """What the nominal model of ``diagnose MODEL`` holds at a calibrated-model file's values: the friction its
        identification held (``of_document``), its nonzero torque offsets (``offset<j>``, as ``psdm validate``
        predicts them) and its drive inertias below 0 (``drive_inertia_split``), so every fit of the diagnosis explains
        the torque they leave."""
        held = cls.of_document(document)
        drive = document["drive"]
        offsets = tuple((name, float(value)) for name, value in zip(drive["names"], drive["values"])
                        if _term(name) == "offset" and float(value) != 0.0)  # fmt: skip
        standard = np.asarray(document["standard"]["values"], dtype=float)
        n_dof = standard.size // 11
        own = {drive_column_joint(name) for name in drive["names"] if _term(name) == "Ia"}
        inertias = drive_inertia_split(standard.reshape(n_dof, 11)[:, 10], own)[1]
        extra = offsets + inertias
        return replace(held, values=held.values + extra) if extra else held

    @property
    def joints(self) -> tuple:
        """The joints whose friction is held (0-based, increasing); a held offset leaves the friction free."""
        return tuple(sorted({drive_column_joint(name) for name, _ in self.values if _term(name) in HELD_TERMS}))

    @property
    def offsets(self) -> tuple:
        """The held torque offsets ``((name, value), ...)`` (a model file's, ``of_model_file``)."""
        return tuple((name, value) for name, value in self.values if _term(name) == "offset")

    @property
    def drive_inertias(self) -> tuple:
        """The held drive inertias ``((name, value), ...)`` (a model file's below 0, ``of_model_file``)."""
        return tuple((name, value) for name, value in self.values if _term(name) == "Ia")

    def offset_of(self, joint: int) -> float:
        """The held torque offset [N m] of ``joint`` (0-based); 0 when none is held."""
        return sum(value for name, value in self.offsets if drive_column_joint(name) == joint)

    def without_offsets(self, joints) -> HeldFriction:
        """This hold without the torque offsets of ``joints`` (0-based): an offset that is no sensor's zero error
        (``counterbalance_record.counterbalance_offsets``) is left to the fit that judges it."""
        joints = set(joints)
        kept = tuple((n, v) for n, v in self.values if _term(n) != "offset" or drive_column_joint(n) not in joints)
        return replace(self, values=kept)

    def torque(self, qd, qdd=None) -> np.ndarray:
        """The held torque (n_samples, n_dof) at the velocities ``qd`` and accelerations ``qdd`` (n_samples, n_dof;
        needed only with a held drive inertia) [N m]."""
        qd = np.asarray(qd, dtype=float)
        out = np.zeros_like(qd)
        for name, value in self.values:
            j = drive_column_joint(name)
            out[:, j] += value * self._column(name, qd[:, j], None if qdd is None else np.asarray(qdd)[:, j])
        return out

    def expression(self, qd, qdd=None):
        """The held torque as a CasADi expression of the velocity ``qd`` and acceleration ``qdd`` (SX, n_dof)."""
        import casadi as ca

        out = ca.SX.zeros(qd.shape[0])
        for name, value in self.values:
            j = drive_column_joint(name)
            out[j] += value * self._column(name, qd[j], None if qdd is None else qdd[j])
        return out

    def _width(self, name) -> float:
        """[rad/s] the Coulomb width of the joint of column ``name``."""
        return joint_width(self.coulomb_velocity, drive_column_joint(name))

    def _column(self, name, qd, qdd):
        if _term(name) == "fv" and self.viscous_exponent:
            dv = self.viscous_exponent[drive_column_joint(name)]
            return friction_term("fv", qd, self._width(name), None, None if dv == 1.0 else dv)
        if _term(name) != "Ia":
            return friction_term(_term(name), qd, self._width(name))
        if qdd is None:
            raise ParameterError(f"HeldFriction.torque needs the accelerations qdd for the held drive inertia {name}.")
        return qdd

    def describe(self) -> str:
        """``joint 3: fc3 0.292, fv3 0.0107`` per held joint ("" when nothing is held)."""
        joint = drive_column_joint
        joints = sorted({joint(name) for name, _ in self.values})
        return "; ".join(f"joint {j + 1}: " + ", ".join(f"{n} {v:.3g}" for n, v in self.values if joint(n) == j)
                         for j in joints)  # fmt: skip


def drive_inertia_split(inertias, own=()) -> tuple:
    """``(rotor, held)`` of a model file's drive inertias ``inertias`` [kg m^2], shape (n_dof,): the rotor inertias
    a ``RobotDescription`` holds (>= 0), and ``(("Ia<j>", value), ...)`` held beside it
    (``HeldFriction.of_model_file``): those below 0, and those of the joints ``own`` (0-based: the file's drive
    columns ``Ia<j>``, which identify fitted outside the base parameters). A held one is no rotor (0 in ``rotor``,
    ``without_held_rotors``), so together they are the file's ``Ia_j qdd_j``."""
    inertias = np.asarray(inertias, dtype=float)
    held = tuple((f"Ia{j + 1}", float(value)) for j, value in enumerate(inertias) if value < 0.0 or j in set(own))
    rotor = np.where([j in set(own) for j in range(inertias.size)], 0.0, np.maximum(inertias, 0.0))
    return rotor, held


def without_held_rotors(robot, held: HeldFriction):
    """``robot`` with no rotor inertia on the joints whose drive inertia ``held`` holds (``Ia<j>``): its torque is the
    held one, ``Ia_j qdd_j``, in every fit of the diagnosis (the prior's and the recalibrated rigid body's alike), not
    the rigid body's. A model file's drive column (``drive_inertia_split``'s ``own``) lies outside the base
    parameters: left in the rotor, a diagnosis that recalibrates the rigid body drops it and finds it again as a
    missing ``rotor_inertia``."""
    joints = {drive_column_joint(name) for name, _ in held.drive_inertias}
    if not joints or robot.rotor_inertia is None:
        return robot
    rotor = np.array(robot.rotor_inertia, dtype=float)
    rotor[sorted(joints)] = 0.0
    return robot.with_links(robot.links, rotor_inertia=rotor)


def check_held_friction(options) -> None:
    """Raise ``ParameterError`` unless ``options.held_friction`` is ``((name, value), ...)`` of finite values of
    ``fc<j>``/``fv<j>`` columns the fit has (``options.friction``), on joints not of the Stribeck shape."""
    held = options.held_friction
    for entry in held:
        ok = isinstance(entry, tuple) and len(entry) == 2 and isinstance(entry[0], str)
        if not ok or _term(entry[0]) not in HELD_TERMS or _term(entry[0]) not in options.friction:
            raise ParameterError(f"TrajectoryOptions.held_friction must hold (name, value) pairs of the columns "
                                 f"{HELD_TERMS} the fit has ({options.friction}), e.g. ('fc3', 0.2); got "
                                 f"{entry!r}.")  # fmt: skip
        if not np.isfinite(float(entry[1])):
            raise ParameterError(f"TrajectoryOptions.held_friction: {entry[0]} must be held at a finite value; got "
                                 f"{entry[1]!r}.")  # fmt: skip
    if held and "fs" in options.friction:
        joints = sorted({drive_column_joint(name) + 1 for name, _ in held})
        shaped = options.stribeck_joints is None or {j - 1 for j in joints} & set(options.stribeck_joints)
        if shaped:
            raise ParameterError(
                f"TrajectoryOptions.held_friction: held joints {joints} must be Coulomb-viscous; "
                "leave them out of stribeck_joints."
            )


def subtract_held_friction(prepared, options) -> list:
    """The prepared recordings with the held friction's torque taken off (``options.held_friction``)."""
    if not options.held_friction:
        return list(prepared)
    held = HeldFriction(options.held_friction, options.coulomb_velocity)
    return [replace(recording, tau=np.asarray(recording.tau, dtype=float) - held.torque(recording.qd))
            for recording in prepared]  # fmt: skip


def held_friction_columns(names, options, n_base: int) -> set:
    """The indices (after the ``n_base`` base parameters) of the held columns among the drive columns ``names``."""
    return {n_base + list(names).index(name) for name, _ in options.held_friction}


def baseline_columns(names, options, n_base: int) -> set:
    """The indices of the held columns ``worse_joint_hold`` chose (``options.baseline_friction``): held in the fit,
    free in the data's own least squares (``trajectory_fit``)."""
    return {n_base + list(names).index(name) for name in options.baseline_friction if name in names}


def with_held_values(fit, options):
    """``fit`` (a ``TrajectoryFit``) with its held columns at their held values, in the estimate and the least-squares
    estimate alike (their standard deviations stay 0: not estimated); a held joint's viscous friction is linear, as
    its held torque (its viscous exponent 1)."""
    if not options.held_friction:
        return fit
    drive, drive_ols = np.array(fit.drive, dtype=float), np.array(fit.drive_ols, dtype=float)
    for name, value in options.held_friction:
        k = fit.drive_names.index(name)
        drive[k] = drive_ols[k] = float(value)
    held = {drive_column_joint(name) for name, _ in options.held_friction if _term(name) in HELD_TERMS}
    dv = tuple(1.0 if j in held else float(v) for j, v in enumerate(fit.viscous_exponent))
    return replace(fit, drive=drive, drive_ols=drive_ols, viscous_exponent=dv if any(v != 1.0 for v in dv) else ())
