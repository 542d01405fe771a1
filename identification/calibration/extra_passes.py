"""The passes that settle known extra terms between the calibration steps (used by ``IdentificationPipeline``).

The slow gravity jog moves the joints over a small range, where a spring ``k q + c`` is nearly
collinear with the gravity torques; the excitation separates them. :func:`alternate_extra_terms`
holds the terms at the inertial step's estimate in the gravity step and refits both in turn until
the terms settle; :func:`refit_friction` fits the friction of the terms' joints again once their
torque is known better than the gravity step's first estimate.
"""

from __future__ import annotations

import copy

import numpy as np

from identification.calibration.friction_step import FrictionIdentifier
from identification.calibration.steps import GravityIdentifier, InertialIdentifier

__all__ = ["alternate_extra_terms", "refit_friction"]


def alternate_extra_terms(gravity, inertial, gravity_train, excitation_train, max_passes: int = 10):
    """Gravity with the extra terms held at the inertial estimate, then inertial (terms refitted), until they settle."""
    if not hasattr(inertial, "extra_terms_"):
        inertial = inertial.fit(excitation_train)
    for _ in range(max_passes):
        before = inertial.extra_terms_.coefficients
        held = dict(gravity.get_params(), extra_terms=inertial.extra_terms_)
        gravity = GravityIdentifier(**held).fit(gravity_train)
        inertial = InertialIdentifier(**dict(inertial.get_params(), theta=gravity.theta_)).fit(excitation_train)
        if np.all(np.abs(inertial.extra_terms_.coefficients - before) <= 1e-3 * (1.0 + np.abs(before))):
            break
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
