"""The four calibration steps of the paper (section 3) as estimators: motor, gravity, friction, inertial.

The motor, gravity and inertial steps are linear regressions, each a
:class:`identification.calibration.estimator.LeastSquaresIdentifier`: it builds its rows in
``_design_matrix`` and inherits weighted least squares, covariance and scores; the friction step
(``friction_step``) fits LuGre by multiple shooting on the shared base alone. Inputs are
preprocessed recordings (``preprocessing.preprocess``: filtered, with qd and qdd). The motor and
gravity steps take *folded* recordings (:func:`fold_out_and_back`): an experiment that runs out and
retraces its path is averaged sample by sample with its mirror image, which cancels friction
(odd in qd) as in the paper.

=========================  =====================  ============================================
step                       paper                  learned attributes
=========================  =====================  ============================================
``MotorIdentifier``        eqs. 16-17             ``kt_`` (n_dof,) [N m/A]
``GravityIdentifier``      eq. 18                 ``theta_gravity_``, ``theta_`` (n_base,)
``FrictionIdentifier``     eqs. 19-20 + LuGre     ``lugre_`` (LuGreParameters per joint; in ``friction_step``)
``InertialIdentifier``     eq. 21                 ``theta_`` (n_base,), all base parameters
=========================  =====================  ============================================
"""

from __future__ import annotations

import numpy as np

from identification.calibration.estimator import Design, LeastSquaresIdentifier, LeastSquaresResult
from identification.calibration.excitation import (
    check_gravity_design,
    check_inertial_design,
    check_motor_experiments,
    thresholds_of,
)
from identification.calibration.extra_terms import (
    extra_torque,
    fitted_extra,
    holds_extra,
    unfitted,
    with_extra_columns,
)
from identification.calibration.friction_step import FrictionIdentifier, friction_torque
from identification.calibration.inputs import check_model, experiments, recordings, tool_torque, vector
from identification.calibration.out_and_back import MotorExperiment, fold_out_and_back
from identification.calibration.payload import payload_static_torque, payload_torque
from identification.data.payload import Payload
from psdm_casadi.errors import ParameterError
from psdm_casadi.model import PSDMModel
from psdm_casadi.robot import RobotDescription

__all__ = [
    "MotorExperiment",
    "fold_out_and_back",
    "regressor_chunked",
    "MotorIdentifier",
    "GravityIdentifier",
    "InertialIdentifier",
    "IDENTIFIERS",
]

_CHUNK = 2000  # samples per regressor evaluation (memory: n_functions doubles per sample)


def regressor_chunked(model: PSDMModel, q, qd, qdd) -> np.ndarray:
    """``model.regressor`` evaluated in chunks (bounded memory), shape (n_samples, n_dof, n_base)."""
    out = np.empty((q.shape[0], model.n_dof, model.n_base))
    for start in range(0, q.shape[0], _CHUNK):
        stop = start + _CHUNK
        out[start:stop] = model.regressor(q[start:stop], qd[start:stop], qdd[start:stop])
    return out


