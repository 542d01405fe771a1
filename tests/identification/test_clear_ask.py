"""An absorbed effect is named only where the data clearly ask for it (``clear_ask``, issue 25, item 1).

Truth: the four-joint cobot of ``torque_scale_data`` logging motor currents, its robot file rough as a user's is
(datasheet masses, centres of mass at the next joint, no rotor inertias; torque constants right), one 10 s recording
without a load. Its rotors, which the base parameters merge into the links, push the consistent fit's links against
their envelopes, link 2 to its reach; the arm has no spring, no counterbalance and no payload. The same arm with a cam
counterbalance on joint 2 (15 N m, a third of that joint's gravity torque) must still have it named there, and on no
other joint.
"""

import numpy as np
import pytest

from identification.calibration.angle_noise import AngleColumns
from identification.calibration.clear_ask import NAME_SIGMA, NAMING_RULE, UNNAMED, refused_noise
from identification.calibration.envelope import link_envelopes
from identification.calibration.envelope_report import where
from identification.calibration.held_back import stored_held_back
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.layout import ColumnLayout
from identification.data.robot_recordings import load_robot_recording
from identification.virtual import effects as xp
from identification.virtual.current_arm import CurrentRun, write_current_recordings
from psdm_casadi.derive import derive_psdm
from psdm_casadi.robot import load_robot
from tests.identification.torque_scale_data import COLUMNS, cobot

CAM = xp.CamCounterbalance(joint=1, amplitude=15.0, lobe=0.3)


@pytest.fixture(scope="module")
def noises():
    """``{name: (least squares' sigma, the rule's noise)}`` per fit of ``fits``, as ``held_back.causes`` is given them
    (``angle_noise.effect_free_noise``, asked here: a ``JointNoise``)."""
    return {}


@pytest.fixture(scope="module")
def fits(tmp_path_factory, noises):
    """``{name: (robot, fit)}`` of the plain arm and the arm with the cam on joint 2."""
    import identification.calibration.trajectory_fit as trajectory_fit

    out, arm, causes = {}, cobot(), trajectory_fit.causes
    for name, extras in (("plain", ()), ("cam", (CAM,))):
        folder = tmp_path_factory.mktemp(name)
        (folder / "cobot.toml").write_text(arm.robot_file((1.0,) * 4))
        robot = load_robot(folder / "cobot.toml")
        (path,) = write_current_recordings(folder, arm, (CurrentRun("run1", 10.0),), np.random.default_rng(1),
                                           extras=extras)  # fmt: skip
        recording = load_robot_recording(path, robot, None, ColumnLayout.parse(COLUMNS, None))

        def kept(*args, name=name):
            noises[name] = np.asarray(args[2][3]), args[-1]()
            return causes(*args)

        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(trajectory_fit, "causes", kept)
            out[name] = robot, identify_trajectories(robot, derive_psdm(robot), [recording], TrajectoryOptions())
    return out


def _along(robot, fit, link) -> float:
    """How far link ``link``'s (0-based) centre of mass lies along its reach (1: at it)."""
    return link_envelopes(robot)[link].reach.along(fit.standard[link, 1:4] / fit.standard[link, 0])


def _said(fit) -> list:
    return [*fit.warnings, *(item.message for item in stored_held_back(fit.envelope_bounds))]


def test_a_link_held_at_its_reach_without_an_effect_names_no_spring_but_its_rotor(fits):
    robot, fit = fits["plain"]
    assert _along(robot, fit, 1) == pytest.approx(1.0, abs=1e-3)  # link 2's centre of mass held at its reach
    link2 = next(f for f in fit.envelope if f.link == 1)
    assert link2.pressed and "envelope" in link2.bounds
    items = stored_held_back(fit.envelope_bounds)
    assert not [f for f in fit.envelope if f.absorbs == "counterbalance"]
    assert not [item for item in items if item.absorbs == "counterbalance"]
    assert not any("spring" in text for text in _said(fit))
    # the torque the bounds refuse is of the order of the noise: the rotor merged into link 2 is named, with the rule
    assert link2.refused_sigma < NAME_SIGMA
    assert link2.absorbs == "drive_inertia" and "joint 2's rotor inertia" in link2.message
    assert NAMING_RULE in link2.message
    # renamed, the finding keeps the opening it was pushed with (``EnvelopeFinding.pushed``), not its old cause
    assert link2.pushed.startswith("link 2 is pushed against its physical envelope")
    assert link2.message.startswith(f"{link2.pushed}. With motor currents") and ". This is " not in link2.message


