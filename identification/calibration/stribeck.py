"""Stribeck velocities of the recordings route: the one nonlinear friction parameter, by separable Gauss-Newton.

The Stribeck shape ``(fc + (fs - fc) exp(-(qd/vs)^2)) tanh(qd/eps) + fv qd`` (``trajectory_data.friction_term``)
is linear in ``fc``, ``fs`` and ``fv`` once the Stribeck velocity ``vs`` of each joint is fixed. So
:func:`fit_stribeck_velocity` solves for ``vs`` by variable projection, on per-joint normal equations
of the same columns with each joint's rows scaled by its torque RMS. The base-parameter regressor of
the prepared (filtered, decimated) samples does not depend on ``vs``: it is computed once and kept
during the search, so this step's memory grows with the decimated samples (the rest of the fit's does not):

1. a coarse grid of velocities common to all joints, each joint keeping the one of least residual;
2. Gauss-Newton steps: the weighted least squares with one more column per joint, the derivative of
   its Stribeck column with respect to ``vs`` (:class:`StribeckColumns`), whose coefficient ``c_j`` is
   ``(fs_j - fc_j) dvs_j`` to first order, so ``vs_j += c_j / (fs_j - fc_j)`` (a step at most doubles
   or halves ``vs_j``), until the steps are below a relative 1e-4.

Each ``vs_j`` stays at most the joint's fastest recorded speed: above it the data hold no Coulomb level for the hump
to decay to (the Kinova Gen3's joint 7, at most 0.85 rad/s, drifted to 60-161 rad/s, its static and Coulomb columns
one column with estimates of +-5e4 N m).

At the solution those derivative columns stay in the least squares of ``identify_trajectories`` with
a coefficient near zero: their standard deviations give the standard deviation of ``vs`` (the
linearised model's covariance, as for any Gauss-Newton estimate) and widen those of the others.
"""

from __future__ import annotations

import logging

import numpy as np

from identification.calibration.trajectory_data import (
    CHUNK_SAMPLES,
    NormalEquations,
    drive_column_names,
    drive_columns,
    stribeck_derivative,
)

__all__ = ["STRIBECK_GRID", "StribeckColumns", "base_regressors", "fit_stribeck_velocity", "row_buffers",
           "stribeck_equations", "stribeck_step",
           "stribeck_velocities", "stribeck_velocity_std"]  # fmt: skip

logger = logging.getLogger(__name__)

#: Starting velocities [rad/s] tried for every joint before the Gauss-Newton steps.
STRIBECK_GRID = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)
MAX_STEPS = 30
STEP_TOLERANCE = 1e-4


class StribeckColumns:
    """Extra columns (after ``extra``'s): per joint ``d(g s)/d vs`` at the joints' Stribeck velocities."""

    def __init__(self, coulomb_velocity, stribeck_velocity, extra=None, viscous_exponent=None):
        self.coulomb_velocity = (
            float(coulomb_velocity) if np.ndim(coulomb_velocity) == 0 else np.asarray(coulomb_velocity)
        )
        self.viscous_exponent = viscous_exponent  # the fit's dv
        self.stribeck_velocity = np.asarray(stribeck_velocity, dtype=float)
        self.extra = extra

    @property
    def names(self) -> list:
        own = [f"dvs{j + 1}" for j in range(self.stribeck_velocity.size)]
        return ([] if self.extra is None else list(self.extra.names)) + own

    @property
    def lower(self) -> np.ndarray:
        own = np.full(self.stribeck_velocity.size, -np.inf)
        return own if self.extra is None else np.concatenate([self.extra.lower, own])

    def columns(self, q, qd, qdd) -> np.ndarray:
        n_samples, n_dof = qd.shape
        own = np.zeros((n_samples, n_dof, n_dof))
        own[:, range(n_dof), range(n_dof)] = stribeck_derivative(qd, self.coulomb_velocity, self.stribeck_velocity)
        return own if self.extra is None else np.concatenate([self.extra.columns(q, qd, qdd), own], axis=2)


def base_regressors(model, prepared) -> list:
    """The base-parameter regressor of every prepared recording in chunks: it does not depend on ``vs``."""
    return [
        [model.regressor(r.q[k : k + CHUNK_SAMPLES], r.qd[k : k + CHUNK_SAMPLES], r.qdd[k : k + CHUNK_SAMPLES])
         for k in range(0, r.n_samples, CHUNK_SAMPLES)]
        for r in prepared
    ]  # fmt: skip


