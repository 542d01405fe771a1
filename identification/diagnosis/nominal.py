"""The nominal model a diagnosis starts from: the robot file's rigid body (or a re-identified one) plus per-joint
friction.

Rigid-body choices (``DiagnosisOptions.rigid_body``): ``"auto"`` (default) starts from the prior and switches to the
identified rigid body when a full recalibration beats a payload- or inertia-type finding (``rigid_body_choice``);
the two underlying ones:

- ``"prior"``: the inertial parameters of the robot file are kept; only friction is fitted.
  Effects that change base parameters (payload, rotor inertia, a tilted base) stay visible as
  a mismatch against the robot file, which is what a diagnosis is for.
- ``"identified"``: the PSDM base parameters are fitted together with friction by least squares.
  Payload, rotor inertia and most of a gravity tilt are then absorbed into the base parameters and
  are not reported as missing physics.

Friction (``DiagnosisOptions.friction``), per joint and linear in its amplitudes:

- ``"lugre"`` (what the default ``"auto"`` takes unless the drives state no friction, ``nominal_friction``): the
  steady-state LuGre curve of the paper (eq. 14 at zdot = 0), ``fc s + (fs - fc) exp(-(qd/vs)^2) s + fv |qd|^dv s``
  with ``s = sign(qd)``, the shape values ``vs`` and ``dv`` from the robot file's drives (``vs = 0.01``, ``dv = 1``
  without drives). The bristle dynamics (pre-sliding) are not modelled in the diagnosis.
- ``"coulomb_viscous"``: ``fc s + fv qd``; with a model file's viscous power law (``DiagnosisOptions.viscous_power``)
  ``fc s + fv |qd|^dv s`` on a joint whose drive states ``dv != 1``.
- ``"stribeck"``: the steady-state curve of ``"lugre"`` alone (no bristle-dynamics columns), the shape of a
  calibrated model identified with ``--friction stribeck`` (its ``vs`` in the drives ``calibrated_robot`` builds).
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from identification.calibration.coulomb_width import joint_width
from identification.data.torque_constants import drive_kt
from identification.diagnosis.candidates.base import SMOOTH_VELOCITY
from identification.diagnosis.columns import BlockColumns
from identification.diagnosis.context import lugre_parameters, simulate_friction
from psdm_casadi.errors import ParameterError

FRICTION_MODELS = ("lugre", "coulomb_viscous", "stribeck")
STRIBECK_SHAPED = ("lugre", "stribeck")  # three columns per joint: fc, (fs - fc) exp(-(qd/vs)^2), fv
RIGID_BODY_CHOICES = ("auto", "prior", "identified")

logger = logging.getLogger(__name__)


def nominal_friction(robot) -> str:
    """The ``"auto"`` nominal friction of a robot file: the LuGre shape of its drives, or Coulomb + viscous when its
    drives state torque constants but no friction (no Stribeck velocity to take, and none the data can fix on a joint
    that never slows down); a robot without drives keeps the steady-state LuGre."""
    if robot.drives is None or all(drive.fc > 0 for drive in robot.drives):
        return "lugre"
    logger.info("diagnose: the robot file's drives state no friction: nominal friction Coulomb + viscous")
    return "coulomb_viscous"


def torque_constants_only(robot, options) -> tuple:
    """(robot, options) for a robot file whose drives give torque constants but no friction prior (``fc`` 0).

    The drives' LuGre friction is the nominal model's prior and its bristle dynamics; without a Coulomb level
    there is none. The torque constants are kept (``options.torque_constants``, for recordings of currents) and
    the drives left out, so the friction is identified from the recordings as for a robot without drives.
    """
    if robot.drives is None or all(d.fc > 0 for d in robot.drives):
        return robot, options
    logger.info("diagnose: the robot file's drives give torque constants but no friction prior (fc = 0): the "
                "friction is identified from the recordings alone")  # fmt: skip
    kt = options.torque_constants if options.torque_constants is not None else tuple(drive_kt(robot).tolist())
    return replace(robot, drives=None), replace(options, torque_constants=kt)


def linear_viscous_unless_stated(robot, options):
    """``robot`` with viscous exponents 1 for a Coulomb-viscous nominal, unless the options keep a model file's viscous
    power law (``DiagnosisOptions.viscous_power``): a robot file's LuGre ``dv`` is the paper's curve, not a request
    for a power law in the Coulomb + viscous shape."""
    if options.friction != "coulomb_viscous" or options.viscous_power or robot.drives is None:
        return robot
    if all(d.dv == 1.0 for d in robot.drives):
        return robot
    return replace(robot, drives=tuple(replace(d, dv=1.0) for d in robot.drives))


def friction_shapes(robot) -> tuple[np.ndarray, np.ndarray]:
    """Stribeck velocities vs [rad/s] and viscous exponents dv per joint from the robot file."""
    if robot.drives is None:
        return np.full(robot.n_dof, 0.01), np.ones(robot.n_dof)
    return (np.array([d.vs for d in robot.drives], dtype=float), np.array([d.dv for d in robot.drives], dtype=float))


def friction_feature_names(kind: str, n_dof: int) -> list:
    per = ("fc", "fs_minus_fc", "fv") if kind in STRIBECK_SHAPED else ("fc", "fv")
    return [f"{name}_{j + 1}" for j in range(n_dof) for name in per]


def friction_columns(kind: str, qd: np.ndarray, vs: np.ndarray, dv: np.ndarray, sign=None) -> np.ndarray:
    """Friction columns (n_samples, n_dof, n_dof * k), joint-major, k = 3 (lugre) or 2.

    ``sign`` (n_samples, n_dof) is the velocity sign to use; default the smooth ``tanh(qd / SMOOTH_VELOCITY)``.
    """
    if kind not in FRICTION_MODELS:
        raise ParameterError(f"DiagnosisOptions.friction must be one of {FRICTION_MODELS}; got {kind!r}.")
    n_samples, n = qd.shape
    s = np.tanh(qd / SMOOTH_VELOCITY) if sign is None else sign
    if kind in STRIBECK_SHAPED:
        per = [s, np.exp(-((qd / vs) ** 2)) * s, np.abs(qd) ** dv * s]
    else:  # a joint of the drives' viscous power law (dv != 1: a model file's, ``viscous_power``) keeps it
        per = [s, np.where(dv == 1.0, qd, np.abs(qd) ** dv * s)]
    k = len(per)
    out = np.zeros((n_samples, n, n * k))
    for j in range(n):
        for c, values in enumerate(per):
            out[:, j, j * k + c] = values[:, j]
    return out


def filtered_friction_columns(robot, kind: str, context) -> np.ndarray:
    """The nominal friction columns of a recording as the measured torque sees them, (n_samples, n_dof, p).

    With a LuGre prior (``context.filtered_friction``, the robot file's drives) the columns
    (``friction_columns`` with the exact velocity sign) and, for ``"lugre"``, the bristle-dynamics columns
    (``lugre_dynamic_columns``) are evaluated at full rate on the recorded velocity and low-pass filtered
    like the recording before decimation (``DiagnosisContext.lowpass``): the recorded torque holds the
    filtered friction steps, not sharp ones at the filtered velocity's zero. Without a prior the smooth-sign
    columns of the filtered velocity are used (see ``context``). The dense form of ``friction_blocks``.
    """
    return friction_blocks(robot, kind, context).dense()


def joint_friction_columns(robot, kind: str, joint: int) -> list:
    """The columns (0-based, in the layout of ``friction_blocks``) of joint ``joint``'s nominal friction: its
    ``friction_columns``, then its bristle-dynamics column with a LuGre prior (``"lugre"`` and the robot's drives)."""
    n, k = robot.n_dof, 3 if kind in STRIBECK_SHAPED else 2
    return list(range(joint * k, (joint + 1) * k)) + ([n * k + joint] if kind == "lugre" and robot.drives else [])


def friction_blocks(robot, kind: str, context, held: tuple = (), own=None) -> BlockColumns:
    """``filtered_friction_columns`` as ``BlockColumns``, built one column at a time: each full-rate column of a
    joint (n_full,) is filtered and decimated before the next, never the whole (n_full, n_dof, p). The friction of
    the ``held`` joints (0-based: a model file's held friction, ``DiagnosisOptions.held_friction``) is no column of
    the fit: theirs stay in the layout, zero. ``own``: a model file's friction (``file_friction.FileFriction``), whose
    own columns are taken instead on its steady-state joints, on the context's samples as the file predicts them (its
    LuGre joints keep these columns)."""
    n = robot.n_dof
    if own is not None:
        lugre = friction_blocks(robot, kind, context, held).dense() if own.lugre_joints else None
        return BlockColumns.from_dense(own.columns(context.qd, lugre, [j for j in range(n) if j not in held]))
    vs, dv = friction_shapes(robot)
    dynamic = kind == "lugre" and robot.drives is not None
    if not context.filtered_friction:  # the sign smoothed as the model file predicts it (``coulomb_velocity``)
        out = friction_columns(kind, context.qd, vs, dv, np.tanh(context.qd / context.coulomb_velocity))
        if dynamic:
            out = np.concatenate([out, lugre_dynamic_columns(robot, context)], axis=2)
        for j in held:
            out[:, j, joint_friction_columns(robot, kind, j)] = 0.0
        return BlockColumns.from_dense(out)
    index, values = [], []
    for j in range(n):
        index.append([] if j in held else joint_friction_columns(robot, kind, j))
        block = np.empty((context.n_samples, len(index[-1])))
        columns = () if j in held else _joint_friction_columns(robot, kind, context, j, dynamic)
        for c, column in enumerate(columns):
            block[:, c] = context.lowpass(column)  # one full-rate column at a time
        values.append(block)
    return BlockColumns(n * len(joint_friction_columns(robot, kind, 0)), tuple(index), tuple(values))


def _joint_friction_columns(robot, kind: str, context, j: int, dynamic: bool):
    """The full-rate friction columns of joint ``j`` (n_full,) with the exact velocity sign, one after the other
    in the order of ``friction_columns``, then its bristle-dynamics column when ``dynamic``."""
    vs, dv = friction_shapes(robot)
    qd = context.full_qd[:, j]
    sign = np.sign(qd)
    yield sign
    if kind in STRIBECK_SHAPED:
        yield np.exp(-((qd / vs[j]) ** 2)) * sign
        yield np.abs(qd) ** dv[j] * sign
    else:
        yield qd if dv[j] == 1.0 else np.abs(qd) ** dv[j] * sign
    if dynamic:
        yield _lugre_dynamic_full(robot, context, j)


def _lugre_dynamic_full(robot, context, j: int) -> np.ndarray:
    """Bristle-dynamics part of joint ``j``'s LuGre friction at full rate (n_full,): the simulated friction minus
    its steady-state curve."""
    p = lugre_parameters(robot.drives[j])
    qd = context.full_qd[:, j]
    tau = simulate_friction(p, context.full_t, qd)
    steady = (p.fc + (p.fs - p.fc) * np.exp(-((qd / p.vs) ** 2))) * np.sign(qd) + p.fv * np.abs(qd) ** p.dv * np.sign(
        qd
    )
    return tau - steady


def lugre_dynamic_columns(robot, context) -> np.ndarray | None:
    """Bristle-dynamics part of the robot file's LuGre friction along the recording, one column per joint.

    The LuGre model (paper eqs. 12-14) with the drive parameters of the robot file is simulated on the
    full-rate velocity; its steady-state curve is subtracted, leaving the pre-sliding and damping
    transients around reversals. The fit scales each joint's column freely. None without drives.
    (Unfiltered; ``filtered_friction_columns`` filters them like the recording.)
    """
    if robot.drives is None:
        return None
    n = robot.n_dof
    out = np.zeros((context.n_samples, n, n))
    for j in range(n):
        out[:, j, j] = _lugre_dynamic_full(robot, context, j)[context.keep]
    return out


def friction_casadi(kind: str, qd, coefficients, vs, dv, smooth=SMOOTH_VELOCITY):
    """Friction torque (SX, n_dof) of fitted coefficients (joint-major as ``friction_columns``), the sign smoothed over
    ``smooth`` [rad/s] (one width, or one per joint)."""
    import casadi as ca

    n = qd.shape[0]
    out = ca.SX.zeros(n)
    k = 3 if kind in STRIBECK_SHAPED else 2
    for j in range(n):
        s = ca.tanh(qd[j] / joint_width(smooth, j))
        c = coefficients[j * k : (j + 1) * k]
        if kind in STRIBECK_SHAPED:
            out[j] = c[0] * s + c[1] * ca.exp(-((qd[j] / vs[j]) ** 2)) * s + c[2] * ca.power(ca.fabs(qd[j]), dv[j]) * s
        else:
            out[j] = c[0] * s + c[1] * (qd[j] if dv[j] == 1.0 else ca.power(ca.fabs(qd[j]), dv[j]) * s)
    return out