# ------------------------------------------------------------------------------------------------
# step 1: motor constants (eqs. 16-17)
# ------------------------------------------------------------------------------------------------
class MotorIdentifier(LeastSquaresIdentifier):
    """Motor torque constants from sweeps with and without a known mass (paper eqs. 16-17).

    For each swept joint j, ``Kt_j (i_w - i_nom)_j = (J(q)^T f_w)_j``: the folded (forward/backward
    averaged) currents cancel friction, their difference with and without the mass cancels gravity.
    The estimate regresses the current difference on the load torque (``di = tau_w / Kt``), whose
    regressor is noise-free, so current noise does not bias Kt; ``Kt = 1 / slope``.

    Parameters
    ----------
    robot : RobotDescription
    payload : Payload
        The calibration mass (mass [kg] and centre of mass in the flange frame [m]).
    min_speed_fraction : float
        Rows where the swept joint moves slower than this fraction of its sweep speed (speed ramps,
        turn) are dropped, in (0, 1). The sweep speed is the 90th percentile of ``|qd|``, not its
        maximum: a start-up transient (a joint pulled by an unmodelled spring before the controller
        settles) would otherwise set it and leave only the transient's rows.
    min_torque_fraction : float
        Rows whose load torque is below this fraction of the largest are dropped, in [0, 1).
    load : {"dynamic", "static"}
        Load torque of the mass: ``"dynamic"`` (default) its full rigid-body torque along the folded
        sweep, ``payload_torque(q, qd, qdd)`` (needs qd and qdd), or ``"static"``, its gravity torque
        alone (eq. 16). Folding keeps the mass's torques that are even in the velocity (centripetal
        and Coriolis), which the static load leaves in the current difference as a Kt bias; the
        gravity step inherits that bias through Kt.
    excitation : ExcitationThresholds, optional
        Thresholds of the excitation check (:mod:`identification.data.excitation_check`; default
        ``ExcitationThresholds()``): ``fit`` refuses sweeps whose joint does not move.

    Attributes
    ----------
    kt_ : array, shape (n_dof,)
        Torque constants [N m/A]; NaN for joints without an experiment.
    kt_std_ : array, shape (n_dof,)
        Standard errors [N m/A].
    """

    def __init__(
        self,
        robot=None,
        payload=None,
        min_speed_fraction=0.9,
        min_torque_fraction=0.05,
        load="dynamic",
        excitation=None,
    ):
        self.robot = robot
        self.payload = payload
        self.min_speed_fraction = min_speed_fraction
        self.min_torque_fraction = min_torque_fraction
        self.load = load
        self.excitation = excitation

    def _validate(self):
        if not isinstance(self.robot, RobotDescription):
            raise ParameterError(f"MotorIdentifier.robot must be a RobotDescription; got {type(self.robot).__name__}.")
        if not isinstance(self.payload, Payload) or not self.payload.mass > 0:
            raise ParameterError(
                "MotorIdentifier.payload must be a Payload with mass > 0 [kg]; got "
                f"{self.payload!r}. Pass the calibration mass, e.g. Payload(mass=2.0, com=(0.05, 0, 0.05))."
            )
        if not 0.0 < self.min_speed_fraction < 1.0:
            raise ParameterError(
                f"MotorIdentifier.min_speed_fraction must be in (0, 1); got {self.min_speed_fraction!r}."
            )
        if self.load not in ("dynamic", "static"):
            raise ParameterError(f"MotorIdentifier.load must be 'dynamic' or 'static'; got {self.load!r}.")
        if not 0.0 <= self.min_torque_fraction < 1.0:
            raise ParameterError(
                f"MotorIdentifier.min_torque_fraction must be in [0, 1); got {self.min_torque_fraction!r}."
            )

    def _experiments(self, data):
        items = experiments(data, MotorExperiment, "MotorIdentifier", self.robot.n_dof)
        for e in items:
            e.nominal.check_robot(self.robot.n_dof, self.robot.name)
        return items

    def _check_excitation(self, data, design):
        thresholds = thresholds_of("MotorIdentifier", self.excitation)
        check_motor_experiments(self._experiments(data), self.robot, thresholds)

    def _n_dof(self, data):
        return self.robot.n_dof

    def _design_matrix(self, data) -> Design:
        self._validate()
        n = self.robot.n_dof
        blocks = []
        for e in self._experiments(data):
            j = e.joint
            q = 0.5 * (e.nominal.q + e.loaded.q)
            d_current = e.loaded.current[:, j] - e.nominal.current[:, j]
            if self.load == "dynamic":
                if any(r.qd is None or r.qdd is None for r in (e.nominal, e.loaded)):
                    raise ParameterError(
                        f"MotorIdentifier.load='dynamic' needs qd and qdd in the sweeps of joint {j + 1}; "
                        "preprocess them first or pass load='static'."
                    )
                qd, qdd = 0.5 * (e.nominal.qd + e.loaded.qd), 0.5 * (e.nominal.qdd + e.loaded.qdd)
                load = payload_torque(self.robot, self.payload, q, qd, qdd)[:, j]
            else:
                load = payload_static_torque(self.robot, self.payload, q)[:, j]
            speed = np.abs(e.nominal.qd[:, j])
            keep = (speed >= self.min_speed_fraction * np.percentile(speed, 90.0)) & (
                np.abs(load) >= self.min_torque_fraction * np.abs(load).max()
            )
            if not np.any(np.abs(load) > 0):
                raise ParameterError(
                    f"MotorExperiment.joint {j + 1}: the calibration mass gives no torque on this joint in this pose. "
                    "Choose a pose (and Payload.com) in which the mass loads the joint."
                )
            a = np.zeros((q.shape[0], n))
            a[:, j] = d_current
            blocks.append(Design(a, load, keep.astype(float), np.full(q.shape[0], j)))
        return Design.concatenate(blocks)

    def _solve(self, design: Design) -> LeastSquaresResult:
        n = design.matrix.shape[1]
        kt, var = np.full(n, np.nan), np.full(n, np.nan)
        sigma2 = 0.0
        for j in range(n):
            rows = (design.joint == j) & (design.weights > 0)
            if not rows.any():
                continue
            di, tau = design.matrix[rows, j], design.target[rows]
            slope = float(tau @ di / (tau @ tau))  # di = slope * tau
            if not slope > 0:
                raise ParameterError(
                    f"MotorIdentifier: the current difference of joint {j + 1} does not grow with the load torque "
                    f"(slope {slope:.3g}); check the sign of the current, the payload and the pose."
                )
            res = di - slope * tau
            s2 = float(res @ res / max(rows.sum() - 1, 1))
            kt[j] = 1.0 / slope
            var[j] = s2 / float(tau @ tau) / slope**4
            sigma2 += s2
        cov = np.diag(np.where(np.isnan(var), 0.0, var))
        return LeastSquaresResult(np.where(np.isnan(kt), 0.0, kt), cov, sigma2, int(np.sum(~np.isnan(kt))), 1.0)

    def _after_fit(self, design):
        fitted = np.zeros(self.n_dof_, dtype=bool)
        fitted[np.unique(design.joint[design.weights > 0])] = True
        self.kt_ = np.where(fitted, self.coef_, np.nan)
        self.kt_std_ = np.where(fitted, np.sqrt(np.diag(self.covariance_)), np.nan)