def stribeck_equations(rows, prepared, terms, inertia_joints, coulomb_velocity, extras) -> NormalEquations:
    """Normal equations of ``[Y, D(vs), extra]`` (``extras`` one :class:`StribeckColumns` holding ``vs`` per
    recording) from :func:`row_buffers` ``rows``: the rows are laid out as the Gram products take them, and only the
    columns after the base regressor, which depend on ``vs``, are written for each candidate ``vs``."""
    vs = extras[0].stribeck_velocity
    equations = None
    for chunks, r, extra in zip(rows, prepared, extras):
        for k, per_joint in zip(range(0, r.n_samples, CHUNK_SAMPLES), chunks):
            q, qd, qdd = (x[k : k + CHUNK_SAMPLES] for x in (r.q, r.qd, r.qdd))
            drive = drive_columns(qd, qdd, terms, inertia_joints, coulomb_velocity, vs, extra.viscous_exponent)
            more = extra.columns(q, qd, qdd)
            start = per_joint.shape[2] - drive.shape[2] - more.shape[2]
            per_joint[:, :, start : start + drive.shape[2]] = drive.transpose(1, 0, 2)
            per_joint[:, :, start + drive.shape[2] :] = more.transpose(1, 0, 2)
            if equations is None:
                equations = NormalEquations(vs.size, per_joint.shape[2])
            equations.add_per_joint(per_joint, r.tau[k : k + CHUNK_SAMPLES])
    return equations


def row_buffers(regressors, n_columns: int) -> list:
    """Per chunk of :func:`base_regressors`, an (n_dof, n_samples, n_columns) array holding the base regressor in its
    first columns (written once), the others for :func:`stribeck_equations` to fill."""
    out = []
    for chunks in regressors:
        out.append([])
        for chunk in chunks:
            buffer = np.zeros((chunk.shape[1], chunk.shape[0], n_columns))
            buffer[:, :, : chunk.shape[2]] = chunk.transpose(1, 0, 2)
            out[-1].append(buffer)
    return out


def _solve(equations: NormalEquations) -> np.ndarray:
    """Least squares with each joint's rows scaled by its torque RMS (unit-diagonal scaled pseudo-inverse)."""
    rms = np.sqrt(equations.energy / np.maximum(equations.count, 1))
    gram, moment, _ = equations.weighted(1.0 / np.maximum(rms, 1e-12) ** 2)
    scale = np.sqrt(np.clip(np.diag(gram), 1e-300, None))
    inverse = np.linalg.pinv(gram / np.outer(scale, scale), rcond=1e-12, hermitian=True) / np.outer(scale, scale)
    return inverse @ moment


def stribeck_step(x, offset: int, names, vs) -> np.ndarray:
    """``c_j / (fs_j - fc_j)``: the velocity change the derivative coefficients ``c`` (after ``names``) ask for.

    ``x`` holds the drive parameters from index ``offset`` on, labelled by ``names``, then one ``c_j``
    per joint last. Joints whose static and Coulomb levels are equal have no defined ``vs``: 0 there.
    """
    n_dof = vs.size
    fc = np.array([x[offset + names.index(f"fc{j + 1}")] for j in range(n_dof)])
    fs = np.array([x[offset + names.index(f"fs{j + 1}")] for j in range(n_dof)])
    gap = fs - fc
    defined = np.abs(gap) > 1e-9 * np.maximum(np.abs(fs) + np.abs(fc), 1e-12)
    return np.where(defined, x[-n_dof:] / np.where(defined, gap, 1.0), 0.0)


def stribeck_velocities(model, prepared, options, inertia_joints, extra) -> np.ndarray:
    """Each joint's Stribeck velocity [rad/s] of a fit with ``options``: ``options.stribeck_held``, or searched
    (:func:`fit_stribeck_velocity`)."""
    if options.stribeck_held is not None:
        return np.asarray(options.stribeck_held, dtype=float)
    return fit_stribeck_velocity(model, prepared, options, inertia_joints, extra)


