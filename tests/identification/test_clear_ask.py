"""An absorbed effect is named only where the data clearly ask for it (``clear_ask``, issue 25, item 1).

Truth: the four-joint cobot of ``torque_scale_data`` logging motor currents, its robot file rough as a user's is
(datasheet masses, centres of mass at the next joint, no rotor inertias; torque constants right), one 10 s recording
without a load. Its rotors, which the base parameters merge into the links, push the consistent fit's links against
their envelopes, link 2 to its reach; the arm has no spring, no counterbalance and no payload. The same arm with a cam
counterbalance on joint 2 (15 N m, a third of that joint's gravity torque) must still have it named there, and on no
other joint, and judged there by the refused torque's part a torque of its angle gives beyond an offset, far above
the rule; joint 1 is vertical (gravity gives it no torque: Pinocchio's gravity torque of the true arm at the recorded
poses), and no counterbalance is named there whatever the data ask; joint 4 is not, though the file's masses give it
none.
"""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.angle_noise import AngleColumns, AngleShare
from identification.calibration.clear_ask import (
    NAME_SIGMA,
    NAMING_RULE,
    UNNAMED,
    angle_refused,
    gravity_free,
    named_where_asked,
    refused_noise,
)
from identification.calibration.envelope import link_envelopes
from identification.calibration.envelope_report import where
from identification.calibration.held_back import stored_held_back
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.layout import ColumnLayout
from identification.data.robot_recordings import load_robot_recording
from identification.virtual import effects as xp
from identification.virtual.current_arm import CurrentRun, write_current_recordings
from psdm_casadi.derive import derive_psdm
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import load_robot
from tests.identification.torque_scale_data import COLUMNS, cobot

CAM = xp.CamCounterbalance(joint=1, amplitude=15.0, lobe=0.3)


@pytest.fixture(scope="module")
def noises():
    """``{name: (least squares' sigma, the rule's noise)}`` per fit of ``fits``, as ``held_back.causes`` is given them
    (``angle_noise.effect_free_noise``, asked here: a ``JointNoise``)."""
    return {}


@pytest.fixture(scope="module")
def judged():
    """``{name: SimpleNamespace(fitted, noise)}`` per fit of ``fits``: what ``held_back.causes`` judged (``fitted``:
    the bounded fit, the least squares, their equations, sigma and the prepared recordings; ``noise``: the callable
    giving the ``JointNoise``)."""
    return {}


@pytest.fixture(scope="module")
def fits(tmp_path_factory, noises, judged):
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
            judged[name] = SimpleNamespace(fitted=args[2], noise=args[-1])
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


