"""The passes that settle known extra terms between the calibration steps (used by ``IdentificationPipeline``).

The slow gravity jog moves the joints over a small range, where a spring ``k q + c`` is nearly
collinear with the gravity torques; the excitation, with its wide motion, separates them but carries
the gravity parameters less precisely than the jog. Each experiment alone is the wrong place to
settle the terms: the jog cannot tell them from gravity, and terms fixed from the excitation alone
pass their standard error, through that same collinearity, into the jog's gravity estimate. So the
terms are fitted *jointly* (:class:`JointGravityIdentifier`): one weighted least squares over the
jog's rows (gravity parameters and terms) and the excitation's rows (every base parameter and the
terms), each experiment's rows weighted per joint by the inverse of the residual variance of that
experiment fitted alone (:class:`ExcitationTermsIdentifier` for the excitation). It uses what both
experiments know and owes nothing to a gravity estimate fixed beforehand; it is the best linear
unbiased estimate when each experiment's residuals are white noise of that variance, and a
systematic error of one experiment (a start-up transient of the jog) is weighted as if it were noise.
:func:`settle_extra_terms` takes the gravity parameters from this joint
fit and then runs the inertial step with them held (the terms refitted beside the inertial
parameters, the values reported with their sigma); :func:`refit_friction` fits the friction of the
terms' joints again once their torque is known better than the gravity step's first estimate.

Without extra terms nothing here runs: the clean calibration takes its gravity parameters from the
jog alone, as the paper does.
"""

from __future__ import annotations

import copy

import numpy as np

from identification.calibration.estimator import Design, rmse_r2, weighted_least_squares
from identification.calibration.extra_terms import fitted_extra, unfitted
from identification.calibration.friction_step import FrictionIdentifier
from identification.calibration.inputs import recordings
from identification.calibration.steps import GravityIdentifier, InertialIdentifier, regressor_chunked
from psdm_casadi.errors import ParameterError

__all__ = ["ExcitationTermsIdentifier", "JointGravityIdentifier", "settle_extra_terms", "refit_friction"]


class ExcitationTermsIdentifier(InertialIdentifier):
    """The extra terms' coefficients fitted on the excitation with every base parameter free beside them.

    Same parameters and data as :class:`InertialIdentifier` (``theta`` is not used: no parameter is held);
    its design adds the columns of the gravity base parameters of the full regressor to the inertial
    ones and the terms'. It is the excitation's part of :class:`JointGravityIdentifier` (and its noise
    reference), not a source of reported base parameters.

    Attributes
    ----------
    theta_ : array, shape (n_base,)
        All base parameters of this fit (the excitation alone).
    extra_terms_ : ExtraTerms
        The terms with the coefficients fitted here and their standard errors.
    """

    def _design_matrix(self, data) -> Design:
        held = super()._design_matrix(data)  # inertial and term columns; offset: the held gravity torque
        mask = self.model.gravity_mask
        sl = slice(None, None, int(self.decimation))
        gravity = np.concatenate(
            [
                regressor_chunked(self.model, rec.q[sl], rec.qd[sl], rec.qdd[sl])[:, :, mask].reshape(
                    -1, int(mask.sum())
                )
                for rec in recordings(data, "ExcitationTermsIdentifier")
            ]
        )
        return Design(np.hstack([gravity, held.matrix]), held.target, held.weights, held.joint)

    def _check_excitation(self, data, design):
        """Nothing more: the inertial step checks the same recordings' excitation."""

    def _after_fit(self, design):
        mask = self.model.gravity_mask
        n_grav, n_base = int(mask.sum()), self.model.n_base
        theta = np.empty(n_base)
        theta[mask], theta[~mask] = self.coef_[:n_grav], self.coef_[n_grav:n_base]
        self.theta_ = theta
        self.extra_terms_ = fitted_extra(self.extra_terms, self.coef_, self.covariance_, n_base)