# ------------------------------------------------------------------------------------------------
# step 2: gravity (eq. 18)
# ------------------------------------------------------------------------------------------------
class GravityIdentifier(LeastSquaresIdentifier):
    """Gravity base parameters from slow out-and-back jogs (paper eq. 18).

    Rows ``(Kt i - tau_tool)_i = Y_grav(q)[i, gravity columns] theta_grav`` on folded recordings;
    a row of joint i is dropped when that joint moves slower than ``min_speed`` (near a reversal
    the LuGre pre-sliding state is not symmetric, so folding does not cancel friction there) and
    joints whose gravity row is identically zero (a massless last link) carry no rows.

    Parameters
    ----------
    model : PSDMModel
    kt : array, shape (n_dof,)
        Motor constants [N m/A] (from :class:`MotorIdentifier`); unused for recordings with torques.
    robot : RobotDescription, optional
        Needed with ``tool``.
    tool : Payload, optional
        Known end-effector load present during the experiment (eq. 18's ``J^T f_ee``).
    min_speed : float
        [rad/s], >= 0.
    theta : array, shape (n_base,), optional
        A full base-parameter estimate (e.g. from :class:`InertialIdentifier`) whose non-gravity
        torques ``(Y(q, qd, qdd) - Y_grav(q)) theta`` (inertial and Coriolis, which eq. 18 neglects)
        are removed from the jog's torque first; needs qdd in the recordings.
    joint_weighting : {"relative", "none"}
        ``"relative"`` (default) weights the rows of joint i by ``1 / mean(tau_i^2)``, so every joint
        counts by its relative error: errors proportional to the torque (a small Kt error of a base
        joint carrying tens of N m) then do not leak into the small wrist parameters, which they
        move markedly unweighted. ``"none"``: eq. 18 as is.
    excitation : ExcitationThresholds, optional
        Thresholds of the excitation check (default ``ExcitationThresholds()``): ``fit`` refuses jogs in
        which a joint with a gravity torque does not move, and a rank-deficient or ill-conditioned regressor.
    extra_terms : ExtraTerms, optional
        Known additive torques (a diagnosis finding, :mod:`identification.calibration.extra_terms`) whose
        columns are fitted beside the gravity parameters (a spring ``k (q - q0) = k q - k q0`` adds the
        columns ``q_j`` and ``1`` on its joint's rows); fitted ones (with coefficients) are held: their
        torque is removed instead.

    Attributes
    ----------
    theta_gravity_ : array, shape (n_gravity,)
        The gravity base parameters (``model.gravity_mask`` order).
    theta_ : array, shape (n_base,)
        ``theta_gravity_`` placed in a full base-parameter vector (zeros elsewhere).
    extra_terms_ : ExtraTerms or None
        ``extra_terms`` with the fitted coefficients and their standard errors.
    """

    def __init__(
        self,
        model=None,
        kt=None,
        robot=None,
        tool=None,
        min_speed=0.05,
        theta=None,
        joint_weighting="relative",
        excitation=None,
        extra_terms=None,
    ):
        self.model = model
        self.kt = kt
        self.robot = robot
        self.tool = tool
        self.min_speed = min_speed
        self.theta = theta
        self.joint_weighting = joint_weighting
        self.excitation = excitation
        self.extra_terms = extra_terms

    def _n_dof(self, data):
        return self.model.n_dof

    def _validate(self):
        check_model(self.model, "GravityIdentifier")
        if not (np.isfinite(self.min_speed) and self.min_speed >= 0):
            raise ParameterError(f"GravityIdentifier.min_speed must be >= 0 [rad/s]; got {self.min_speed!r}.")
        if self.joint_weighting not in ("relative", "none"):
            raise ParameterError(
                f"GravityIdentifier.joint_weighting must be 'relative' or 'none'; got {self.joint_weighting!r}."
            )

    def _design_matrix(self, data) -> Design:
        self._validate()
        n = self.model.n_dof
        kt = None if self.kt is None else vector(self.kt, n, "GravityIdentifier", "kt", "N m/A")
        theta = (
            None
            if self.theta is None
            else vector(self.theta, self.model.n_base, "GravityIdentifier", "theta", "base parameters")
        )
        mask = self.model.gravity_mask
        blocks = []
        for rec in recordings(data, "GravityIdentifier"):
            rec.check_robot(n)
            tau = rec.joint_torque(kt) - tool_torque(self.robot, self.tool, rec, static=True)
            y_all = self.model.gravity_regressor(rec.q)
            if theta is not None:
                tau = tau - (regressor_chunked(self.model, rec.q, rec.qd, rec.qdd) - y_all) @ theta
            y = y_all[:, :, mask]  # (N, n, n_grav)
            active = np.any(np.abs(y) > 0, axis=0).any(axis=1)  # joints with a gravity row
            weights = ((np.abs(rec.qd) >= self.min_speed) & active[None, :]).astype(float)
            y = with_extra_columns(y, None if holds_extra(self.extra_terms) else self.extra_terms, rec)
            tau = tau - (extra_torque(self.extra_terms, rec) if holds_extra(self.extra_terms) else 0.0)
            blocks.append(
                Design(
                    y.reshape(y.shape[0] * n, -1),
                    tau.reshape(-1),
                    weights.reshape(-1),
                    np.tile(np.arange(n), rec.n_samples),
                )
            )
        design = Design.concatenate(blocks)
        if self.joint_weighting == "relative":
            scale = np.ones(n)
            for j in range(n):
                rows = (design.joint == j) & (design.weights > 0)
                if rows.any():
                    scale[j] = max(float(np.mean(design.target[rows] ** 2)), 1e-12)
            design = Design(
                design.matrix, design.target, design.weights / scale[design.joint], design.joint, offset=design.offset
            )
        return design

    def _check_excitation(self, data, design):
        thresholds = thresholds_of("GravityIdentifier", self.excitation)
        base = _base_columns(design, int(self.model.gravity_mask.sum()))
        check_gravity_design(self.model, recordings(data, "GravityIdentifier"), base, self.robot, thresholds)

    def _after_fit(self, design):
        n_grav = int(self.model.gravity_mask.sum())
        self.theta_gravity_ = self.coef_[:n_grav].copy()
        theta = np.zeros(self.model.n_base)
        theta[self.model.gravity_mask] = self.theta_gravity_
        self.theta_ = theta
        held = self.extra_terms if holds_extra(self.extra_terms) else None
        self.extra_terms_ = held or fitted_extra(self.extra_terms, self.coef_, self.covariance_, n_grav)


