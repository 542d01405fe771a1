"""The augmented model's description (``AugmentedModel.describe``) states the friction a model file holds as the
function computes it: the held values, their Coulomb smoothing and the viscous power law's exponent per joint."""

from __future__ import annotations

import numpy as np

from identification.calibration.held_friction import HeldFriction
from identification.diagnosis.augmented import AugmentedModel


def test_the_description_states_the_held_viscous_exponent_the_function_uses(denso_model):
    """A model file's held friction with a viscous power law on joint 2 (dv = 0.6): the description gives that
    exponent, and the paper's law ``fv |qd|^dv sign(qd)`` (eq. 14) with the described numbers is the function's
    torque at speeds far above the smoothing (with the zero rigid body and no fitted friction)."""
    n = denso_model.n_dof
    held = HeldFriction((("fv2", 0.8), ("fv3", 0.5)), coulomb_velocity=1e-3, viscous_exponent=(1, 0.6, 1, 1, 1, 1))
    zeros = np.zeros(n)
    augmented = AugmentedModel(denso_model, np.zeros(denso_model.n_base), "coulomb_viscous", np.zeros(2 * n), zeros,
                               zeros, (), (), held_friction=held)  # fmt: skip
    friction = augmented.describe()["friction"]
    assert friction["held"] == {"fv2": 0.8, "fv3": 0.5}
    assert friction["held_viscous_exponent"] == [1.0, 0.6, 1.0, 1.0, 1.0, 1.0]
    function = augmented.build_function()
    q = np.zeros(n)
    for speed in (-2.0, 0.5, 3.0):
        qd = np.full(n, speed)
        tau = function(q, qd, np.zeros(n), 0.0).full().ravel()
        expected = np.zeros(n)
        for name, value in friction["held"].items():
            j = int(name[2:]) - 1
            dv = friction["held_viscous_exponent"][j]
            expected[j] = value * abs(speed) ** dv * np.sign(speed)
        np.testing.assert_allclose(tau, expected, rtol=1e-5, atol=1e-9)
    linear = AugmentedModel(denso_model, np.zeros(denso_model.n_base), "coulomb_viscous", np.zeros(2 * n), zeros,
                            zeros, (), (), held_friction=HeldFriction(held.values, 1e-3))  # fmt: skip
    assert linear.describe()["friction"]["held_viscous_exponent"] == []  # linear viscous: no exponent to state