def test_the_refused_torques_part_a_torque_of_the_angle_gives_beyond_an_offset_is_its_projection():
    """``AngleShare`` from normal equations, against the torque of a direction written out on each joint's rows and
    projected by least squares on the joint's series and a constant, less its projection on the constant alone (its
    ``share``: that over the torque's energy about its mean)."""
    from identification.calibration.trajectory_data import NormalEquations

    rng = np.random.default_rng(5)
    q, model_columns = rng.uniform(-0.6, 0.9, (400, 3)), rng.normal(size=(400, 3, 4))
    model_columns[:, :, 0] += np.sin(2.0 * q)  # a part of the model's columns that is a torque of the angles
    angle = AngleColumns(None, 3, harmonics=2, offset=True).columns(q, q, q)
    equations = NormalEquations(3, 4 + angle.shape[2])
    equations.add(np.concatenate([model_columns, angle], axis=2), rng.normal(size=(400, 3)))
    delta = rng.normal(size=4)
    torque = np.einsum("njk,k->nj", model_columns, delta)
    for j in range(3):
        series = np.column_stack([np.cos(q[:, j]), np.cos(2 * q[:, j]), np.sin(q[:, j]), np.sin(2 * q[:, j])])
        both = np.column_stack([series, np.ones(400)])
        fitted = both @ np.linalg.lstsq(both, torque[:, j], rcond=None)[0]
        expected = np.sqrt((np.sum(fitted**2) - 400 * np.mean(torque[:, j]) ** 2) / 400)
        assert AngleShare(equations, 4, harmonics=2).rms(delta)[j] == pytest.approx(expected, rel=1e-6)
        varying = np.sum((torque[:, j] - np.mean(torque[:, j])) ** 2) / 400
        assert AngleShare(equations, 4, harmonics=2).share(delta)[j] == pytest.approx(expected**2 / varying, rel=1e-6)
    # a torque of each joint's own angle alone (a counterbalance's): all of it beyond its offset
    own = np.stack([np.sin(q) + 0.3 * np.cos(2 * q), np.ones_like(q), np.zeros_like(q), np.zeros_like(q)], axis=2)
    alone = NormalEquations(3, 4 + angle.shape[2])
    alone.add(np.concatenate([own, angle], axis=2), rng.normal(size=(400, 3)))
    np.testing.assert_allclose(AngleShare(alone, 4, harmonics=2).share(delta), 1.0, rtol=1e-6)
    # a constant torque (a true offset) is no torque of the angle: nothing of it is counted
    constant = NormalEquations(3, 4 + angle.shape[2])
    constant.add(np.concatenate([np.ones((400, 3, 4)), angle], axis=2), rng.normal(size=(400, 3)))
    level = abs(float(np.sum(delta)))  # the constant torque's RMS on every joint
    np.testing.assert_allclose(AngleShare(constant, 4, harmonics=2).rms(delta), 0.0, atol=1e-4 * level)


def test_the_cam_is_asked_for_by_its_angle_far_above_the_rule_and_the_plain_arm_by_nothing(fits, judged):
    """The refused torque's part a torque of each joint's angle gives beyond an offset, against the joint's noise
    with such a torque and an offset (``angle_refused``): the cam on joint 2 at more than twice the rule's
    ``NAME_SIGMA`` and more than its refusal against the noise that keeps the offset's part (``refused_noise``);
    every other joint of both arms below half of the rule."""
    cam, plain = judged["cam"], judged["plain"]
    on_cam = angle_refused(cam.fitted[2], cam.fitted[0], cam.fitted[1], cam.noise)
    on_plain = angle_refused(plain.fitted[2], plain.fitted[0], plain.fitted[1], plain.noise)
    fitted = cam.fitted
    refused = refused_noise(fitted[2], fitted[0], fitted[1], np.minimum(fitted[3], cam.noise().noise))
    assert on_cam[1] > 2 * NAME_SIGMA and on_cam[1] > refused[1]
    assert np.all(np.delete(on_cam, 1) < 0.5 * NAME_SIGMA) and np.all(on_plain < 0.5 * NAME_SIGMA)


def test_no_counterbalance_is_named_on_a_joint_gravity_gives_no_torque(fits, judged):
    """The cobot's joint 1 turns about a vertical axis: the true arm's gravity torque (Pinocchio) at the recorded
    poses is nil there and not on joints 2-4, and ``gravity_free`` reads that from the recorded poses. Joint 4 is
    horizontal: the user's file puts link 4's centre of mass on its axis, so the file's own gravity torque there is nil
    too, but the true link (and any tool) loads it; a reading of the file's masses would call it gravity-free. A
    counterbalance-like torque the data ask for far beyond the rule (the cam fit's finding on link 2 put on joint 1,
    every joint refused and asked 25 noise levels) is named none on joint 1, and named on joints 2 and 4."""
    robot, fit = fits["cam"]
    (recording,) = judged["cam"].fitted[4]
    poses = recording.q[::10]
    gravity = PinocchioOracle(cobot().truth).gravity(poses)
    nil = np.sqrt(np.mean(gravity**2, axis=0)) <= 1e-9 * np.abs(recording.tau).max()
    assert nil.tolist() == [True, False, False, False]
    file_gravity = PinocchioOracle(robot, robot.nominal_dynamic_parameters()).gravity(poses)
    assert np.abs(file_gravity[:, 3]).max() < 1e-9  # the file's masses alone: joint 4 nil as well
    np.testing.assert_array_equal(gravity_free(judged["cam"].noise), nil)
    (link2,) = [f for f in fit.envelope if f.link == 1 and f.absorbs == "counterbalance"]
    asked = np.full(robot.n_dof, 25.0)
    for joint, named in ((0, UNNAMED), (3, "counterbalance"), (1, "counterbalance")):
        finding = replace(link2, effect_joint=joint)
        (out,), _ = named_where_asked((finding,), (), asked, robot, noise=judged["cam"].noise, angle=asked)
        assert out.absorbs == named, joint
        # without the recorded poses (no noise given): the data alone name it on any joint
        (alone,), _ = named_where_asked((finding,), (), asked, robot, angle=asked)
        assert alone.absorbs == "counterbalance"


