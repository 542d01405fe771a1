"""Step 3 of the calibration (paper 3.3): friction per joint.

Eq. 19 isolates it, eq. 20 gives the start values, multiple shooting fits LuGre.

:class:`FrictionIdentifier` is one of the four step estimators of :mod:`identification.calibration.steps`
(re-exported there); it is not a linear regression, so it derives from
:class:`identification.calibration.estimator.BaseIdentifier` alone. :func:`friction_torque`
simulates the identified LuGre models along measured velocities for the other steps.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from identification.calibration.estimator import BaseIdentifier
from identification.calibration.excitation import check_friction_experiment, thresholds_of
from identification.calibration.extra_terms import extra_torque
from identification.calibration.inputs import check_model, experiments, recordings, tool_torque, vector
from identification.data.recording import Recording
from identification.friction.shooting import ShootingOptions, fit_lugre_multiple_shooting
from identification.friction.simulation import simulate_lugre
from identification.friction.start import fit_high_speed, initial_lugre_guess
from psdm_casadi.errors import ParameterError

__all__ = ["FrictionExperiment", "FrictionIdentifier", "friction_torque"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class FrictionExperiment:
    """One joint's friction experiment (paper 3.3): that joint oscillating, the others held.

    Parameters
    ----------
    joint : int
        Moving joint, 0-based.
    recording : Recording
        Preprocessed recording (qd required).
    """

    joint: int
    recording: Recording


def friction_torque(lugre, t, qd) -> np.ndarray:
    """LuGre friction torques [N m] of every joint along measured velocities, shape (n_samples, n_dof)."""
    qd = np.atleast_2d(np.asarray(qd, dtype=float))
    out = np.zeros_like(qd)
    for j, p in enumerate(lugre):
        if p is not None:
            out[:, j], _ = simulate_lugre(p, t, qd[:, j])
    return out


def _fit_inertia_high_speed(qd, qdd, tau, threshold):
    """Eq. 20 with the joint's own inertia: ``tau = J qdd + (fc + fv |qd|^dv) sign qd`` on fast samples."""
    fast = np.abs(qd) > threshold
    v, s, a, y = np.abs(qd[fast]), np.sign(qd[fast]), qdd[fast], tau[fast]
    lin = np.linalg.lstsq(np.column_stack([a, s, v * s]), y, rcond=None)[0]
    x0 = np.array([lin[0], max(lin[1], 1e-3), max(lin[2], 1e-3), 1.0])

    def residual(x):
        return x[0] * a + (x[1] + x[2] * v ** x[3]) * s - y

    sol = least_squares(
        residual, x0, bounds=([-np.inf, 0.0, 0.0, 0.05], [np.inf, np.inf, np.inf, 3.0]), x_scale="jac", method="trf"
    )
    return float(sol.x[0])


def _coupling_torque(model, theta, rec, joint, every=20):
    """``sum_k M_jk(q) qdd_k`` over the other joints k [N m], shape (n_samples,).

    ``M_jk`` comes from the regressor, ``(Y(q, 0, e_k) - Y(q, 0, 0))[j] theta``, on every
    ``every``-th sample and is interpolated in between (the pose changes slowly, and the full
    regressor at every sample of a 1 kHz record is costly). Velocity terms are left out: the moving
    joint's own velocity exerts no torque on itself, and the held joints barely move.
    """
    n = model.n_dof
    pick = np.unique(np.append(np.arange(0, rec.n_samples, every), rec.n_samples - 1))
    q = rec.q[pick]
    zero = np.zeros_like(q)
    base = model.regressor(q, zero, zero)[:, joint, :] @ theta
    out = np.zeros(rec.n_samples)
    for k in range(n):
        if k == joint:
            continue
        unit = zero.copy()
        unit[:, k] = 1.0
        m_jk = model.regressor(q, zero, unit)[:, joint, :] @ theta - base
        out += np.interp(np.arange(rec.n_samples), pick, m_jk) * rec.qdd[:, k]
    return out


