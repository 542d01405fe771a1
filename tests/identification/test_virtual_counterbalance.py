"""Physical counterbalances of the virtual robot (``identification.virtual.counterbalance``, issue 25).

Reference: Pinocchio's gravity torque of the robot file (``PinocchioOracle.gravity``). A balancer built for a joint
must oppose that torque at every angle of a full turn (the other joints at the design pose) and cancel the stated
share of its amplitude; the benchmarks' heavy-arm balancers must oppose the gravity torque on every recorded sample.
Before, the heavy arm's cams were drawn without regard to gravity and added to it on most of the range.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.virtual import effects as xp
from identification.virtual.counterbalance import (
    balance,
    cam_counterbalance,
    gas_spring_counterbalance,
    gravity_law,
)
from psdm_casadi.errors import ParameterError
from psdm_casadi.oracle import PinocchioOracle

POSE = np.array([0.3, 0.2, 1.2, 0.0, 0.5, 0.0])


def _turn(pose, joint):
    q = np.tile(pose, (360, 1))
    q[:, joint] = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    return q


def test_the_gravity_law_is_pinocchios_gravity_torque_over_a_full_turn(denso):
    law = gravity_law(denso, 1, POSE)
    q = _turn(POSE, 1)
    gravity = PinocchioOracle(denso).gravity(q)[:, 1]
    assert law.amplitude > 0
    np.testing.assert_allclose(law.torque(q[:, 1]), gravity, atol=1e-9 * law.amplitude)
    # the hanging angle is the stable one: the load torque grows with the angle through it
    assert law.torque(law.hanging + 1e-3) > 0 > law.torque(law.hanging - 1e-3)


@pytest.mark.parametrize("share", [0.4, 0.9])
def test_both_balancers_oppose_gravity_at_every_angle_and_cancel_their_share(denso, share):
    cam = cam_counterbalance(denso, 1, POSE, share, lobe=0.35)
    strut = gas_spring_counterbalance(denso, 1, POSE, share, a=0.25, b=0.1, stiffening=0.5)
    q = _turn(POSE, 1)
    for effect in (cam, strut):
        measured = balance(denso, effect, q)
        assert measured.opposing == 1.0, effect
        assert measured.share == pytest.approx(share, rel=1e-6), effect
    assert strut.preload > 0 and strut.stiffness > 0  # a compressed strut that pushes the arm up


def test_a_cam_set_without_regard_to_gravity_is_measured_as_adding_to_it(denso):
    """The cam the project's tests used on the Denso (``q0 = 0``, positive amplitude) adds to joint 2's gravity torque
    over most of a turn; ``balance`` says so, and the one built about the hanging angle does not."""
    q = _turn(POSE, 1)
    arbitrary = balance(denso, xp.CamCounterbalance(joint=1, amplitude=12.0, lobe=0.3), q)
    assert arbitrary.opposing < 0.9 and arbitrary.share < 0.3
    assert balance(denso, cam_counterbalance(denso, 1, POSE, 0.6), q).opposing == 1.0


def test_a_share_or_a_lobe_outside_the_physical_range_is_refused(denso):
    with pytest.raises(ParameterError, match="share"):
        cam_counterbalance(denso, 1, POSE, 1.5)
    with pytest.raises(ParameterError, match="lobe"):
        cam_counterbalance(denso, 1, POSE, 0.5, lobe=1.2)
    with pytest.raises(ParameterError, match="pose"):
        gravity_law(denso, 1, POSE[:3])


@pytest.mark.parametrize("maker", ["heavy_counterbalance", "heavy_gas_spring"])
def test_the_heavy_arms_balancers_oppose_gravity_on_every_recorded_pose(benchmark_modules, maker):
    """The diagnosis benchmark's heavy-arm counterbalances (also ``benchmarks/heavy_arm.py``'s), seeds 0-2: on the
    poses of the scenario's whole reference motion they oppose joint 2's gravity torque and take 30-95 % of it
    (the seeded 40-90 % of the amplitude, measured over the recorded range instead of a full turn)."""
    from diagnosis import MAKERS, exciting_reference, reference_scale
    from heavy_arm import heavy_industrial_arm

    robot = heavy_industrial_arm()
    for seed in range(3):
        rng = np.random.default_rng(seed)
        reference = exciting_reference(robot, 20.0, rng)
        scale = reference_scale(robot, reference, 20.0)
        ((_, joint, effect, truth),) = MAKERS[maker](robot, rng, (), scale)
        measured = balance(robot, effect, reference[1][::5])
        assert joint == 1 and measured.opposing == 1.0, (seed, effect)
        assert 0.3 < measured.share < 0.95 and 0.4 <= truth["share"] <= 0.9, (seed, measured)