# ------------------------------------------------------------------------------------------------
# step 4: inertial (eq. 21)
# ------------------------------------------------------------------------------------------------
class InertialIdentifier(LeastSquaresIdentifier):
    """The non-gravity base parameters by least squares on an exciting trajectory (paper eq. 21).

    ``Kt i - Y[:, grav] theta_grav - tau_fric - tau_tool = Y[:, iner] theta_iner``, with friction
    simulated by LuGre along the measured velocity and the gravity columns of the full regressor
    (their parameters also carry inertial terms).

    Parameters
    ----------
    model : PSDMModel
    kt : array, shape (n_dof,)
    theta : array, shape (n_base,)
        Base parameters whose gravity part is held (from :class:`GravityIdentifier`).
    lugre : sequence of LuGreParameters, length n_dof
    robot : RobotDescription, optional
    tool : Payload, optional
    decimation : int
        Keep every ``decimation``-th sample (after filtering), >= 1.
    excitation : ExcitationThresholds, optional
        Thresholds of the excitation check (default ``ExcitationThresholds()``): ``fit`` refuses recordings
        in which a joint does not move, and a rank-deficient or ill-conditioned regressor.
    extra_terms : ExtraTerms, optional
        Known additive torques whose columns are fitted beside the inertial parameters (their gravity-step
        values are start values only).

    Attributes
    ----------
    theta_ : array, shape (n_base,)
        All base parameters: the held gravity part and the estimated inertial part.
    theta_std_ : array, shape (n_base,)
        Standard errors (zero for the held gravity part).
    extra_terms_ : ExtraTerms or None
        ``extra_terms`` with the coefficients fitted on the excitation and their standard errors.
    """

    def __init__(
        self,
        model=None,
        kt=None,
        theta=None,
        lugre=None,
        robot=None,
        tool=None,
        decimation=1,
        excitation=None,
        extra_terms=None,
    ):
        self.model = model
        self.kt = kt
        self.theta = theta
        self.lugre = lugre
        self.robot = robot
        self.tool = tool
        self.decimation = decimation
        self.excitation = excitation
        self.extra_terms = extra_terms

    def _n_dof(self, data):
        return self.model.n_dof

    def _validate(self):
        check_model(self.model, "InertialIdentifier")
        n = self.model.n_dof
        if self.lugre is None or len(self.lugre) != n:
            raise ParameterError(
                f"InertialIdentifier.lugre must hold {n} LuGreParameters (one per joint); got "
                f"{None if self.lugre is None else len(self.lugre)}. Fit FrictionIdentifier first."
            )
        if not (isinstance(self.decimation, (int, np.integer)) and self.decimation >= 1):
            raise ParameterError(f"InertialIdentifier.decimation must be an integer >= 1; got {self.decimation!r}.")

    def _design_matrix(self, data) -> Design:
        self._validate()
        n, mask = self.model.n_dof, self.model.gravity_mask
        kt = None if self.kt is None else vector(self.kt, n, "InertialIdentifier", "kt", "N m/A")
        theta = vector(self.theta, self.model.n_base, "InertialIdentifier", "theta", "base parameters")
        blocks = []
        for rec in recordings(data, "InertialIdentifier"):
            rec.check_robot(n)
            friction = friction_torque(self.lugre, rec.t, rec.qd)
            tau = rec.joint_torque(kt) - friction - tool_torque(self.robot, self.tool, rec, static=False)
            sl = slice(None, None, int(self.decimation))
            y = regressor_chunked(self.model, rec.q[sl], rec.qd[sl], rec.qdd[sl])
            held = y[:, :, mask] @ theta[mask]
            m = y.shape[0]
            columns = with_extra_columns(y[:, :, ~mask], unfitted(self.extra_terms), rec, int(self.decimation))
            blocks.append(
                Design(
                    columns.reshape(m * n, -1),
                    tau[sl].reshape(-1),
                    np.ones(m * n),
                    np.tile(np.arange(n), m),
                    offset=held.reshape(-1),
                )
            )
        return Design.concatenate(blocks)

    def _check_excitation(self, data, design):
        thresholds = thresholds_of("InertialIdentifier", self.excitation)
        base = _base_columns(design, int((~self.model.gravity_mask).sum()))
        check_inertial_design(self.model, recordings(data, "InertialIdentifier"), base, self.robot, thresholds)

    def _after_fit(self, design):
        mask = self.model.gravity_mask
        n_iner = int((~mask).sum())
        theta = np.asarray(self.theta, dtype=float).copy()
        theta[~mask] = self.coef_[:n_iner]
        std = np.zeros(self.model.n_base)
        std[~mask] = np.sqrt(np.clip(np.diag(self.covariance_)[:n_iner], 0, None))
        self.theta_ = theta
        self.theta_std_ = std
        self.extra_terms_ = fitted_extra(self.extra_terms, self.coef_, self.covariance_, n_iner)


def _base_columns(design: Design, n_columns: int) -> Design:
    """``design`` restricted to its first ``n_columns`` columns (the base parameters, for the excitation check)."""
    if design.matrix.shape[1] == n_columns:
        return design
    return Design(design.matrix[:, :n_columns], design.target, design.weights, design.joint, offset=design.offset)


IDENTIFIERS = (MotorIdentifier, GravityIdentifier, FrictionIdentifier, InertialIdentifier)