def test_a_joint_the_file_states_massless_beyond_still_carries_a_tools_gravity(fits, denso, denso_model):
    """The virtual Denso's file states link 6 massless: its own gravity torque on joint 6 is nil at every pose, and
    the model derived from it drops link 6's parameters (its gravity regressor row is zero too). A recording that
    carries a tool (1 kg, 5 cm off joint 6's axis: Pinocchio's gravity torque of the file with the tool, the reference)
    loads joint 6 all the same, so the veto reads the arm's kinematics (``gravity_free``): a counterbalance the data ask
    for on joint 6 is named."""
    from identification.calibration.angle_noise import JointNoise
    from identification.calibration.gravity_load import joints_carrying_gravity, recorded_poses

    t = np.linspace(0.0, 8.0, 801)[:, None]
    q = 0.6 * np.sin(2 * np.pi * t * np.array([0.11, 0.13, 0.17, 0.19, 0.23, 0.29]) + np.arange(6))
    poses = recorded_poses([SimpleNamespace(q=q)])
    with_tool = denso.nominal_dynamic_parameters().copy()
    with_tool[5, :4] = (1.0, 0.05, 0.0, 0.02)  # a 1 kg tool, its centre of mass 5 cm off joint 6's axis
    file_only = np.abs(PinocchioOracle(denso, denso.nominal_dynamic_parameters()).gravity(poses)).max(axis=0)
    tool = np.abs(PinocchioOracle(denso, with_tool).gravity(poses)).max(axis=0)
    assert file_only[5] == 0.0 and tool[5] > 0.01 and (file_only[:5] > 0.1).all()
    assert not denso_model.gravity_regressor(poses[:50])[:, 5].any()  # the model's reading: none either
    carries = joints_carrying_gravity(denso, poses)
    assert carries.tolist() == (tool > 1e-9 * tool.max()).tolist() == [True] * 6

    ones = np.ones(denso.n_dof)
    noise = JointNoise(ones, ones, ones, ones, None, carries)
    np.testing.assert_array_equal(gravity_free(lambda: noise), np.zeros(6, dtype=bool))
    _, fit = fits["cam"]
    (link2,) = [f for f in fit.envelope if f.link == 1 and f.absorbs == "counterbalance"]
    asked = np.full(denso.n_dof, 25.0)
    (out,), _ = named_where_asked((replace(link2, effect_joint=5),), (), asked, denso, noise=lambda: noise, angle=asked)
    assert out.absorbs == "counterbalance"


def test_the_noise_pass_is_made_only_where_a_counterbalance_is_judged(fits):
    """The veto's reading (``gravity_free``) comes with the noise's pass over the recordings: a fit whose findings
    judge no counterbalance (none, a drive inertia, a payload) does not make it."""
    robot, fit = fits["cam"]
    (link2,) = [f for f in fit.envelope if f.link == 1 and f.absorbs == "counterbalance"]
    never = lambda: pytest.fail("the noise was computed")  # noqa: E731
    assert named_where_asked((), (), never, robot, noise=never) == ((), ())
    asked = np.full(robot.n_dof, 25.0)
    for absorbs in ("drive_inertia", "payload"):
        (out,), _ = named_where_asked((replace(link2, absorbs=absorbs),), (), asked, robot, noise=never, angle=never)
        assert out.absorbs == absorbs
