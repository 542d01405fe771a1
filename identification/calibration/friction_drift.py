"""Friction that changed between the training recordings: the per-recording check, the drift it names, the friction
the model keeps.

``psdm identify --data A B C`` fits one friction per joint over every recording. A gearbox warming up over a session,
or wear between days, changes a joint's friction between recordings: the shared fit's friction is their average, wrong
on each, and what the friction columns cannot follow leaks into the rigid body. The check is one linear least squares
on the recordings as the fit prepares them (known payloads taken off):

1. the rigid body, the torque offsets, the drive inertias and any unknown payload are shared; each joint's friction
   columns, in the shape the fit chose (Coulomb or Stribeck, linear or power-law viscous), are one set per recording
   *segment* (``SEGMENTS`` contiguous parts of each recording); weights ``1 / sigma_j^2`` and the sandwich covariance
   of the correlated residual (``residual_correlation``), as in the fit;
2. per joint, how far its friction moves between the segments of one recording beyond their covariance (a Wald
   statistic over its degrees of freedom) is the over-dispersion ``phi^2 >= 1``: what the friction shape misses on
   different motions, which a comparison of recordings must not call drift (``fleet.drift`` scales its baselines
   alike);
3. the recordings' friction (their segments tied) is compared by a Wald test, its covariance times ``phi^2``, at the
   family-wise level ``ALPHA`` over the joints (Bonferroni); a change is named only where it also matters: two
   recordings' friction torques differ by at least ``MIN_CHANGE`` of their mean, along the samples of both within the
   speeds both reach (a shape fitted on a faster motion extrapolates differently, which is no drift).

A named drift decides the model's friction (``drift_choice``), and the training torques of the drifting joints are
moved to it before the fit (``drift_correction``), so the rigid body is fitted beside each recording's
own friction and the drift does not leak into the inertial parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from identification.calibration.payload_fit import FlangeBodies, subtract_known_payloads
from identification.calibration.residual_correlation import residual_correlation_time
from identification.calibration.stribeck import base_regressors
from identification.calibration.trajectory_data import (
    CHUNK_SAMPLES,
    NormalEquations,
    drive_column_names,
    drive_columns,
    fit_shape,
)
from identification.calibration.weighted_solve import solve_scaled, weighted_least_squares

__all__ = [
    "ALPHA",
    "MIN_CHANGE",
    "SEGMENTS",
    "DriftCheck",
    "JointFriction",
    "check_friction_drift",
    "finite_list",
    "recording_names",
]

#: Contiguous parts of each recording with friction of their own (the within-recording scatter, step 2).
SEGMENTS = 3
#: Family-wise false-alarm rate of the drift test over the joints.
ALPHA = 0.01
#: The smallest change worth naming: the recordings' friction torques apart by this share of the joint's friction
#: torque (RMS along the training motion).
MIN_CHANGE = 0.10
#: Percentile of each recording's joint speed: two recordings' friction torques are compared up to the smaller one.
REACH = 95.0
#: The friction terms the check gives each recording (the offset and the drive inertia stay shared).
DRIFT_TERMS = ("fc", "fs", "fv")


@dataclass(frozen=True)
class JointFriction:
    """One joint's friction per training recording.

    ``names`` its coefficients (``fc3``, ``fv3``, ...), ``values`` and ``stds`` (recordings, coefficients; NaN for a
    recording that does not measure the joint's torque), the stds grown by the over-dispersion ``phi2``;
    ``statistic`` the Wald statistic of equal friction over its ``dof``, ``p_value`` its tail probability, ``change``
    the largest RMS difference of two recordings' friction torque over that of their mean, where both move (module
    docstring); ``drift`` whether it is named (module docstring)."""

    joint: int
    names: tuple
    values: np.ndarray
    stds: np.ndarray
    phi2: float
    statistic: float
    dof: int
    p_value: float
    change: float
    drift: bool

    def to_dict(self, recordings) -> dict:
        return {
            "joint": self.joint + 1,
            "drift": self.drift,
            "coefficients": {
                n: {"values": finite_list(self.values[:, k]), "stds": finite_list(self.stds[:, k])}
                for k, n in enumerate(self.names)
            },
            "recordings": list(recordings),
            "over_dispersion": self.phi2,
            "wald": self.statistic,
            "dof": self.dof,
            "p_value": self.p_value,
            "change": self.change,
        }

    def sentence(self) -> str:
        """``joint 3: fc3 9.59 +- 0.05 -> 6.71 +- 0.05, fv3 ... (p 1e-09; friction torque 14 % apart)``: the values
        per recording in their order."""
        parts = [f"{name} " + " -> ".join(f"{v:.4g} +- {s:.2g}" if np.isfinite(v) else "- (not measured)"
                                          for v, s in zip(self.values[:, k], self.stds[:, k]))
                 for k, name in enumerate(self.names)]  # fmt: skip
        return f"joint {self.joint + 1}: {', '.join(parts)} (p {self.p_value:.2g}; friction torque " \
               f"{100 * self.change:.0f} % apart)"  # fmt: skip


@dataclass(frozen=True, eq=False)
class DriftCheck:
    """The per-recording friction fit (module docstring): ``joints`` the friction of each joint per recording (in the
    order of ``recordings``), ``x`` the recording-level estimate over ``names`` (rigid body first), the data the
    choice of the kept friction needs (``layout``: the friction columns' indices per joint; ``shape``: the drive
    columns' arguments; ``motions``: each prepared recording's ``(t, qd, qdd)``), and ``reason`` where it was not
    checked; ``preparation`` the ``(cutoff [Hz], edge periods)`` the motions were prepared with."""

    recordings: tuple = ()
    joints: tuple = ()
    x: np.ndarray | None = None
    names: tuple = ()
    layout: dict = field(default_factory=dict)
    shape: tuple = ()
    motions: tuple = ()
    reason: str = ""
    preparation: tuple = (None, 0.0)

    @property
    def drifting(self) -> tuple:
        return tuple(f for f in self.joints if f.drift)


def finite_list(values) -> list:
    """``values`` as a JSON list: None where not finite (a recording that does not measure the joint)."""
    return [float(v) if np.isfinite(v) else None for v in np.ravel(values)]


def recording_names(recordings) -> tuple:
    """The recordings' names as reports give them (``recording <k>`` for one without a name)."""
    return tuple(r.name or f"recording {k + 1}" for k, r in enumerate(recordings))


