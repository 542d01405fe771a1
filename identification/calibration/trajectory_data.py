"""Ordinary recordings made ready for identification: filtered, differentiated, decimated, as normal equations.

Most users calibrate from one or a few exciting trajectories with joint torques (or motor currents
and torque constants), not from the paper's four experiments. This module turns such recordings
into what a linear fit needs, with memory that does not grow with the recording's length:

- :func:`choose_filter` picks the low-pass cutoff and the decimation from the sampling rate (the
  choice is stated in the result): an 8th-order zero-phase Butterworth at ``min(10 Hz, rate / 10)``
  keeps the joint motion of excitation trajectories (a few Hz at most) and removes the noise that
  differentiating twice would amplify; after it, samples are kept at about ten times the cutoff.
- :func:`prepare_recording` applies it to q and the torque alike (so both see the same phase and
  gain), differentiates q by central differences and drops ``filter_choice.EDGE_PERIODS`` filter periods at each end
  (a model file's own number when it is judged: ``model_preparation``).
- :class:`NormalEquations` accumulates, per joint, ``A_j^T A_j``, ``A_j^T y_j`` and ``y_j^T y_j``
  of the rows ``tau_j = A_j x`` in chunks of samples: the regressor of an hour at 1 kHz is never held.

The columns ``A`` are the PSDM base-parameter regressor followed by the drive columns of
:func:`drive_columns` (Coulomb and viscous friction, optional Stribeck static friction and offset,
and the drive inertia of the joints whose model has none).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from identification.data.excitation_check import check_joint_motion
from identification.data.filter_choice import EDGE_PERIODS, choose_filter, edge_samples, kept_samples
from identification.data.plausibility import check_plausible_recording, check_torque_magnitude
from identification.data.preprocessing import central_difference, resample_uniform, zero_phase_filter
from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, RecordingError

__all__ = ["DRIVE_TERMS", "FRICTION_TERMS", "NormalEquations", "choose_filter", "drive_column_joint",
           "drive_column_names", "drive_columns", "drive_offset", "file_shape", "fit_shape", "friction_shapes",
           "friction_term", "prepare_recording", "prepare_recordings", "samples_text", "stribeck_derivative",
           "stribeck_joints", "viscous_column"]  # fmt: skip

#: The friction terms a joint may carry, in column order: Coulomb, static (Stribeck), viscous, torque offset.
FRICTION_TERMS = ("fc", "fs", "fv", "offset")
#: The drive terms: the friction terms, then the drive inertia.
DRIVE_TERMS = (*FRICTION_TERMS, "Ia")


MOTION_FIX = "record a trajectory that moves {joints} over more of its range and speed ('psdm excite' designs one)"
CHUNK_SAMPLES = 4000


def prepare_recording(
    recording: Recording, kt=None, cutoff_hz: float | None = None, edge_periods: float = EDGE_PERIODS
) -> tuple[Recording, float, int]:
    """Filter q and the joint torque alike, differentiate, trim ``edge_periods`` filter periods at each end, decimate.

    Returns the prepared recording (``tau`` is the joint torque, ``kt * current`` when only currents
    were recorded), the cutoff [Hz] and the decimation step used.
    """
    rec = recording if recording.is_uniform(1e-6) else resample_uniform(recording)
    rate = 1.0 / rec.dt
    cutoff, step = choose_filter(rate, cutoff_hz)
    rec.joint_torque(kt, 0)  # refuses currents without torque constants before any work
    keep = kept_samples(rec.n_samples, rate, cutoff, step, edge_periods)
    # one joint at a time, only its kept samples stored: the full-rate filtered signals and derivatives are one
    # column long (an hour at 1 kHz is not held four times over); the values are those of the whole arrays
    kept = {name: np.empty((len(range(*keep.indices(rec.n_samples))), rec.n_dof)) for name in ("q", "qd", "qdd", "tau")}
    for j in range(rec.n_dof):
        q = zero_phase_filter(rec.q[:, j], rate, cutoff)
        kept["tau"][:, j] = zero_phase_filter(rec.joint_torque(kt, j), rate, cutoff)[keep]
        qd, qdd = central_difference(rec.t, q)
        kept["q"][:, j], kept["qd"][:, j], kept["qdd"][:, j] = q[keep], qd[keep], qdd[keep]
    if kept["q"].shape[0] < 3:
        edge = edge_samples(rate, cutoff, edge_periods)
        raise RecordingError(
            f"{rec.name or 'recording'}: {rec.duration:.3g} s is too short to filter at {cutoff:g} Hz and keep "
            f"samples; record at least {4 * edge / rate:.2g} s."
        )
    prepared = Recording(t=rec.t[keep], name=rec.name, missing_torque=rec.missing_torque, **kept)
    return prepared, cutoff, step


def prepare_recordings(
    robot, recordings, kt=None, cutoff_hz: float | None = None, edge_periods=EDGE_PERIODS, torque_constants=None
) -> tuple:
    """(cutoffs, decimation steps, prepared recordings): each recording checked against ``robot``, then prepared
    (``prepare_recording``).

    ``torque_constants`` (n_dof,): what makes a prepared current the joint torque for the torque-scale check where
    ``kt`` leaves it in amperes (the fleet's ``kt = 1``: it refits the robot file's kt and passes those); by default
    the prepared torque is the joint torque already (``kt`` times the current, or the recorded torque).

    Raises
    ------
    RecordingError
        For a recording of another robot, one in the wrong units (``plausibility.check_plausible_recording``), one
        whose torque is off the robot file's by the same large factor on most joints (``plausibility.
        check_torque_magnitude``: a torque constant without its gear ratio, a torque unit), or one in which a joint
        barely moves (naming it and the fix).
    """
    cutoffs, steps, prepared = [], [], []
    for rec in recordings:
        rec.check_robot(robot.n_dof, robot.name)
        check_plausible_recording(rec, robot)
        check_joint_motion(rec, range(robot.n_dof), robot=robot, purpose="identification from exciting trajectories",
                           fix=MOTION_FIX)  # fmt: skip
        ready, cutoff, step = prepare_recording(rec, kt, cutoff_hz, edge_periods)
        check_torque_magnitude(ready, robot, currents=rec.tau is None, torque_constants=torque_constants)
        cutoffs.append(cutoff)
        steps.append(step)
        prepared.append(ready)
    return cutoffs, steps, prepared


def drive_column_names(n_dof: int, terms: tuple, inertia_joints) -> list:
    """Labels of the drive columns, e.g. ``fc1, fv1, fc2, ...``, then ``Ia<j>`` for ``inertia_joints``."""
    names = [f"{term}{j + 1}" for j in range(n_dof) for term in terms if term != "Ia"]
    return names + [f"Ia{j + 1}" for j in inertia_joints]


def drive_column_joint(name: str) -> int:
    """The joint (0-based) of a drive column labelled by ``drive_column_names``: ``fc3`` -> 2, ``Ia1`` -> 0."""
    return int(name[len(name.rstrip("0123456789")) :]) - 1


def drive_offset(values, names, joint: int, required: bool = False) -> float:
    """[N m] the torque offset of the 0-based ``joint`` among drive ``values`` labelled ``names`` (a fit's drive
    parameters, a model file's drive block): the value of its column ``offset<joint + 1>``, 0 where there is none or
    its value is null (a model file writes a value it does not state as null). ``required``: a caller that reads an
    offset the fit chose, where no column is an error (ParameterError naming the columns), not an offset of 0."""
    names, name = list(names), f"offset{joint + 1}"
    if required and name not in names:
        raise ParameterError(f"drive_offset: no column {name} among the drive columns {names}; the offset of joint "
                             f"{joint + 1} was to be read from the fit.")  # fmt: skip
    value = values[names.index(name)] if name in names else None
    return 0.0 if value is None else float(value)


def _is_symbolic(*values) -> bool:
    return any(isinstance(v, (ca.SX, ca.MX)) for v in values)


def _symbolic_width(coulomb_velocity, symbolic: bool):
    """The width as the expression divides by it: a per-joint array as a CasADi column beside CasADi velocities."""
    if symbolic and np.ndim(coulomb_velocity) > 0:
        return ca.DM(np.asarray(coulomb_velocity, dtype=float).reshape(-1, 1))
    return coulomb_velocity


def friction_term(term: str, qd, coulomb_velocity, stribeck_velocity=None, viscous_exponent=None):
    """The column of one friction term at velocities ``qd`` (numbers, arrays or CasADi expressions alike).

    ``coulomb_velocity`` [rad/s]: a number, or one per joint along the last axis of ``qd`` (a CasADi column: along it).
    ``fc``: the smooth sign ``s = tanh(qd / coulomb_velocity)``; ``fv``: ``qd``, or with a ``viscous_exponent`` ``dv``
    the viscous power law (:func:`viscous_column`); ``offset``: 1. With a
    Stribeck velocity ``vs`` (the Stribeck shape), the friction ``(fc + (fs - fc) g) s + fv qd`` with
    ``g = exp(-(qd / vs)^2)`` is linear in ``fc`` and ``fs``: ``fc`` has the column ``(1 - g) s`` and
    ``fs`` the column ``g s``. A joint whose ``vs`` is 0 has no Stribeck hump (``g = 0``: the Coulomb-viscous
    shape, its ``fs`` column zero), so one model holds joints of both shapes (``column_choice`` chooses per joint).
    The one definition the fit (:func:`drive_columns`), the calibrated model's ``predict`` and the exported code
    (``codegen.calibrated``) share.
    """
    if term in ("fc", "fs"):
        symbolic = _is_symbolic(qd, stribeck_velocity)
        sign = (ca.tanh if symbolic else np.tanh)(qd / _symbolic_width(coulomb_velocity, symbolic))
        if stribeck_velocity is None:
            if term == "fs":
                raise ParameterError("friction_term: the term 'fs' needs stribeck_velocity [rad/s]; got None.")
            return sign
        bump = _stribeck_bump(qd, stribeck_velocity, symbolic)
        return sign * (bump if term == "fs" else 1.0 - bump)
    if term == "fv":
        return qd if viscous_exponent is None else viscous_column(qd, viscous_exponent, coulomb_velocity)
    if term == "offset":
        return 1.0 + 0.0 * qd
    raise ParameterError(f"friction_term.term must be one of {FRICTION_TERMS}; got {term!r}.")


def viscous_column(qd, exponent, coulomb_velocity):
    """The paper's viscous power law ``|qd|^dv sign(qd)`` (eq. 14), smoothed below the Coulomb smoothing velocity
    ``v`` as ``qd (qd^2 + v^2)^((dv - 1) / 2)`` (the same beyond a few ``v``, with a finite slope at rest: the exported
    code's derivatives stay finite); ``qd`` where ``exponent`` is 1. ``exponent``: a number (with numbers, arrays or
    CasADi expressions) or one per joint along the last axis of ``qd``; ``coulomb_velocity`` likewise."""
    if np.ndim(exponent) == 0 and float(exponent) == 1.0:
        return qd
    dv = float(exponent) if np.ndim(exponent) == 0 else np.asarray(exponent, dtype=float)
    v = _symbolic_width(coulomb_velocity, _is_symbolic(qd))
    return qd * (qd**2 + v**2) ** ((dv - 1.0) / 2.0)


def file_shape(drive: dict) -> tuple:
    """(Stribeck velocities, viscous exponents), each an array per joint or None, of a model file's ``drive`` block:
    the shape arguments of :func:`drive_columns` (a file without ``viscous_exponent`` is linear viscous)."""
    vs, dv = drive.get("stribeck_velocity") or None, drive.get("viscous_exponent") or None
    return tuple(None if v is None else np.asarray(v, dtype=float) for v in (vs, dv))


def fit_shape(fit) -> tuple:
    """(Stribeck velocities, viscous exponents) of a ``TrajectoryFit``, as :func:`file_shape`."""
    vs, dv = fit.stribeck_velocity or None, getattr(fit, "viscous_exponent", ()) or None
    return tuple(None if v is None else np.asarray(v, dtype=float) for v in (vs, dv))


def _stribeck_bump(qd, stribeck_velocity, symbolic: bool):
    """``g = exp(-(qd / vs)^2)``, and 0 where ``vs`` is 0 (no Stribeck hump on that joint)."""
    if symbolic:
        if not isinstance(stribeck_velocity, (ca.SX, ca.MX)) and float(stribeck_velocity) == 0.0:
            return 0.0 * qd
        return ca.exp(-((qd / stribeck_velocity) ** 2))
    vs = np.asarray(stribeck_velocity, dtype=float)
    hump = vs > 0
    return np.where(hump, np.exp(-((qd / np.where(hump, vs, 1.0)) ** 2)), 0.0)


def friction_shapes(terms, stribeck_velocity, n_dof: int) -> list:
    """The friction shape of each joint of a fit with friction ``terms``: ``"stribeck"`` where it has a Stribeck
    velocity, else ``"coulomb-viscous"`` (``column_choice`` chooses it per joint; ``drive.friction_shapes`` of the
    calibrated-model file)."""
    if "fs" not in terms:
        return ["coulomb-viscous"] * n_dof
    return ["stribeck" if float(v) > 0 else "coulomb-viscous" for v in stribeck_velocity]


def stribeck_joints(terms, stribeck_velocity) -> tuple | None:
    """The joints (0-based) of the Stribeck shape of a fit with friction ``terms``: those with a Stribeck velocity
    (``TrajectoryOptions.stribeck_joints``); None (every joint) when all have one, or without ``"fs"``."""
    vs = [float(v) for v in stribeck_velocity or []]
    return None if "fs" not in terms or all(v > 0 for v in vs) else tuple(j for j, v in enumerate(vs) if v > 0)


def stribeck_derivative(qd, coulomb_velocity, stribeck_velocity):
    """``d/d vs`` of the Stribeck column ``g s`` (:func:`friction_term`): ``g s 2 qd^2 / vs^3`` (0 where ``vs`` is 0:
    that joint's velocity is not fitted), numpy."""
    vs = np.asarray(stribeck_velocity, dtype=float)
    safe = np.where(vs > 0, vs, 1.0)
    return friction_term("fs", qd, coulomb_velocity, vs) * 2.0 * qd**2 / safe**3


def drive_columns(
    qd, qdd, terms: tuple, inertia_joints, coulomb_velocity, stribeck_velocity=None, viscous_exponent=None
):
    """Drive columns (n_samples, n_dof, k): per joint its friction terms, then the listed drive inertias.

    The Coulomb column is the smooth sign ``tanh(qd / coulomb_velocity)`` (a width [rad/s] for every joint, or one
    per joint, ``coulomb_width``); with ``stribeck_velocity``
    (n_dof,) [rad/s] the Coulomb and static columns are the Stribeck shape's, with ``viscous_exponent`` (n_dof,) the
    viscous column the power law (:func:`friction_term`).
    """
    n_samples, n_dof = qd.shape
    per_joint = [term for term in terms if term != "Ia"]
    k = len(per_joint) * n_dof + len(inertia_joints)
    out = np.zeros((n_samples, n_dof, k))
    vs = None if stribeck_velocity is None or "fs" not in terms else np.asarray(stribeck_velocity, dtype=float)
    for c, term in enumerate(per_joint):
        column = friction_term(term, qd, coulomb_velocity, vs, viscous_exponent)
        out[:, range(n_dof), [j * len(per_joint) + c for j in range(n_dof)]] = column
    for c, j in enumerate(inertia_joints):
        out[:, j, len(per_joint) * n_dof + c] = qdd[:, j]
    return out


def samples_text(counts) -> str:
    """``"N samples"`` of a fit whose joints have ``counts`` (``NormalEquations.count``) rows: N the samples it used
    (the most any joint has), and each joint with fewer (a recording's rows without its torque left out) with its
    own count, e.g. ``"986 samples (joint 1: 461)"``."""
    counts = [int(c) for c in np.ravel(counts)]
    most = max(counts, default=0)
    fewer = [f"joint {j + 1}: {c}" for j, c in enumerate(counts) if c < most]
    return f"{most} samples" + (f" ({', '.join(fewer)})" if fewer else "")


@dataclass
class NormalEquations:
    """Per-joint sums of a linear model's rows: ``gram[j] = A_j^T A_j``, ``moment[j] = A_j^T y_j``, ``y_j^T y_j``
    (``energy``), the row count and ``sum(y_j)`` (``total``)."""

    n_dof: int
    n_columns: int
    gram: np.ndarray = field(init=False)
    moment: np.ndarray = field(init=False)
    energy: np.ndarray = field(init=False)
    count: np.ndarray = field(init=False)
    total: np.ndarray = field(init=False)

    def __post_init__(self):
        self.gram = np.zeros((self.n_dof, self.n_columns, self.n_columns))
        self.moment = np.zeros((self.n_dof, self.n_columns))
        self.energy = np.zeros(self.n_dof)
        self.count = np.zeros(self.n_dof, dtype=int)
        self.total = np.zeros(self.n_dof)

    def add(self, columns: np.ndarray, tau: np.ndarray) -> None:
        """Add rows: ``columns`` (n_samples, n_dof, n_columns), ``tau`` (n_samples, n_dof).

        A NaN torque (a joint whose torque the recording does not measure: ``Recording.missing_torque``) leaves
        that joint's row out; the other joints' rows of the sample count.
        """
        self.add_per_joint(np.ascontiguousarray(columns.transpose(1, 0, 2)), tau)

    def add_per_joint(self, per_joint: np.ndarray, tau: np.ndarray) -> None:
        """:meth:`add` of the columns laid out per joint, ``per_joint`` (n_dof, n_samples, n_columns) C-contiguous
        (the layout of the BLAS products; a caller that builds its rows in it saves the transposed copy)."""
        measured = np.isfinite(tau)
        if not measured.all():
            tau = np.where(measured, tau, 0.0)
            per_joint = per_joint * measured.T[:, :, None]
        self.gram += np.matmul(per_joint.transpose(0, 2, 1), per_joint)
        self.moment += np.einsum("nsc,ns->nc", per_joint, tau.T)
        self.energy += np.einsum("sn,sn->n", tau, tau)
        self.count += measured.sum(axis=0)
        self.total += tau.sum(axis=0)

    def add_recording(
        self,
        model,
        recording: Recording,
        terms,
        inertia_joints,
        coulomb_velocity,
        extra=None,
        stribeck=None,
        viscous=None,
    ) -> None:
        """Add a prepared recording's rows: the base-parameter regressor, the drive columns (Stribeck velocities
        ``stribeck`` and viscous exponents ``viscous``, :func:`drive_columns`) and the ``extra`` columns (an object
        with ``columns(q, qd, qdd)``, e.g. ``findings.FindingColumns``), in chunks."""
        for start in range(0, recording.n_samples, CHUNK_SAMPLES):
            sl = slice(start, start + CHUNK_SAMPLES)
            q, qd, qdd = recording.q[sl], recording.qd[sl], recording.qdd[sl]
            drive = drive_columns(qd, qdd, terms, inertia_joints, coulomb_velocity, stribeck, viscous)
            blocks = [model.regressor(q, qd, qdd), drive]
            if extra is not None:
                blocks.append(extra.columns(q, qd, qdd))
            self.add(np.concatenate(blocks, axis=2), recording.tau[sl])

    def subset(self, columns) -> NormalEquations:
        """The normal equations of the listed columns only (same rows)."""
        columns = np.asarray(columns, dtype=int)
        out = NormalEquations(self.n_dof, columns.size)
        out.gram = self.gram[:, columns][:, :, columns].copy()
        out.moment = self.moment[:, columns].copy()
        out.energy, out.count, out.total = self.energy.copy(), self.count.copy(), self.total.copy()
        return out

    def weighted(self, weights) -> tuple[np.ndarray, np.ndarray, float]:
        """``(A^T W A, A^T W y, y^T W y)`` with one weight per joint (``1 / sigma_j^2``)."""
        w = np.asarray(weights, dtype=float)
        return (np.einsum("n,ncd->cd", w, self.gram), np.einsum("n,nc->c", w, self.moment), float(w @ self.energy))

    def residual_sum(self, x) -> np.ndarray:
        """Per joint ``||A_j x - y_j||^2`` of a parameter vector ``x``."""
        x = np.asarray(x, dtype=float)
        return np.einsum("c,ncd,d->n", x, self.gram, x) - 2 * self.moment @ x + self.energy

    def r2(self, x) -> np.ndarray:
        """Per joint, the coefficient of determination of the parameters ``x`` on the rows (1 - residual / variance)."""
        variance = self.energy - self.total**2 / np.maximum(self.count, 1)
        return 1.0 - self.residual_sum(x) / np.maximum(variance, 1e-300)