class FrictionIdentifier(BaseIdentifier):
    """LuGre friction per joint (paper 3.3): eq. 19 isolates friction, eq. 20 starts, multiple shooting finishes.

    For the experiment of joint j, ``tau_fric = Kt_j i_j - (Y_grav theta_grav)_j - tau_tool,j`` (eq. 19).
    Only joint j moves, so its remaining rigid-body torque is ``M_jj qdd_j`` with a constant ``M_jj``
    (M_jj does not depend on q_j); with ``inertia="fit"`` that inertia is estimated together with
    eq. 20 on the fast samples and removed (the paper neglects it, which biases Fc/Fv on a fast
    experiment). The seven LuGre parameters then come from
    :func:`identification.friction.shooting.fit_lugre_multiple_shooting` started at
    :func:`identification.friction.shooting.initial_lugre_guess`.

    Parameters
    ----------
    model : PSDMModel
    kt : array, shape (n_dof,)
    theta : array, shape (n_base,)
        Base parameters whose gravity part is used (from :class:`GravityIdentifier`).
    robot : RobotDescription, optional
        Needed with ``tool``.
    tool : Payload, optional
    inertia : {"fit", "ignore"}
    decimation : int
        Keep every ``decimation``-th sample for the shooting NLP (its size grows with the samples), >= 1.
    high_speed_fraction : float
        Samples faster than this fraction of the peak speed are "high speed" (eq. 20), in (0, 1).
    shooting_options : identification.friction.shooting.ShootingOptions, optional
        With ``measurement="central-difference"`` the fit models the measured friction exactly as
        formed here (held commands, central second difference of ``q``), which needs
        ``decimation=1`` and ``held_torque=True``.
    held_torque : bool
        The recorded current (or torque) is a set-point held over the following sample period
        (zero-order hold, as the virtual robot and robots reporting set-points record). The
        acceleration then jumps at every sample, and the central-difference ``qdd[k]`` is the mean of
        its values just before and after ``t[k]``, which the mean of the set-points ``k-1`` and ``k``
        balances; with ``False`` the set-point ``k`` alone is used, which leaves ``M_jj / 2`` times the
        jump in the measured friction, a torque that biases the damping sigma1. Use ``False`` for
        currents measured at the sample instants.
    coupling_theta : array, shape (n_base,), optional
        Base parameters (e.g. the robot's nominal CAD values) whose coupling torques on the moving
        joint j, ``sum_{k != j} M_jk(q) qdd_k`` (the held joints' accelerations), are removed from the
        measured friction. The held joints ring with the moving one whenever it sticks, and through
        a large off-diagonal inertia that torque biases the moving joint's sigma1.
    verbose : bool
        Log a progress line per joint at INFO (at DEBUG otherwise); each joint is an Ipopt solve.
    excitation : ExcitationThresholds, optional
        Thresholds of the excitation check (:mod:`identification.data.excitation_check`; default
        ``ExcitationThresholds()``): ``fit`` refuses an experiment whose joint does not move or does not
        slide in both directions above the Stribeck range (``min_sliding_fraction`` of ``robot.qd_max``
        when ``robot`` is given).
    extra_terms : ExtraTerms, optional
        Fitted known additive torques (e.g. a spring from the gravity step,
        :mod:`identification.calibration.extra_terms`), removed from the measured friction like the gravity.

    Attributes
    ----------
    lugre_ : tuple of LuGreParameters or None, length n_dof
    inertia_ : array, shape (n_dof,)
        Removed joint inertia M_jj [kg m^2] (NaN when not fitted).
    shooting_ : tuple of ShootingResult or None
    seconds_ : array, shape (n_dof,)
        Wall time per joint [s].
    n_dof_ : int
    """

    _fitted_attribute = "lugre_"

    def __init__(
        self,
        model=None,
        kt=None,
        theta=None,
        robot=None,
        tool=None,
        inertia="fit",
        decimation=1,
        high_speed_fraction=0.25,
        shooting_options=None,
        held_torque=True,
        coupling_theta=None,
        verbose=False,
        excitation=None,
        extra_terms=None,
    ):
        self.model = model
        self.kt = kt
        self.theta = theta
        self.robot = robot
        self.tool = tool
        self.inertia = inertia
        self.decimation = decimation
        self.high_speed_fraction = high_speed_fraction
        self.shooting_options = shooting_options
        self.held_torque = held_torque
        self.coupling_theta = coupling_theta
        self.verbose = verbose
        self.excitation = excitation
        self.extra_terms = extra_terms

    def _validate(self):
        check_model(self.model, "FrictionIdentifier")
        if self.inertia not in ("fit", "ignore"):
            raise ParameterError(f"FrictionIdentifier.inertia must be 'fit' or 'ignore'; got {self.inertia!r}.")
        if not (isinstance(self.decimation, (int, np.integer)) and self.decimation >= 1):
            raise ParameterError(f"FrictionIdentifier.decimation must be an integer >= 1; got {self.decimation!r}.")
        options = self.shooting_options
        if (
            options is not None
            and getattr(options, "measurement", "sample") == "central-difference"
            and (self.decimation != 1 or not self.held_torque)
        ):
            raise ParameterError(
                "FrictionIdentifier.shooting_options.measurement='central-difference' models held commands and the "
                f"central differences of the recorded rate; got decimation={self.decimation!r}, "
                f"held_torque={self.held_torque!r}. Use decimation=1 and held_torque=True, or measurement='sample'."
            )
        if not 0.0 < self.high_speed_fraction < 1.0:
            raise ParameterError(
                f"FrictionIdentifier.high_speed_fraction must be in (0, 1); got {self.high_speed_fraction!r}."
            )

    def _experiments(self, data):
        n = self.model.n_dof
        items = experiments(data, FrictionExperiment, "FrictionIdentifier", n)
        for e in items:
            recordings(e.recording, "FrictionIdentifier")
            e.recording.check_robot(n)
        return items

    def measured_friction(self, experiment: FrictionExperiment) -> np.ndarray:
        """Eq. 19 for the moving joint: ``Kt i - Y_grav theta_grav - tau_tool`` [N m], shape (n_samples,).

        With ``held_torque`` the set-points are first averaged with their predecessors, and with
        ``coupling_theta`` the coupling torques of the other joints are removed (class docstring).
        """
        n = self.model.n_dof
        kt = None if self.kt is None else vector(self.kt, n, "FrictionIdentifier", "kt", "N m/A")
        theta = vector(self.theta, self.model.n_base, "FrictionIdentifier", "theta", "base parameters")
        rec, j = experiment.recording, experiment.joint
        gravity = self.model.gravity_regressor(rec.q)[:, j, :] @ (theta * self.model.gravity_mask)
        tool = tool_torque(self.robot, self.tool, rec, static=False)[:, j]
        torque = rec.joint_torque(kt)[:, j]
        if self.held_torque:
            torque = np.concatenate([torque[:1], 0.5 * (torque[1:] + torque[:-1])])
        torque = torque - gravity - tool - extra_torque(self.extra_terms, rec)[:, j]
        if self.coupling_theta is not None:
            theta_c = vector(
                self.coupling_theta, self.model.n_base, "FrictionIdentifier", "coupling_theta", "base parameters"
            )
            if rec.qdd is None:
                raise ParameterError(
                    "FrictionIdentifier.coupling_theta needs qdd in the friction recordings; preprocess them first."
                )
            torque = torque - _coupling_torque(self.model, theta_c, rec, j)
        return torque

    def fit(self, data):
        """Fit LuGre parameters for every joint with an experiment; return ``self``."""
        self._validate()
        options = self.shooting_options if self.shooting_options is not None else ShootingOptions()
        n = self.model.n_dof
        lugre, shooting = [None] * n, [None] * n
        inertia, seconds = np.full(n, np.nan), np.full(n, np.nan)
        items = self._experiments(data)
        thresholds = thresholds_of("FrictionIdentifier", self.excitation)
        for e in items:
            check_friction_experiment(e, self.robot, thresholds)
        log = logger.info if self.verbose else logger.debug
        for k, e in enumerate(items):
            log(
                "friction joint %d (%d/%d): eq. 20 + LuGre multiple shooting (Ipopt) ...",
                e.joint + 1,
                k + 1,
                len(items),
            )
            start = time.perf_counter()
            rec, j = e.recording, e.joint
            tau = self.measured_friction(e)
            qd, qdd = rec.qd[:, j], rec.qdd[:, j]
            threshold = self.high_speed_fraction * float(np.max(np.abs(qd)))
            if self.inertia == "fit":
                inertia[j] = _fit_inertia_high_speed(qd, qdd, tau, threshold)
                tau = tau - inertia[j] * qdd
            sl = slice(None, None, int(self.decimation))
            t_d, qd_d, tau_d = rec.t[sl], qd[sl], tau[sl]
            high = fit_high_speed(qd_d, tau_d, threshold=threshold)
            initial = initial_lugre_guess(t_d, qd_d, tau_d, high)
            result = fit_lugre_multiple_shooting(t_d, qd_d, tau_d, initial, options, q=rec.q[sl, j])
            lugre[j], shooting[j] = result.parameters, result
            seconds[j] = time.perf_counter() - start
        self.lugre_ = tuple(lugre)
        self.inertia_ = inertia
        self.shooting_ = tuple(shooting)
        self.seconds_ = seconds
        self.n_dof_ = n
        return self

    def _scored_rows(self, data):
        """Measured friction (eq. 19, the fitted inertia removed) and the LuGre simulation along ``qd``, per sample."""
        observed, predicted, joint = [], [], []
        for e in self._experiments(data):
            rec, j = e.recording, e.joint
            tau = self.measured_friction(e)
            if self.inertia == "fit" and np.isfinite(self.inertia_[j]):
                tau = tau - self.inertia_[j] * rec.qdd[:, j]
            if self.lugre_[j] is None:
                raise ParameterError(
                    f"FrictionIdentifier has no LuGre model of joint {j + 1}; fit it on that joint first."
                )
            pred, _ = simulate_lugre(self.lugre_[j], rec.t, rec.qd[:, j])
            observed.append(tau)
            predicted.append(pred)
            joint.append(np.full(rec.n_samples, j))
        return np.concatenate(observed), np.concatenate(predicted), np.concatenate(joint)