def _friction_layout(fit, n_dof: int) -> tuple:
    """``(drive names, per joint the indices of its friction columns among them, shared indices)``: the fit's drive
    columns; a static-friction column of a Coulomb-viscous joint (Stribeck velocity 0) and an offset the fit holds
    at 0 are left out."""
    names = drive_column_names(n_dof, fit.friction_terms, fit.inertia_joints)
    vs = fit.stribeck_velocity or (0.0,) * n_dof
    per_joint, shared = [[] for _ in range(n_dof)], []
    for k, name in enumerate(names):
        term = name.rstrip("0123456789")
        joint = int(name[len(term) :]) - 1
        if term == "fs" and vs[joint] == 0:
            continue
        if term in DRIFT_TERMS:
            per_joint[joint].append(k)
        elif term == "Ia" or fit.drive_std[k] > 0:  # an offset held at 0 has no std
            shared.append(k)
    return names, per_joint, shared


def _segments(n_samples: int) -> np.ndarray:
    return np.linspace(0, n_samples, SEGMENTS + 1).astype(int)


def _rows(recording, rigid, extra, setup, segment: int, n_segments: int):
    """The check's rows of one chunk (n, n_dof, columns): rigid body, shared drive columns, the friction of segment
    ``segment`` (of ``n_segments``), then the unknown payloads' columns."""
    fit, per_joint, shared, sl = setup
    vs, dv = fit_shape(fit)
    drive = drive_columns(recording.qd[sl], recording.qdd[sl], fit.friction_terms, fit.inertia_joints,
                          fit.coulomb_velocity, vs, dv)  # fmt: skip
    friction = [k for ks in per_joint for k in ks]
    block = np.zeros((drive.shape[0], drive.shape[1], len(friction) * n_segments))
    block[:, :, segment * len(friction) : (segment + 1) * len(friction)] = drive[:, :, friction]
    parts = [rigid, drive[:, :, shared], block]
    if extra is not None:
        parts.append(extra.columns(recording.q[sl], recording.qd[sl], recording.qdd[sl]))
    return np.concatenate(parts, axis=2)


def _chunks(prepared, regressors, extras, layout):
    """Per recording and chunk ``(segment index, rows, tau)`` of the check (segments cut at their edges; segment
    ``r * SEGMENTS + s`` is part ``s`` of recording ``r``)."""
    n_segments = SEGMENTS * len(prepared)
    for r, (recording, chunks, extra) in enumerate(zip(prepared, regressors, extras)):
        rigid_all = np.concatenate(chunks)
        edges = _segments(recording.n_samples)
        for s, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
            for start in range(a, b, CHUNK_SAMPLES):
                sl = slice(start, min(start + CHUNK_SAMPLES, b))
                rows = _rows(recording, rigid_all[sl], extra, (*layout, sl), r * SEGMENTS + s, n_segments)
                yield r * SEGMENTS + s, rows, recording.tau[sl]


