"""The noise ``clear_ask`` judges against (``angle_noise.joint_noise``) where the model already holds an offset.

Truth: three joints, 2000 samples of a random regressor of five columns and a torque offset column on joint 2 (a
constant 1 on its rows: the model's ``offset2``), a true 4 N m offset there and Gaussian noise of known RMS on every
joint. The fits "with an offset" add one per joint; on joint 2 that would be a second column identical to the
model's, so none is added there.
"""

import numpy as np
import pytest

from identification.calibration.angle_noise import AngleColumns, held_offsets, joint_noise
from identification.calibration.trajectory_data import NormalEquations

N, DOF, STD = 2000, 3, 0.05


def _equations(offset_column: np.ndarray):
    rng = np.random.default_rng(4)
    q = np.stack([0.6 * np.sin(np.linspace(0.0, 5.0 + k, N) + k) for k in range(DOF)], axis=1)
    model = rng.normal(size=(N, DOF, 5)) * np.array([100.0, 10.0, 1.0, 0.1, 30.0])
    model = np.concatenate([model, offset_column[None, :, None] * np.ones((N, DOF, 1))], axis=2)
    x = np.append(rng.normal(size=5), 4.0)
    tau = np.einsum("njk,k->nj", model, x) + rng.normal(scale=STD, size=(N, DOF))
    angle = AngleColumns(None, DOF, offset=True).columns(q, q, q)
    equations = NormalEquations(DOF, 6 + angle.shape[2])
    equations.add(np.concatenate([model, angle], axis=2), tau)
    return equations, 6 + angle.shape[2] - DOF  # the first added offset column


def test_a_joint_whose_model_holds_an_offset_gets_no_second_one():
    equations, first = _equations(np.array([0.0, 1.0, 0.0]))
    assert held_offsets(equations, 6, range(6), first).tolist() == [False, True, False]
    # twice the constant is the same offset; a constant on every joint's rows is no one joint's offset
    assert held_offsets(_equations(np.array([0.0, 2.0, 0.0]))[0], 6, range(6), first).tolist() == [False, True, False]
    assert not held_offsets(_equations(np.ones(DOF))[0], 6, range(6), first).any()
    assert not held_offsets(equations, 6, range(5), first).any()  # the model's offset column held out of the fit

    found = joint_noise(equations, 6, range(6))
    # on joint 2 "with an offset on every joint" and "on every other joint" are then the same fit: the model's own
    # offset is its offset (a second, identical column changed the figure through the fit's column count)
    assert found.offset[1] == pytest.approx(found.others[1], rel=1e-12)
    np.testing.assert_allclose(found.offset, STD, rtol=0.05)  # the noise the data were made with
    np.testing.assert_allclose(found.own, STD, rtol=0.05)