class JointGravityIdentifier(GravityIdentifier):
    """The gravity step with the extra terms fitted jointly on the jog and the excitation (stacked least squares).

    Rows of the jog as :class:`GravityIdentifier` builds them (gravity parameters and the terms'
    columns) and rows of the excitation as :class:`ExcitationTermsIdentifier` builds them (every base
    parameter and the terms), in one weighted least squares for the gravity parameters, the inertial
    ones and the terms. The rows of each experiment and joint are weighted by ``1 / s^2``, ``s`` the
    residual RMS of that joint when the experiment is fitted alone (``noise_rms_``), so each
    experiment counts by its own noise and model error: the weights are the statistics of each
    step, not a tuning. ``fit(data, excitation_data)`` takes the (folded) jog and the excitation.

    Parameters
    ----------
    model, kt, robot, tool, min_speed, theta, excitation
        As :class:`GravityIdentifier` (the jog's rows; ``theta`` removes the jog's inertial torques).
    joint_weighting : {"relative", "none"}
        Accepted for the parameters of :class:`GravityIdentifier`; the joint fit weights the rows by the
        residual variances instead.
    extra_terms : ExtraTerms
        The terms, without coefficients (``unfitted(terms)``): the joint fit estimates them.
    inertial : InertialIdentifier
        The parameters of the excitation's rows (``kt``, ``lugre``, ``decimation``, ``tool``; fitted or
        not); its ``theta`` and ``extra_terms`` are not used.

    Attributes
    ----------
    theta_gravity_, theta_ : arrays, shapes (n_gravity,) and (n_base,)
        The gravity parameters of the joint fit (as :class:`GravityIdentifier`).
    extra_terms_ : ExtraTerms
        The terms with the coefficients of the joint fit and their standard errors.
    theta_joint_ : array, shape (n_base,)
        Every base parameter of the joint fit.
    noise_rms_ : array, shape (2, n_dof)
        Residual RMS [N m] per joint of the jog (row 0) and of the excitation (row 1), each fitted
        alone with the terms; NaN for a joint without rows.
    coef_, covariance_ : arrays
        Gravity parameters then terms, as :class:`GravityIdentifier` lays them out (the inertial
        parameters are marginalised: their block is dropped from the joint covariance).

    Raises
    ------
    ParameterError
        Without the excitation recordings, without ``inertial``, or with terms missing or fitted.
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
        inertial=None,
    ):
        super().__init__(model, kt, robot, tool, min_speed, theta, joint_weighting, excitation, extra_terms)
        self.inertial = inertial

    def _validate(self):
        super()._validate()
        if self.extra_terms is None or self.extra_terms.fitted:
            raise ParameterError(
                "JointGravityIdentifier.extra_terms must be terms without coefficients (the joint fit estimates "
                f"them); got {'none' if self.extra_terms is None else 'fitted terms'}. Pass unfitted(terms)."
            )
        if not isinstance(self.inertial, InertialIdentifier):
            raise ParameterError(
                "JointGravityIdentifier.inertial must be an InertialIdentifier (the excitation's kt, lugre and "
                f"decimation); got {type(self.inertial).__name__}."
            )

    def fit(self, data, excitation_data=None):
        """Fit on the jog ``data`` and the excitation recordings ``excitation_data``; return ``self``."""
        self._validate()
        if excitation_data is None:
            raise ParameterError(
                "JointGravityIdentifier.fit needs excitation_data, the excitation recordings the terms are fitted "
                "on beside the jog; got none. Call fit(jog, excitation)."
            )
        jog = self._design_matrix(data)
        self._check_excitation(data, jog)
        rows = ExcitationTermsIdentifier(**dict(self.inertial.get_params(), extra_terms=self.extra_terms))
        exc = rows._design_matrix(excitation_data)
        self.noise_rms_ = np.vstack([_noise_rms(d, self.model.n_dof) for d in (jog, exc)])
        n_grav, n_iner = int(self.model.gravity_mask.sum()), int((~self.model.gravity_mask).sum())
        variance = np.where(np.isfinite(self.noise_rms_) & (self.noise_rms_ > 0), self.noise_rms_**2, 1.0)
        jog_matrix = np.insert(jog.matrix, [n_grav] * n_iner, 0.0, axis=1)  # no inertial column on the jog
        design = Design(
            np.vstack([jog_matrix, exc.matrix]),
            np.concatenate([jog.target, exc.target]),
            np.concatenate([(jog.weights > 0) / variance[0, jog.joint], exc.weights / variance[1, exc.joint]]),
            np.concatenate([jog.joint, exc.joint]),
            np.concatenate([jog.offset, exc.offset]),
        )
        result = weighted_least_squares(design.matrix, design.target, design.weights, design.offset)
        keep = np.r_[0:n_grav, n_grav + n_iner : result.coefficients.size]
        self.coef_ = result.coefficients[keep]
        self.covariance_ = result.covariance[np.ix_(keep, keep)]
        self.sigma2_, self.condition_, self.n_rows_ = result.sigma2, result.condition, design.n_rows
        self.n_dof_ = self._n_dof(data)
        theta = np.empty(self.model.n_base)
        theta[self.model.gravity_mask] = result.coefficients[:n_grav]
        theta[~self.model.gravity_mask] = result.coefficients[n_grav : n_grav + n_iner]
        self.theta_joint_ = theta
        self._after_fit(jog)
        return self


def _noise_rms(design: Design, n_dof: int) -> np.ndarray:
    """Residual RMS [N m] per joint of ``design`` fitted alone (rows with weight > 0, unweighted), shape (n_dof,)."""
    keep = design.weights > 0
    fit = weighted_least_squares(design.matrix, design.target, keep.astype(float), design.offset)
    return rmse_r2(design.target[keep], design.predicted(fit.coefficients)[keep], design.joint[keep], n_dof)[0]


def settle_extra_terms(gravity, inertial, gravity_train, excitation_train):
    """``(gravity, inertial)`` again: the gravity parameters and terms fitted jointly on the jog and the
    excitation (:class:`JointGravityIdentifier`), then the inertial step on that gravity (the terms refitted
    beside the inertial parameters).

    ``gravity`` and ``inertial`` are step estimators whose parameters are reused (fitted or not); the
    inertial one's ``extra_terms`` name the terms."""
    params = {k: v for k, v in gravity.get_params().items() if k != "inertial"}
    params["extra_terms"] = unfitted(inertial.extra_terms)
    gravity = JointGravityIdentifier(**params, inertial=inertial).fit(gravity_train, excitation_train)
    inertial = InertialIdentifier(**dict(inertial.get_params(), theta=gravity.theta_)).fit(excitation_train)
    return gravity, inertial


def refit_friction(friction, train, extra, theta):
    """``friction`` with the joints of ``extra``'s terms fitted again without the terms' torque and with the
    gravity parameters of ``theta`` (others kept)."""
    joints = sorted({j for term in extra.terms for j in term.joints})
    again = FrictionIdentifier(**dict(friction.get_params(), extra_terms=extra, theta=theta)).fit(
        [e for e in train if e.joint in joints]
    )
    merged = copy.copy(friction)
    merged.extra_terms, merged.theta = extra, theta
    for name in ("lugre_", "shooting_"):
        old, new = getattr(friction, name), getattr(again, name)
        setattr(merged, name, tuple(new[j] if j in joints else old[j] for j in range(len(old))))
    for name in ("inertia_", "seconds_"):
        values = getattr(friction, name).copy()
        values[joints] = getattr(again, name)[joints]
        setattr(merged, name, values)
    return merged