def test_a_counterbalance_the_data_clearly_ask_for_is_named_on_its_joint_alone(fits):
    robot, fit = fits["cam"]
    named = [f for f in fit.envelope if f.pressed and f.absorbs == "counterbalance"]
    assert named and {where(f) for f in named} == {1}  # joint 2's cam, on joint 2 only
    assert all(f.refused_sigma >= NAME_SIGMA for f in named)
    counterbalances = {i.effect_joint for i in stored_held_back(fit.envelope_bounds) if i.absorbs == "counterbalance"}
    assert counterbalances <= {1}
    # link 3, held at its reach beside the cam, asks joint 3 for less than the rule's torque: no spring named there
    assert _along(robot, fit, 2) == pytest.approx(1.0, abs=1e-3)
    link3 = next(f for f in fit.envelope if f.link == 2)
    assert link3.absorbs == UNNAMED and "joint 3" in link3.message.split("No counterbalance or payload")[1]


def test_the_refused_torque_is_the_residual_growth_from_the_least_squares_to_the_bounded_fit():
    """Against residuals computed directly: two joints, 100 samples of a random regressor."""
    from identification.calibration.trajectory_data import NormalEquations

    rng = np.random.default_rng(3)
    y, x_fit, x_ols = rng.normal(size=(100, 2, 3)), rng.normal(size=3), rng.normal(size=3)
    tau = np.einsum("njk,k->nj", y, x_ols) + rng.normal(scale=0.1, size=(100, 2))
    equations = NormalEquations(2, 3)
    equations.add(y, tau)
    sigma = np.array([0.1, 0.2])
    residual = [np.sum((tau - np.einsum("njk,k->nj", y, x)) ** 2, axis=0) for x in (x_fit, x_ols)]
    expected = np.sqrt(np.maximum(residual[0] - residual[1], 0.0) / 100) / sigma
    np.testing.assert_allclose(refused_noise(equations, x_fit, x_ols, sigma), expected, rtol=1e-9)


def test_the_noise_judged_against_is_the_arms_with_or_without_the_cam(fits, noises):
    """The noise a torque of the angle cannot inflate (``angle_noise``), against the same arm and recorded noise
    without the cam: the plain arm's is its least squares' (no torque of the angle and no offset to take out, so no
    false alarm gains from it, and no offset is named); the cam's is the plain arm's on the joints without the cam.
    On joint 2, over its short travel (about 1.1 rad), what the links leave of the cam is mostly what a torque offset
    gives as well: with an offset the least squares' noise is near the plain arm's. That part is no evidence for a
    counterbalance (a true offset the model lacks must never name one), so it stays in the noise; the cam is named
    all the same (above), on the refusal against the least squares' noise."""
    assert set(noises) == {"plain", "cam"}
    (plain_ols, plain), (cam_ols, cam) = noises["plain"], noises["cam"]
    np.testing.assert_allclose(plain.noise, plain_ols, rtol=0.15)
    assert np.all(plain.others < NAME_SIGMA * plain.offset)  # no joint's own offset takes its noise down
    np.testing.assert_allclose(cam.noise[[0, 2, 3]], plain.noise[[0, 2, 3]], rtol=0.15)
    assert cam.offset[1] < 1.15 * plain.noise[1] and cam_ols[1] > 1.5 * cam.offset[1]
    assert cam.noise[1] > 1.5 * plain.noise[1]  # the offset's part is not credited to the angle


def test_the_angle_columns_are_each_joints_own_angle_on_its_rows_alone():
    """Against the series written out: joint ``j``'s rows carry ``cos(k q_j), sin(k q_j)`` in its own block, zero in
    the others'; an extra object's columns come first, the offsets' (one per joint) last."""

    class Extra:
        def columns(self, q, qd, qdd):
            return np.ones((q.shape[0], q.shape[1], 1))

    q = np.random.default_rng(0).uniform(-3.0, 3.0, size=(7, 3))
    block = AngleColumns(None, 3, harmonics=2).columns(q, q, q)
    assert block.shape == (7, 3, 12)
    for j in range(3):
        own = np.column_stack([np.cos(q[:, j]), np.cos(2 * q[:, j]), np.sin(q[:, j]), np.sin(2 * q[:, j])])
        np.testing.assert_allclose(block[:, j, 4 * j : 4 * j + 4], own)
        assert not np.any(np.delete(block[:, j], np.s_[4 * j : 4 * j + 4], axis=1))
    np.testing.assert_array_equal(AngleColumns(Extra(), 3, harmonics=2).columns(q, q, q)[:, :, 1:], block)
    # with the offsets: a constant 1 on each joint's own rows, after the series
    offsets = AngleColumns(None, 3, harmonics=2, offset=True).columns(q, q, q)
    np.testing.assert_array_equal(offsets[:, :, :12], block)
    np.testing.assert_array_equal(offsets[:, :, 12:], np.broadcast_to(np.eye(3), (7, 3, 3)))