def fit_stribeck_velocity(
    model, prepared, options, inertia_joints, extra=None, regressors=None, trial: bool = False
) -> np.ndarray:
    """Stribeck velocity [rad/s] per joint of prepared recordings (module docstring), shape (n_dof,).

    Parameters
    ----------
    model : PSDMModel
    prepared : sequence of Recording
        Filtered, differentiated and decimated (``trajectory_data.prepare_recording``).
    options : trajectory_fit.TrajectoryOptions
        Its ``friction`` holds ``"fs"``; ``coulomb_velocity`` as in the fit; the joints of its ``stribeck_joints``
        (None: every joint) get a velocity, the others 0 (no Stribeck hump: the Coulomb-viscous shape).
    inertia_joints : sequence of int
        The joints with a drive-inertia column of their own.
    extra : object with ``names``, ``lower`` and ``columns(q, qd, qdd)``, or a list of them, optional
        Further linear columns fitted jointly (a list: one per recording, e.g. its payload's, ``payload_fit``).
    regressors : list, optional
        :func:`base_regressors` of ``prepared``, when the caller has them already.
    trial : bool
        The Stribeck shape is a candidate the column choice judges (``column_candidates``), not the shape of the fit:
        the log line says so (the velocities of a shape not chosen are no model's).
    """
    n_dof = prepared[0].n_dof
    terms, velocity = options.friction, options.coulomb_velocity
    names = drive_column_names(n_dof, terms, inertia_joints)
    regressors = base_regressors(model, prepared) if regressors is None else regressors
    extras = list(extra) if isinstance(extra, (list, tuple)) else [extra] * len(prepared)
    first = prepared[0]  # the extra columns as computed (an unknown payload's block has columns but no names)
    probe = StribeckColumns(velocity, np.ones(n_dof), extras[0]).columns(first.q[:1], first.qd[:1], first.qdd[:1])
    n_columns = model.n_base + len(names) + probe.shape[2]
    rows = row_buffers(regressors, n_columns)

    def solve(vs):
        """(augmented estimate with the derivative coefficients, per-joint relative residual without them)."""
        columns = [StribeckColumns(velocity, vs, e, getattr(options, "viscous_exponent", None)) for e in extras]
        equations = stribeck_equations(rows, prepared, terms, inertia_joints, velocity, columns)
        plain = equations.subset(range(equations.n_columns - n_dof))
        return _solve(equations), plain.residual_sum(_solve(plain)) / np.maximum(plain.energy, 1e-300)

    joints = getattr(options, "stribeck_joints", None)
    hump = np.ones(n_dof, bool) if joints is None else np.isin(np.arange(n_dof), list(joints))
    if not hump.any():
        return np.zeros(n_dof)
    # a Stribeck velocity above the joint's fastest recorded speed is no hump the data show (the friction never
    # reaches its Coulomb level; the static and Coulomb columns become one): the search stays within the recorded speeds
    top = np.max([np.max(np.abs(r.qd), axis=0) for r in prepared], axis=0)
    residuals = [solve(np.where(hump, np.minimum(candidate, top), 0.0))[1] for candidate in STRIBECK_GRID]
    vs = np.where(hump, np.minimum(np.asarray(STRIBECK_GRID)[np.argmin(residuals, axis=0)], top), 0.0)
    x, residual = solve(vs)
    steps = 0
    while steps < MAX_STEPS:
        steps += 1
        change = np.clip(vs + stribeck_step(x, model.n_base, names, vs), vs / 2.0, np.minimum(vs * 2.0, top)) - vs
        change[~hump] = 0.0
        for _ in range(8):  # halve the step until the residual does not grow
            trial_x, trial_residual = solve(vs + change)
            if trial_residual.sum() <= residual.sum() * (1 + 1e-12):
                break
            change = change / 2.0
        else:
            break
        vs, x, residual = vs + change, trial_x, trial_residual
        if np.max(np.abs(change[hump]) / vs[hump]) < STEP_TOLERANCE:
            break
    shown = ", ".join(f"{v:.3g}" for v in vs)
    if trial:
        logger.info("identify: the Stribeck shape tried for the column choice (kept only if it is chosen): velocities "
                    "%s rad/s after %d Gauss-Newton steps", shown, steps)  # fmt: skip
    else:
        logger.info("identify: Stribeck velocities %s rad/s after %d Gauss-Newton steps", shown, steps)
    return vs


def stribeck_velocity_std(x, std, offset: int, names, vs) -> tuple:
    """Standard deviation [rad/s] of each Stribeck velocity: that of its derivative coefficient over |fs - fc|.

    ``x`` and ``std`` are the least-squares estimate and its standard deviations, laid out as in
    :func:`stribeck_step` (the derivative coefficients last).
    """
    n_dof = vs.size
    fc = np.array([x[offset + names.index(f"fc{j + 1}")] for j in range(n_dof)])
    fs = np.array([x[offset + names.index(f"fs{j + 1}")] for j in range(n_dof)])
    with np.errstate(divide="ignore", invalid="ignore"):  # 0 where vs is 0: a Coulomb-viscous joint, none fitted
        return tuple(float(v) for v in np.where(vs > 0, np.asarray(std)[-n_dof:] / np.abs(fs - fc), 0.0))