def _solve(equations, sigma, correlation, transform) -> tuple:
    """Weighted least squares of the sub-model ``transform`` (full columns from its own) and its sandwich covariance,
    both in the sub-model's columns."""
    weights = 1.0 / sigma**2
    gram, moment, _ = equations.weighted(weights)
    x, inverse, _ = solve_scaled(transform.T @ gram @ transform, transform.T @ moment)
    middle = transform.T @ equations.weighted(correlation * weights)[0] @ transform
    return x, inverse @ middle @ inverse


def _wald(values, covariance) -> tuple:
    """(statistic, degrees of freedom) of ``values`` = 0 with ``covariance`` (its pseudo-inverse, rank-limited)."""
    inverse = np.linalg.pinv(covariance, rcond=1e-10, hermitian=True)
    rank = int(np.linalg.matrix_rank(covariance, tol=1e-10 * max(float(np.max(np.abs(covariance))), 1e-300)))
    return float(values @ inverse @ values), rank


def _contrasts(n_groups: int, size: int, k: int) -> np.ndarray:
    """Rows ``b_{g,s} - b_{g,0}`` (s = 1..size-1) of ``n_groups`` groups of ``size`` members of ``k`` coefficients."""
    rows = []
    for g in range(n_groups):
        for s in range(1, size):
            for c in range(k):
                row = np.zeros(n_groups * size * k)
                row[(g * size + s) * k + c], row[g * size * k + c] = 1.0, -1.0
                rows.append(row)
    return np.array(rows).reshape(-1, n_groups * size * k)


