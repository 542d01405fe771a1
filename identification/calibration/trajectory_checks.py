"""Checks around the fit of exciting trajectories: refuse what cannot be identified, flag what looks like bad data.

Before the fit (:func:`~identification.calibration.trajectory_fit.identify_trajectories` calls them):

- :func:`check_columns`: the weighted regressor has full rank and a bounded condition number
  (``regressor_check``);
- :func:`check_offset_reversals`: with a torque offset per joint, every joint must move both ways. A
  joint that moves one way only has a Coulomb column ``tanh(qd / eps)`` that is a constant, like the
  offset's: the two cancel (thousands of N m each) and the model predicts nonsense elsewhere.

After it, :func:`fit_warnings` lists what a correct recording does not produce: a joint whose torque
the model does not explain on its own training data (R^2 below one half: a torque of another joint, or
of the wrong sign where the unconstrained fit does explain it), a friction or drive
inertia that the data want negative by many standard deviations (held at its bound of zero by the
consistent fit: a torque of the wrong sign, or of another joint), torques in another unit (only when every
joint's recorded torque is a unit factor, 1000 or 180/pi, off the robot file's), link masses an order of
magnitude away from the robot file's (an unmodelled effect or another robot's file), and the links the data
push against their physical envelope (``envelope_report``, with what they likely absorb). These are warnings, not
refusals: the model may still be what the data say, and the user decides.

A recording a calibrated model is judged on (``psdm validate``, ``psdm identify --validate``) passes
:func:`check_validation_recording` first: in the robot's units (``plausibility``), every joint moving. On a
joint that stands still the model's friction and velocity terms are not tested, and its RMSE and R^2
are a number that says nothing about them.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from identification.calibration.coulomb_width import coulomb_widths
from identification.calibration.trajectory_data import drive_column_joint
from identification.data.excitation_check import check_joint_motion, check_reversals, joint_label
from identification.data.plausibility import check_plausible_recording
from identification.data.regressor_check import base_parameter_joints, check_regressor

__all__ = [
    "COLUMN_FIX",
    "check_columns",
    "check_offset_reversals",
    "check_validation_recording",
    "fit_quality_warnings",
    "fit_warnings",
    "torque_ratio",
    "unit_factor",
]

COLUMN_FIX = "record a trajectory that excites {joints} better ('psdm excite' designs one), or add recordings"
REVERSAL_FIX = (
    "Record a trajectory on which {joints} reverses ('psdm excite' designs one), or identify without the torque "
    "offset (drop --offset)."
)
VALIDATION_FIX = (
    "Validate on a recording that moves {joints} over more of its range and speed, as the identification's "
    "recordings do ('psdm excite' designs one)."
)
#: Least share of the samples in each direction for Coulomb friction and an offset to be told apart.
MIN_REVERSAL_FRACTION = 0.02
#: Standard deviations below zero from which a friction's unconstrained estimate is flagged (drive inertias: 3).
FRICTION_Z = 5.0
DRIVE_INERTIA_Z = 3.0
#: Identified link mass over (or under) the robot file's by this factor is flagged.
MASS_RATIO = 10.0
#: Unit mistakes of a torque signal (recorded over true torque) and how close every joint's ratio must be to one.
UNIT_FACTORS = ((1000.0, "torques in mN m? (N m expected)"), (1e-3, "torques in kN m? (N m expected)"),
                (180.0 / np.pi, "a torque signal scaled by 180/pi (a degree conversion applied to it?)"),
                (np.pi / 180.0, "a torque signal scaled by pi/180 (a radian conversion applied to it?)"))  # fmt: skip
UNIT_TOLERANCE = 2.0
#: A joint whose torque the identified model explains less than this share of (R^2 on its own data) is flagged.
MIN_TRAINING_R2 = 0.5


def check_columns(robot, model, equations, names, recordings) -> None:
    """Refuse recordings whose (torque-RMS weighted) regressor is rank deficient or too ill-conditioned.

    The check sees the regressor through a square root ``R`` of its normal matrix (``R^T R = A^T W A``),
    which has the same singular values and directions as the stacked rows.
    """
    rms = np.sqrt(equations.energy / np.maximum(equations.count, 1))
    gram, _, _ = equations.weighted(1.0 / np.maximum(rms, 1e-12) ** 2)
    values, vectors = np.linalg.eigh(gram)
    root = np.sqrt(np.clip(values, 0.0, None))[:, None] * vectors.T
    base_names = [f"theta{k + 1}" for k in range(model.n_base)]
    drive_joints = [(drive_column_joint(name),) for name in names]
    check_regressor(root, names=base_names + list(names), owner="identify", robot=robot,
                    source=", ".join(r.name or "recording" for r in recordings), fix=COLUMN_FIX,
                    column_joints=list(base_parameter_joints(model)) + drive_joints)  # fmt: skip


def check_offset_reversals(robot, prepared, friction, coulomb_velocity, joints=None) -> None:
    """With ``"offset"`` and ``"fc"`` in ``friction``, every joint with an offset (``joints``, 0-based; None: all)
    moves faster than its ``coulomb_velocity`` (one width, or one per joint of ``robot``) both ways on at least
    ``MIN_REVERSAL_FRACTION`` of the prepared samples (``excitation_check.check_reversals``).

    Raises
    ------
    ParameterError
        For widths of another number than the robot's joints (``coulomb_width.coulomb_widths``).
    InsufficientExcitationError
        Naming the recordings, the joints that move one way only and the fix (record reversals, or drop the offset).
    """
    speed = coulomb_widths(coulomb_velocity, robot.n_dof, "TrajectoryOptions.coulomb_velocity")
    if "offset" not in friction or "fc" not in friction:
        return
    joints = range(robot.n_dof) if joints is None else joints
    check_reversals(prepared, joints, speed=speed, min_fraction=MIN_REVERSAL_FRACTION,
                    robot=robot, purpose="to tell its Coulomb friction (fc) from its torque offset (offset)",
                    fix=REVERSAL_FIX)  # fmt: skip


def check_validation_recording(robot, recording) -> None:
    """Refuse a recording a calibrated model of ``robot`` cannot be judged on (module docstring, last paragraph).

    Parameters
    ----------
    robot : RobotDescription
        The robot the model was identified for (limits, joint names).
    recording : Recording
        The raw validation recording; its ``name`` is the file named in the messages.

    Raises
    ------
    RecordingError
        For positions, speeds or time stamps in the wrong units (``plausibility.check_plausible_recording``).
    InsufficientExcitationError
        Naming the recording and every joint that barely moves (``excitation_check.check_joint_motion``).
    """
    check_plausible_recording(recording, robot)
    check_joint_motion(recording, range(robot.n_dof), robot=robot, purpose="the validation of a calibrated model",
                       fix=VALIDATION_FIX)  # fmt: skip


def _negative_terms(fit) -> dict:
    """Per joint (0-based), the friction terms whose unconstrained estimate is below zero by FRICTION_Z sigma."""
    out = {}
    for name, value, std in zip(fit.drive_names, fit.drive_ols, fit.drive_std):
        match = re.fullmatch(r"(fc|fs|fv)(\d+)", name)
        if match and value < -FRICTION_Z * std:
            unit = "N m s/rad" if match.group(1) == "fv" else "N m"
            term = f"{name} = {value:.3g} +- {std:.2g} {unit}, {-value / std:.0f} sigma below 0"
            out.setdefault(int(match.group(2)) - 1, []).append(term)
    return out


def _rising_viscous(fit) -> dict:
    """Per joint (0-based), the viscous friction ``fv`` estimated above zero by FRICTION_Z sigma, as text."""
    out = {}
    for name, value, std in zip(fit.drive_names, fit.drive_ols, fit.drive_std):
        match = re.fullmatch(r"fv(\d+)", name)
        if match and value > FRICTION_Z * std:
            out[int(match.group(1)) - 1] = f"fv{match.group(1)} = +{value:.3g} +- {std:.2g} N m s/rad"
    return out


def _friction_warnings(robot, fit) -> list:
    """A friction the data want negative. A torque of the wrong sign (or another joint's) turns every friction term
    negative; where the viscous term stays well above zero the sign is right, and a negative Coulomb or Stribeck
    term says the friction at low speed lies below the Coulomb-plus-viscous line through the fast samples (the
    heavy arm's smooth-Coulomb refit: fc2 = -746, fs2 = -1250 beside fv2 = +728 N m s/rad), not a wiring error."""
    held = "the consistent fit holds it at 0" if fit.checked else "the unconstrained model keeps it negative"
    viscous = _rising_viscous(fit)
    return [
        f"{joint_label(j, robot)}: the data want a negative friction ({'; '.join(terms)}); {held}. "
        + (
            f"The sign of tau{j + 1} is right ({viscous[j]} opposes the motion): the friction at low speed is below "
            f"a Coulomb-plus-viscous line through the fast samples (it rises faster than linearly with speed, or a "
            f"torque the model lacks follows the speed). 'psdm diagnose' compares friction shapes and names such a "
            f"torque."
            if j in viscous
            else f"Torque sign or joint mapping wrong? Check the sign of tau{j + 1} (or i{j + 1}) and that it is the "
            f"torque of {joint_label(j, robot)}."
        )
        for j, terms in sorted(_negative_terms(fit).items())
    ]


def _drive_inertia_warnings(fit) -> list:
    """A rotor inertia cannot be negative: the usual cause is a torque signal without the rotors in it."""
    return [
        f"the data ask for a negative drive inertia on joint {name[2:]} (unconstrained {name} = {value:.3g} +- "
        f"{std:.2g} kg m^2); the consistent fit holds it at 0, which costs fit on that joint. Torques measured on "
        "the link side of the gearbox (joint torque sensors: Franka Panda, KUKA iiwa) hold no rotor inertia: identify "
        "with --drive-inertia auto (the default, which drops such a column) or off."
        for name, value, std in zip(fit.drive_names, fit.drive_ols, fit.drive_std)
        if name.startswith("Ia") and value < -DRIVE_INERTIA_Z * std
    ]


def unit_factor(ratios) -> str | None:
    """The unit mistake that explains a torque ratio (recorded over expected) on every joint, or None.

    A factor counts when every joint's ratio is within ``UNIT_TOLERANCE`` of it (friction and a wrong robot file
    scatter the ratios; a unit scales them all alike).
    """
    ratios = np.asarray(ratios, dtype=float)
    if ratios.size == 0 or not np.all(np.isfinite(ratios) & (ratios > 0)):
        return None
    for factor, name in UNIT_FACTORS:
        if np.all(np.abs(np.log(ratios / factor)) <= np.log(UNIT_TOLERANCE)):
            return name
    return None


def _mass_warnings(robot, fit) -> list:
    """Torques in another unit (every joint off by a unit factor), else masses far from the robot file's."""
    if robot.links is None or not fit.checked:
        return []
    unit = unit_factor(fit.torque_ratio)
    if unit is not None:
        ratios = ", ".join(f"{r:.3g}" for r in fit.torque_ratio)
        return [f"the identified rigid-body torques are {ratios} times the robot file's on joints 1-"
                f"{robot.n_dof}: {unit}. Convert the torques to N m, state the log's unit (--columns tau=PREFIX:mNm), "
                "or fix the torque constants kt, and identify again."]  # fmt: skip
    prior = np.array([link.mass for link in robot.links], dtype=float)
    mass = np.asarray(fit.standard, dtype=float)[:, 0]
    out = []
    for j, (m, m0) in enumerate(zip(mass, prior)):
        if m0 > 0 and np.isfinite(m) and not (m0 / MASS_RATIO <= m <= m0 * MASS_RATIO):
            out.append(
                f"link {j + 1} ({joint_label(j, robot)}): identified mass {m:.3g} kg, {m / m0:.3g} times the robot "
                f"file's {m0:.3g} kg: the link absorbs a torque the rigid body does not model (a counterbalance or "
                "spring, a payload), or the robot file is another robot's. Identify with the physical envelope (the "
                "default) to see which link is pushed, and run 'psdm diagnose ROBOT --train DATA --validate OTHER' "
                "against the robot file to find the effect."
            )
    return out


def _envelope_warnings(fit) -> list:
    """The links and drives the data push against their physical envelope (``envelope_report``); none when the
    torques are in another unit (every link is then pushed, and the unit is the one cause to name)."""
    if unit_factor(getattr(fit, "torque_ratio", ())) is not None:
        return []
    return [finding.message for finding in fit.envelope if finding.pressed]  # a link resting on a bound: a note


def fit_quality_warnings(robot, fit, loaded=()) -> list:
    """Joints whose torque the identified model does not explain on the very recordings it was fitted to (none when
    the torques are in another unit: the bounded model cannot reach them, and the unit is the one cause to name).
    ``loaded``: the recordings that look as if they carry a load the others do not (``configuration_check``'s
    ``LoadedRecording``): one arm fitted across different loads is the cause then, not a torque's sign, and the
    warning says so. The only warnings of :func:`fit_warnings` that read the fit's R^2 (``training_r2``,
    ``training_r2_ols``): a fit of the torque with a friction taken out judges them on the whole torque instead
    (``lugre_identify.whole_torque_warnings``)."""
    if unit_factor(getattr(fit, "torque_ratio", ())) is not None:
        return []
    loaded, out = [f.name or "a recording" for f in loaded if f.mass > 0], []
    for j, (r2, r2_ols) in enumerate(zip(fit.training_r2, fit.training_r2_ols)):
        if r2 >= MIN_TRAINING_R2:
            continue
        label, k = joint_label(j, robot), j + 1
        if r2_ols >= MIN_TRAINING_R2 and loaded:
            cause = (
                f"the unconstrained fit explains {r2_ols:.0%}: one arm fitted across recordings that carry different "
                f"loads is unphysical, and {', '.join(loaded)} looks loaded (said below). State each recording's "
                "payload (A.payload.json or a configurations.toml) and identify again"
            )
        elif r2_ols >= MIN_TRAINING_R2:
            cause = (
                f"the unconstrained fit explains {r2_ols:.0%}: the data ask for an unphysical model. Torque sign or "
                f"joint mapping wrong? Check the sign of tau{k} (or i{k}) and its joint"
            )
        else:
            cause = (
                f"the unconstrained fit only {max(r2_ols, 0.0):.0%}: tau{k} does not look like the torque of {label}. "
                "Joint mapping wrong (columns swapped)? Check the column order, the units and the robot file"
            )
        share = f"only {r2:.0%}" if r2 > 0 else "none"
        out.append(
            f"{label}: the identified model explains {share} of the variance of tau{k} on the recordings it was "
            f"fitted to (R^2 = {r2:.3g}), {cause}."
        )
    return out


def fit_warnings(robot, fit, loaded=()) -> tuple:
    """Warnings (str) on a ``TrajectoryFit`` of ``robot`` that point at a wrong recording (module docstring);
    ``loaded``: the training recordings that look loaded against the others (``configuration_check``)."""
    return tuple(
        fit_quality_warnings(robot, fit, loaded)
        + _friction_warnings(robot, fit)
        + _drive_inertia_warnings(fit)
        + _mass_warnings(robot, fit)
        + [r.message(Path(robot.urdf_path or "").name) for r in getattr(robot, "replaced_inertias", ())]
        + _envelope_warnings(fit)
    )


def torque_ratio(robot, model, equations, x_ols) -> tuple:
    """Per joint, the RMS of the unconstrained fit's rigid-body torque over the robot file's, on the same rows."""
    if robot.links is None:
        return ()
    prior, fitted = np.zeros(equations.n_columns), np.zeros(equations.n_columns)
    prior[: model.n_base] = model.base_parameters(robot.nominal_dynamic_parameters())
    fitted[: model.n_base] = x_ols[: model.n_base]
    energy = [np.einsum("c,ncd,d->n", x, equations.gram, x) for x in (fitted, prior)]
    return tuple(np.sqrt(np.maximum(energy[0], 0.0) / np.maximum(energy[1], 1e-300)).tolist())
