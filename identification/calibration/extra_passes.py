"""The passes that settle known extra terms between the calibration steps (used by ``IdentificationPipeline``).

The slow gravity jog moves the joints over a small range, where a spring ``k q + c`` is nearly
collinear with the gravity torques; the excitation, with its wide motion, separates them. So the
terms are estimated where they are best determined: on the excitation with *every* base parameter
free beside them (:class:`ExcitationTermsIdentifier`), so that their estimate owes nothing to the
jog's collinearity nor to a gravity estimate it has corrupted. :func:`settle_extra_terms` holds them
at that estimate in the gravity step and then runs the inertial step with the gravity so found (the
terms refitted beside the inertial parameters, the values reported with their sigma);
:func:`refit_friction` fits the friction of the terms' joints again once their torque is known
better than the gravity step's first estimate.

An alternation (gravity with the terms held at the inertial step's estimate, the inertial step with
that gravity held, until the terms settle) converges to a point where each step's error feeds the
other's: on the quick demo's plan with a joint-4 spring it left the wrist's gravity parameters at
about twice the clean-data error (``benchmarks/calibration_loop.py``).
"""

from __future__ import annotations

import copy

import numpy as np

from identification.calibration.estimator import Design
from identification.calibration.extra_terms import fitted_extra
from identification.calibration.friction_step import FrictionIdentifier
from identification.calibration.inputs import recordings
from identification.calibration.steps import GravityIdentifier, InertialIdentifier, regressor_chunked

__all__ = ["ExcitationTermsIdentifier", "settle_extra_terms", "refit_friction"]


class ExcitationTermsIdentifier(InertialIdentifier):
    """The extra terms' coefficients fitted on the excitation with every base parameter free beside them.

    Same parameters and data as :class:`InertialIdentifier` (``theta`` is not used: no parameter is held);
    its design adds the columns of the gravity base parameters of the full regressor to the inertial
    ones and the terms'. Used to estimate the terms where they are best determined
    (:func:`settle_extra_terms`), not to report base parameters.

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


def settle_extra_terms(gravity, inertial, gravity_train, excitation_train):
    """``(gravity, inertial)`` again: the terms from the excitation with every base parameter free, held in the
    gravity step; then the inertial step on that gravity (the terms refitted beside the inertial parameters).

    ``gravity`` and ``inertial`` are step estimators whose parameters are reused (fitted or not); the
    inertial one's ``extra_terms`` name the terms."""
    terms = ExcitationTermsIdentifier(**inertial.get_params()).fit(excitation_train).extra_terms_
    gravity = GravityIdentifier(**dict(gravity.get_params(), extra_terms=terms)).fit(gravity_train)
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