def check_friction_drift(robot, model, recordings, fit, configurations=None) -> DriftCheck:
    """The per-recording friction check of raw training ``recordings`` with the shape of ``fit`` (module docstring);
    a ``DriftCheck`` with a ``reason`` and no joints for a single recording."""
    from identification.calibration.column_candidates import prepare_training
    from identification.calibration.trajectory_fit import TrajectoryOptions

    names_in = recording_names(recordings)
    if len(recordings) < 2:
        return DriftCheck(recordings=names_in, reason="one training recording: nothing to compare")
    options = TrajectoryOptions(cutoff_hz=None if not fit.cutoff_hz else min(fit.cutoff_hz),
                                edge_periods=fit.edge_periods)  # fmt: skip
    prepared = subtract_known_payloads(robot, list(prepare_training(robot, recordings, options).prepared),
                                       configurations)  # fmt: skip
    if any(r.n_samples < 4 * SEGMENTS for r in prepared):
        return DriftCheck(recordings=names_in, reason="a recording too short to cut into segments")
    n_dof, n_rec = robot.n_dof, len(prepared)
    drive_names, per_joint, shared = _friction_layout(fit, n_dof)
    bodies = FlangeBodies.of(configurations, n_rec)
    extras = bodies.extras(robot) if bodies.n_columns else [None] * n_rec
    regressors = base_regressors(model, prepared)
    friction = [k for ks in per_joint for k in ks]
    n_f, n_seg = len(friction), SEGMENTS * n_rec
    n_columns = model.n_base + len(shared) + n_f * n_seg + bodies.n_columns
    equations = NormalEquations(n_dof, n_columns)
    layout = (fit, per_joint, shared)
    measured = np.zeros((n_seg, n_dof), dtype=int)  # rows per segment and joint (a dead torque channel: none)
    for segment, rows, tau in _chunks(prepared, regressors, extras, layout):
        equations.add(rows, tau)
        measured[segment] += np.isfinite(tau).sum(axis=0)
    sigma, x_seg, _, _ = weighted_least_squares(equations)
    residuals = [[] for _ in range(n_rec)]
    for segment, rows, tau in _chunks(prepared, regressors, extras, layout):
        residuals[segment // SEGMENTS].append(tau - rows @ x_seg)
    correlation = np.max([residual_correlation_time(np.concatenate(parts)) for parts in residuals], axis=0)
    _, cov_seg = _solve(equations, sigma, correlation, np.eye(n_columns))
    # the recording level: a recording's segments tied
    start = model.n_base + len(shared)
    keep = [k for k in range(n_columns) if not start <= k < start + n_f * n_seg]
    n_tied = len(keep) + n_f * n_rec
    tie = np.zeros((n_columns, n_tied))
    tie[keep, np.arange(len(keep))] = 1.0
    for r in range(n_rec):
        for s in range(SEGMENTS):
            for c in range(n_f):
                tie[start + (r * SEGMENTS + s) * n_f + c, len(keep) + r * n_f + c] = 1.0
    x_rec, cov_rec = _solve(equations, sigma, correlation, tie)
    gram = _common_grams(prepared, fit, per_joint)
    joints = []
    for j, columns in enumerate(per_joint):
        if not columns:
            continue
        where = [friction.index(k) for k in columns]
        joints.append(_test_joint(j, columns, drive_names, where, (x_seg, cov_seg, x_rec, cov_rec),
                                  (start, n_f, n_rec, len(keep)), gram[j], measured[:, j], n_dof))  # fmt: skip
    names = tuple([f"theta{k}" for k in range(model.n_base)] + [drive_names[k] for k in shared])
    return DriftCheck(recordings=names_in, joints=tuple(joints), x=x_rec, names=names,
                      layout={"per_joint": per_joint, "shared": shared, "friction": friction, "start": len(keep),
                              "n_base": model.n_base, "drive_names": drive_names},
                      shape=(fit.friction_terms, fit.inertia_joints, fit.coulomb_velocity, *fit_shape(fit)),
                      motions=tuple((r.t, r.qd, r.qdd) for r in prepared),
                      preparation=(options.cutoff_hz, options.edge_periods))  # fmt: skip


def _common_grams(prepared, fit, per_joint) -> list:
    """Per joint, per pair of recordings ``(r, s)``, ``D_j^T D_j / n`` of its friction columns over both recordings'
    samples within the speeds both reach (``|qd_j|`` up to the smaller of their ``REACH`` percentiles): the friction
    torque of coefficients ``b`` there has the mean square ``b^T G b``. Two recordings' friction is compared where both
    move, not where one recording's fit extrapolates its shape."""
    vs, dv = fit_shape(fit)
    drives = [drive_columns(r.qd, r.qdd, fit.friction_terms, fit.inertia_joints, fit.coulomb_velocity, vs, dv)
              for r in prepared]  # fmt: skip
    out = []
    for j, columns in enumerate(per_joint):
        reach = [float(np.percentile(np.abs(r.qd[:, j]), REACH)) for r in prepared]
        grams = {}
        for r in range(len(prepared)):
            for t in range(r + 1, len(prepared)):
                top = min(reach[r], reach[t])
                rows = np.concatenate([drives[k][np.abs(prepared[k].qd[:, j]) <= top][:, j, columns] for k in (r, t)])
                grams[r, t] = rows.T @ rows / max(rows.shape[0], 1)
        out.append(grams)
    return out


def _apart(a, b, gram) -> float:
    """RMS of the friction torque of ``a - b`` over that of their mean, along the samples of ``gram``."""
    mean = 0.5 * (a + b)
    return float(np.sqrt(max((a - b) @ gram @ (a - b), 0.0) / max(float(mean @ gram @ mean), 1e-300)))


def _test_joint(j, columns, drive_names, where, estimates, sizes, gram, measured, n_dof) -> JointFriction:
    """Steps 2-3 of the module docstring for joint ``j`` (its friction columns ``columns``, at ``where`` among the
    friction columns of one segment or recording), over the recordings that measure its torque in every segment
    (``measured``: rows per segment); the others' values are NaN."""
    x_seg, cov_seg, x_rec, cov_rec = estimates
    start, n_f, n_rec, n_kept = sizes
    k = len(columns)
    present = [r for r in range(n_rec) if np.all(measured[r * SEGMENTS : (r + 1) * SEGMENTS] > 0)]
    values, stds = np.full((n_rec, k), np.nan), np.full((n_rec, k), np.nan)
    names = tuple(drive_names[c] for c in columns)
    if len(present) < 2:  # nothing to compare: the measured recording's friction alone
        rec = [n_kept + r * n_f + c for r in present for c in where]
        values[present] = x_rec[rec].reshape(len(present), k)
        stds[present] = np.sqrt(np.clip(np.diag(cov_rec[np.ix_(rec, rec)]), 0.0, None)).reshape(len(present), k)
        return JointFriction(j, names, values, stds, 1.0, 0.0, 0, 1.0, 0.0, False)
    seg = [start + (r * SEGMENTS + s) * n_f + c for r in present for s in range(SEGMENTS) for c in where]
    contrast = _contrasts(len(present), SEGMENTS, k)
    within, dof_within = _wald(contrast @ x_seg[seg], contrast @ cov_seg[np.ix_(seg, seg)] @ contrast.T)
    phi2 = max(1.0, within / max(dof_within, 1))
    rec = [n_kept + r * n_f + c for r in present for c in where]
    own, covariance = x_rec[rec].reshape(len(present), k), phi2 * cov_rec[np.ix_(rec, rec)]
    between = _contrasts(1, len(present), k)
    statistic, dof = _wald(between @ x_rec[rec], between @ covariance @ between.T)
    p_value = float(stats.chi2.sf(statistic, max(dof, 1)))
    change = max(_apart(own[a], own[b], gram[present[a], present[b]]) for a in range(len(present))
                 for b in range(a + 1, len(present)))  # fmt: skip
    drift = p_value < ALPHA / n_dof and change >= MIN_CHANGE
    values[present] = own
    stds[present] = np.sqrt(np.clip(np.diag(covariance), 0.0, None)).reshape(len(present), k)
    return JointFriction(j, names, values, stds, phi2, statistic, dof, p_value, change, bool(drift))
