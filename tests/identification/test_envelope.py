"""The physical envelope of the consistent fit (issue 25, item 1): the ellipsoid condition against known bodies, the
bounded fit on virtual data with and without hidden physics, and what the report names.

References: textbook bodies whose pseudo-inertia and fill of their bounding ellipsoid are known in closed form
(a uniform box fills the ellipsoid through its corners to 1/3, a uniform solid ellipsoid its own to 3/5), a
Monte-Carlo integral of the density condition, and the virtual robot's hidden truth.
"""

import json
import logging
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from identification.calibration.envelope import (
    PRIOR_FILL,
    density_weights,
    ellipsoid_fill,
    ellipsoid_matrix,
    envelope_fill,
    kinematic_envelope,
    link_envelopes,
)
from identification.calibration.pseudo_inertia import pseudo_inertia
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.virtual import effects as xp
from psdm_casadi.cli import main
from psdm_casadi.description import physical_to_dynamic
from psdm_casadi.errors import ParameterError, RobotFileError
from psdm_casadi.link_envelope import LinkEnvelope
from psdm_casadi.robot import load_robot
from psdm_casadi.robot_writer import write_robot_file
from tests.conftest import DENSO_FILE
from tests.identification.diagnosis_data import rigid_recording


def _box(mass, centre, half, rotation):
    """Standard parameters of a uniform box with half extents ``half`` (its axes the columns of ``rotation``)."""
    a, b, c = 2 * np.asarray(half)
    inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return physical_to_dynamic(mass, centre, rotation @ inertia @ rotation.T)


def _condition(link, envelope):
    """``tr(J Q_hat)`` with the 4 x 4 matrices of the paper (Wensing, Kim and Slotine 2017)."""
    return float(np.trace(pseudo_inertia(link) @ ellipsoid_matrix(envelope)))


def test_a_uniform_box_fills_the_ellipsoid_through_its_corners_to_one_third():
    rng = np.random.default_rng(0)
    for _ in range(10):
        rotation = Rotation.random(random_state=rng).as_matrix()
        centre, half, mass = rng.normal(size=3) * 0.3, rng.uniform(0.02, 0.4, 3), rng.uniform(0.5, 20.0)
        envelope = LinkEnvelope.from_box(centre, half, rotation)
        link = _box(mass, centre, half, rotation)
        # the LMI's trace equals the linear form the fit uses, and E[(x-c)^T Q (x-c)] = sum (h_i^2/3) / (3 h_i^2)
        assert density_weights(envelope) @ link == pytest.approx(_condition(link, envelope), rel=1e-10)
        assert envelope_fill(link, envelope) == pytest.approx(1.0 / 3.0, rel=1e-9)
        assert _condition(link, envelope) > 0
        # the same against a Monte-Carlo integral of 1 - (x-c)^T Q (x-c) over the box's mass
        points = centre + (rng.uniform(-1, 1, (20000, 3)) * half) @ rotation.T
        d = points - centre
        integral = mass * np.mean(1.0 - np.einsum("ni,ij,nj->n", d, envelope.shape_matrix, d))
        assert _condition(link, envelope) == pytest.approx(integral, rel=0.02)
        # a point mass at a corner lies on the ellipsoid (condition 0); beyond it the condition fails
        corner = centre + rotation @ half
        assert _condition(physical_to_dynamic(mass, corner, np.zeros((3, 3))), envelope) == pytest.approx(
            0.0, abs=1e-9 * mass
        )
        outside = physical_to_dynamic(mass, centre + 1.05 * rotation @ (np.sqrt(3.0) * half * [1, 0, 0]), np.zeros(3))
        assert _condition(outside, envelope) < 0 and not envelope.contains(
            centre + 1.05 * rotation @ [np.sqrt(3) * half[0], 0, 0]
        )


def test_a_uniform_solid_ellipsoid_fills_its_own_envelope_to_three_fifths():
    axes, centre = np.array([0.3, 0.1, 0.05]), np.array([0.2, -0.1, 0.0])
    rotation = Rotation.from_euler("xyz", [0.3, -0.7, 1.1]).as_matrix()
    inertia = (
        4.0 / 5.0 * np.diag([axes[1] ** 2 + axes[2] ** 2, axes[0] ** 2 + axes[2] ** 2, axes[0] ** 2 + axes[1] ** 2])
    )
    link = physical_to_dynamic(4.0, centre, rotation @ inertia @ rotation.T)
    envelope = LinkEnvelope(centre, axes, rotation)
    assert envelope_fill(link, envelope) == pytest.approx(3.0 / 5.0, rel=1e-12)
    shrunk = LinkEnvelope(centre, 0.7 * axes, rotation)  # the same body does not fit in a smaller ellipsoid
    assert _condition(link, shrunk) < 0


def test_the_kinematic_envelope_holds_the_capsule_around_its_segment():
    rng = np.random.default_rng(1)
    ends = np.array([[0.0, 0.0, 0.0], [0.4, 0.2, -0.1]])
    radius = 0.1
    envelope = kinematic_envelope(ends, radius)
    t = rng.uniform(0, 1, 5000)[:, None]
    direction = rng.normal(size=(5000, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    capsule = ends[0] + t * (ends[1] - ends[0]) + radius * rng.uniform(0, 1, (5000, 1)) ** (1 / 3) * direction
    assert envelope.contains(capsule).all()
    assert not envelope.contains(ends[1] + 3.0 * radius * (ends[1] - ends[0]) / np.linalg.norm(ends[1] - ends[0]))[0]


def test_every_link_envelope_holds_the_robot_files_link_and_its_joints(denso):
    envelopes = link_envelopes(denso)
    prior = denso.nominal_dynamic_parameters()
    for i, envelope in enumerate(envelopes):
        if prior[i, 0] > 0:
            assert ellipsoid_fill(prior[i], envelope) <= PRIOR_FILL + 1e-9
            assert envelope.holds_centre(prior[i, 1:4] / prior[i, 0])
        assert envelope.contains(np.zeros(3))[0]  # the link frame's origin (a joint axis of the DH link)
        assert envelope.semi_axes.max() < 1.0  # a link of a 0.6 m arm: not a sphere around the world


def test_bad_envelopes_and_bounds_are_refused():
    with pytest.raises(RobotFileError, match="semi_axes must be 3 finite numbers > 0"):
        LinkEnvelope([0, 0, 0], [0.1, 0.0, 0.2])
    with pytest.raises(RobotFileError, match="rotation must be a 3x3 rotation"):
        LinkEnvelope([0, 0, 0], [0.1, 0.1, 0.2], np.diag([1.0, 2.0, 1.0]))
    with pytest.raises(ParameterError, match="mass_ratio must be"):
        TrajectoryOptions(mass_ratio=(2.0, 0.5))
    with pytest.raises(ParameterError, match="drive_inertia_ratio must be"):
        TrajectoryOptions(drive_inertia_ratio=(0.5,))


def test_the_bounded_fit_recovers_true_parameters_inside_the_envelope_as_before(denso, denso_model):
    recording = rigid_recording(denso, [])
    bounded = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions())
    free = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions(envelope=False))
    assert bounded.envelope == () and bounded.consistent
    scale = np.maximum(np.abs(free.theta), 1e-3 * np.abs(free.theta).max())
    np.testing.assert_allclose(bounded.theta / scale, free.theta / scale, atol=5e-3)
    truth = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    gravity = denso_model.gravity_mask
    np.testing.assert_allclose(bounded.theta[gravity], truth[gravity], atol=0.01 * np.abs(truth[gravity]).max())


NAMED_ON_JOINT_2 = r"most likely a (counterbalance or spring|spring or counterbalance) on joint 2"


def test_a_hidden_counterbalance_stays_out_of_the_links_and_is_named(denso, denso_model):
    recording = rigid_recording(denso, [xp.CamCounterbalance(joint=1, amplitude=12.0, lobe=0.3)])
    free = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions(envelope=False))
    fit = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions())
    prior = denso.nominal_dynamic_parameters()
    assert free.standard[1, 0] > 2.0 * prior[1, 0]  # without the envelope, link 2 absorbs the counterbalance
    assert np.all(fit.standard[:, 0] <= 2.0 * prior[:, 0] * (1 + 1e-6))
    for i, envelope in enumerate(link_envelopes(denso, range(5))):
        if envelope is not None:
            assert envelope_fill(fit.standard[i], envelope) <= 1.0 + 1e-6
    named = [f for f in fit.envelope if f.absorbs == "counterbalance" and f.pressed]  # link 1 rests on its envelope
    assert named and all(f.joint == 1 for f in named) and named[0].link == 1
    # named whichever bound it presses: link 2's envelope, or joint 2's drive inertia (a negative inertia on a periodic
    # motion) now that the masses are held as their bounds state them (link 2 at 1.76 x, no longer on its 2 x bound)
    assert any(re.search(NAMED_ON_JOINT_2, w) and "psdm diagnose" in w for w in fit.warnings)
    assert not any("mN m" in w for w in fit.warnings)


def test_a_hidden_payload_is_named_as_a_payload(denso, denso_model):
    recording = rigid_recording(denso, [xp.Payload(mass=4.0, com=(0.0, 0.0, 0.1))])
    fit = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions())
    assert fit.envelope and {f.absorbs for f in fit.envelope} == {"payload"}
    assert any(f.link == 4 and "mass upper" in f.bounds for f in fit.envelope)
    assert any("payload or tool at the flange" in w for w in fit.warnings)
    # the forearm (link 4, 0.295 m to the wrist) may not carry the payload's weight beyond the wrist: its centre of
    # mass (the file's at 0.215 m along it) stops at its reach, and the report says so
    reach = link_envelopes(denso)[3].reach
    forearm = next(f for f in fit.envelope if f.link == 3 and "envelope" in f.bounds)
    assert reach.along(fit.standard[3, 1:4] / fit.standard[3, 0]) == pytest.approx(1.0, abs=1e-3)
    assert forearm.reach_limit == reach.limit and forearm.prior_reach == pytest.approx(0.215, abs=1e-9)
    assert "its centre of mass 0.325 m along the link" in forearm.message


def _with_envelopes(text, envelope_line, fmt="psdm-robot/2"):
    """The Denso robot file with ``envelope_line`` added to its second [[link]] table, in format ``fmt``."""
    head, first, second = text.split("\n[[link]]\n", 2)
    head = head.replace('format = "psdm-robot/1"', f'format = "{fmt}"')
    return head + "\n[[link]]\n" + first + "\n[[link]]\n" + envelope_line + "\n" + second


def test_the_robot_file_gives_a_links_envelope_and_writes_it_back(denso, tmp_path):
    text = _with_envelopes(
        DENSO_FILE.read_text(), "envelope = { center = [0.13, 0, -0.03], half_extents = [0.2, 0.06, 0.06] }"
    )
    (tmp_path / "arm.toml").write_text(text)
    robot = load_robot(tmp_path / "arm.toml")
    given = robot.envelopes[1]
    assert robot.envelopes[0] is None and given.source == "robot file"
    np.testing.assert_allclose(given.semi_axes, np.sqrt(3.0) * np.array([0.2, 0.06, 0.06]))
    envelopes = link_envelopes(robot)
    assert envelopes[1] is given and envelopes[0].source == "kinematic lengths"
    again = load_robot(write_robot_file(robot, tmp_path / "copy.toml"))
    np.testing.assert_allclose(again.envelopes[1].shape_matrix, given.shape_matrix, rtol=1e-9)
    assert 'format = "psdm-robot/2"' in (tmp_path / "copy.toml").read_text()
    assert 'format = "psdm-robot/1"' in write_robot_file(denso, tmp_path / "plain.toml").read_text()


@pytest.mark.parametrize(
    ("line", "fmt", "message"),
    [
        (
            "envelope = { center = [0, 0, 0], semi_axes = [0.2, -0.1, 0.1] }",
            "psdm-robot/2",
            "semi_axes must be 3 finite",
        ),
        ("envelope = { center = [0, 0, 0] }", "psdm-robot/2", "must give center and one of semi_axes"),
        ("envelope = { center = [0, 0, 0], semi_axes = [0.2, 0.1, 0.1], size = 3 }", "psdm-robot/2", "size"),
        (
            "envelope = { center = [0, 0, 0], semi_axes = [0.2, 0.1, 0.1] }",
            "psdm-robot/1",
            "needs format = 'psdm-robot/2'",
        ),
    ],
)
def test_a_bad_envelope_in_the_robot_file_exits_2_naming_the_field(tmp_path, capsys, line, fmt, message):
    (tmp_path / "arm.toml").write_text(_with_envelopes(DENSO_FILE.read_text(), line, fmt))
    assert main(["derive", str(tmp_path / "arm.toml"), "--out", str(tmp_path / "m.npz")]) == 2
    err = capsys.readouterr().err
    assert "link[2].envelope" in err and message in err and "Traceback" not in err


@pytest.mark.slow  # identify with the envelope, text, --json and the model file: about 25 s
def test_identify_reports_the_pushed_link_in_text_json_and_the_model_file(denso, tmp_path, capsys):
    recording = rigid_recording(denso, [xp.CamCounterbalance(joint=1, amplitude=12.0, lobe=0.3)])
    save_recording(recording, tmp_path / "train.csv")
    argv = [
        "identify",
        str(DENSO_FILE),
        "--data",
        str(tmp_path / "train.csv"),
        "--out",
        str(tmp_path / "m.json"),
        "--no-counterbalance",
    ]  # the report of the pushed link (by default identify takes the spring)
    assert main([*argv, "--json"]) == 0
    captured = capsys.readouterr()
    payload = json.loads(captured.out)
    assert payload["envelope"]["mass_ratio"] == [0.5, 2.0]
    assert any(f["absorbs"] == "counterbalance" and f["joint"] == 1 for f in payload["envelope_findings"])
    route = f"psdm diagnose {DENSO_FILE} --train {tmp_path / 'train.csv'} --validate OTHER.csv"
    assert any(re.search(NAMED_ON_JOINT_2, w) and route in w for w in payload["warnings"])
    stored = json.loads((tmp_path / "m.json").read_text())
    assert stored["warnings"] == payload["warnings"] and stored["standard"]["envelope_findings"]
    assert main([*argv, "--overwrite", "--no-envelope"]) == 0
    out = capsys.readouterr().out
    assert "physical envelope" not in out and json.loads((tmp_path / "m.json").read_text())["warnings"] == []
    assert main([*argv, "--overwrite", "--mass-bounds", "2", "3"]) == 2
    assert "--mass-bounds must be (low, high)" in capsys.readouterr().err


ARM_URDF = """<robot name="arm">
  <link name="base"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <link name="l1">
    <inertial><origin xyz="0 0 0.2"/><mass value="2"/>
      <inertia ixx="0.03" iyy="0.03" izz="0.003" ixy="0" ixz="0" iyz="0"/></inertial>
    {l1}
  </link>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <link name="l2">
    <inertial><origin xyz="0.15 0 0"/><mass value="1"/>
      <inertia ixx="0.001" iyy="0.008" izz="0.008" ixy="0" ixz="0" iyz="0"/></inertial>
    {l2}
  </link>
  <joint name="tip" type="fixed"><parent link="l2"/><child link="l2_tip"/><origin xyz="0.3 0 0"/></joint>
  <link name="l2_tip">{tip}</link>
</robot>
"""
SHAPES = {
    "l1": '<collision><origin xyz="0 0 0.2"/><geometry><box size="0.1 0.1 0.4"/></geometry></collision>',
    "l2": '<collision><origin xyz="0.15 0 0" rpy="0 1.5707963267948966 0"/><geometry><cylinder radius="0.05" '
    'length="0.3"/></geometry></collision>',
    "tip": '<collision><geometry><sphere radius="0.04"/></geometry></collision>',
}


def test_a_urdf_links_envelope_comes_from_its_collision_geometry(tmp_path):
    from psdm_casadi.urdf_geometry import link_geometry_points

    (tmp_path / "arm.urdf").write_text(ARM_URDF.format(**SHAPES))
    robot = load_robot(tmp_path / "arm.urdf")
    points, kind = link_geometry_points(robot)
    assert kind == "collision"
    np.testing.assert_allclose(points[0].min(axis=0), [-0.05, -0.05, 0.0], atol=1e-9)  # the box
    np.testing.assert_allclose(points[0].max(axis=0), [0.05, 0.05, 0.4], atol=1e-9)
    # the cylinder along x and the sphere of the fixed tip link count for link 2
    np.testing.assert_allclose(points[1].min(axis=0), [0.0, -0.05, -0.05], atol=1e-9)
    np.testing.assert_allclose(points[1].max(axis=0), [0.34, 0.05, 0.05], atol=1e-9)
    envelopes = link_envelopes(robot)
    assert all(e.source == "URDF collision geometry" for e in envelopes)
    for envelope, shape in zip(envelopes, points):
        assert envelope.contains(shape).all()
    # the box link: the ellipsoid through its corners, a uniform box of the same size fills a third of it
    box = _box(2.0, [0, 0, 0.2], [0.05, 0.05, 0.2], np.eye(3))
    assert ellipsoid_fill(box, envelopes[0]) == pytest.approx(1.0 / 3.0, rel=1e-6)
    # its centre of mass halfway to the next joint (0.4 m), whose origin bounds it with a tenth of its length to spare
    assert envelope_fill(box, envelopes[0]) == pytest.approx(0.2 / 0.44, rel=1e-9)
    (tmp_path / "bare.urdf").write_text(ARM_URDF.format(l1="", l2="", tip=""))
    assert {e.source for e in link_envelopes(load_robot(tmp_path / "bare.urdf"))} == {"kinematic lengths"}


def test_a_urdf_whose_meshes_are_absent_says_so_once_with_what_is_used_instead(tmp_path, caplog):
    """A vendor URDF copied without its meshes package (the TX40's): both geometries fail on the same mesh; one line
    names them, the envelope's source and how to have the meshes read."""
    mesh = '<{0}><geometry><mesh filename="package://arm_description/meshes/l1.stl"/></geometry></{0}>'
    (tmp_path / "arm.urdf").write_text(ARM_URDF.format(l1=mesh.format("collision") + mesh.format("visual"), l2="",
                                                       tip=""))  # fmt: skip
    with caplog.at_level(logging.INFO, logger="psdm_casadi.urdf_geometry"):
        envelopes = link_envelopes(load_robot(tmp_path / "arm.urdf"))
    assert {e.source for e in envelopes} == {"kinematic lengths"}
    lines = [r.getMessage() for r in caplog.records if "cannot be read" in r.getMessage()]
    assert len(lines) == 1 and "collision and visual geometry" in lines[0] and lines[0].count("l1.stl") == 1, lines
    assert "from the kinematic lengths instead" in lines[0] and "package folder" in lines[0]


def test_an_mjcf_robots_envelope_comes_from_its_kinematic_lengths(tmp_path):
    from tests.psdm_casadi.test_mjcf_robot import ARM

    (tmp_path / "arm4.xml").write_text(ARM)
    robot = load_robot(tmp_path / "arm4.xml")
    envelopes = link_envelopes(robot)
    assert {e.source for e in envelopes} == {"kinematic lengths"}
    prior = robot.nominal_dynamic_parameters()
    assert all(ellipsoid_fill(prior[i], e) <= PRIOR_FILL + 1e-9 for i, e in enumerate(envelopes) if prior[i, 0] > 0)


def test_one_drive_pressed_down_is_a_spring_every_drive_is_the_torque_signal(denso):
    from types import SimpleNamespace

    from identification.calibration.consistent_fit import FitBounds
    from identification.calibration.envelope_report import envelope_findings

    n, prior = denso.n_dof, denso.nominal_dynamic_parameters()
    rotor = prior[:, -1]
    equations = SimpleNamespace(count=np.full(n, 1000.0), residual_sum=lambda x: np.full(n, 1000.0) * (1.0 + x[0]))
    sigma = np.ones(n)

    def findings(low_joints):
        standard = prior.copy()
        standard[low_joints, -1] = 0.5 * rotor[low_joints]
        pressure = np.zeros((n, 3))
        pressure[low_joints, 2] = 500.0  # well above MIN_PRESSURE x 1000 samples
        bounds = FitBounds((None,) * n, np.zeros(n), np.full(n, np.inf), 0.5 * rotor, 2.0 * rotor, pressure)
        return envelope_findings(denso, bounds, standard, equations, np.array([0.2]), np.array([0.0]), sigma)

    (one,) = findings([1])
    assert one.absorbs == "counterbalance" and one.joint == 1 and "spring or counterbalance on joint 2" in one.message
    every = findings(list(range(n)))
    assert len(every) == n and {f.absorbs for f in every} == {"drive_inertia"}
    assert all("link side of the gearbox" in f.message for f in every)


def test_a_link_resting_on_a_bound_is_a_note_that_nothing_acts_on(denso):
    """A link at its mass bound that the data press on only lightly (the unseen KR6-like arm's links 4 and 6 on slow
    gravity poses, unreported before) is listed, ``pressed`` False, with a note naming what it may hold; the
    warnings, identify's counterbalance route and the diagnosis's rigid body act on the pressed ones only."""
    from types import SimpleNamespace

    from identification.calibration.consistent_fit import FitBounds
    from identification.calibration.counterbalance_column import counterbalance_joints
    from identification.calibration.diagnosis_prior import diagnosis_prior
    from identification.calibration.envelope_report import MIN_PRESSURE, envelope_findings
    from identification.calibration.trajectory_checks import _envelope_warnings

    n, prior = denso.n_dof, denso.nominal_dynamic_parameters()
    mass = prior[:, 0]
    count = 1000.0
    refused = np.eye(n)[1]  # the bounded fit gives up sqrt(0.2) of joint 2's noise, none elsewhere
    equations = SimpleNamespace(count=np.full(n, count), residual_sum=lambda x: count * (1.0 + x[0] * refused))
    standard = prior.copy()
    standard[1, 0], standard[4, 0] = 0.5 * mass[1], 2.0 * mass[4]  # link 2 at its lower bound, link 5 at its upper
    pressure = np.zeros((n, 3))
    pressure[1, 1], pressure[4, 1] = 10 * MIN_PRESSURE * count, 0.2 * MIN_PRESSURE * count
    upper = np.where(mass > 0, 2.0 * mass, np.inf)
    bounds = FitBounds((None,) * n, 0.5 * mass, upper, np.zeros(n), np.full(n, np.inf), pressure)
    found = envelope_findings(denso, bounds, standard, equations, np.array([0.2]), np.zeros(1), np.ones(n))
    pressed, resting = sorted(found, key=lambda f: f.link)
    assert (pressed.link, pressed.pressed, pressed.absorbs) == (1, True, "counterbalance")
    assert (resting.link, resting.pressed, resting.absorbs, resting.bounds) == (4, False, "payload", ("mass upper",))
    assert (
        resting.message.startswith("link 5 rests against its mass upper bound") and "payload or tool" in resting.message
    )
    assert "--mass-bounds" in resting.message and resting.to_dict()["pressed"] is False
    fit = SimpleNamespace(envelope=found, torque_ratio=())
    assert counterbalance_joints(fit) == (1,)
    assert _envelope_warnings(fit) == [pressed.message]  # the resting link is no warning
    document = {"standard": {"envelope_findings": [resting.to_dict()]}}
    assert not diagnosis_prior(document, denso).robot_file  # resting only: the model's own rigid body stays
    document["standard"]["envelope_findings"].append(pressed.to_dict())
    assert diagnosis_prior(document, denso).robot_file
    del document["standard"]["envelope_findings"][0]["pressed"]  # a file written before: every finding pressed
    assert diagnosis_prior(document, denso).links == (1, 4)


def test_a_counterbalance_is_named_on_a_joint_the_links_weight_loads_not_an_upright_base_axis(denso):
    """An upright arm's base axis is parallel to gravity: no link's weight gives it a torque, so a link's first
    moment cannot have absorbed a balancer there. A 210 kg-class arm with a gas spring on joint 2 (HX-210, vertical
    joint 1) had link 2 pressed to its envelope and joint 1 refusing the most torque, and the report named "a
    counterbalance or spring on joint 1"; it is named on joint 2, the first joint below the link that carries it."""
    from types import SimpleNamespace

    from identification.calibration.consistent_fit import FitBounds
    from identification.calibration.envelope_report import MIN_PRESSURE, envelope_findings
    from identification.calibration.gravity_load import joints_carrying_gravity
    from psdm_casadi.oracle import PinocchioOracle
    from psdm_casadi.samples import serial_arm

    upright = serial_arm(6)  # gravity along -z0, joint 1 about z0
    q = np.random.default_rng(3).uniform(-2.0, 2.0, (20, upright.n_dof))
    g = np.abs(PinocchioOracle(upright).gravity(q)).max(axis=0)  # the independent reference: the file's own weight
    assert g[0] < 1e-9 * g.max() and (g[1:3] > 1.0).all()
    assert joints_carrying_gravity(upright).tolist()[:3] == [False, True, True]
    assert joints_carrying_gravity(denso)[0]  # the Denso file's gravity lies across its joint 1: it carries weight

    n, prior = upright.n_dof, upright.nominal_dynamic_parameters()
    mass, count = prior[:, 0], 1000.0
    refused = np.zeros(n)
    refused[0], refused[1] = 9.0, 4.0  # the bounded fit gives up 3 noise levels on joint 1, 2 on joint 2
    equations = SimpleNamespace(count=np.full(n, count), residual_sum=lambda x: count * (1.0 + x[0] * refused))
    standard = prior.copy()
    standard[1, 0] = 0.5 * mass[1]  # link 2 at its lower mass bound, the data pressing on it
    pressure = np.zeros((n, 3))
    pressure[1, 1] = 10 * MIN_PRESSURE * count
    upper = np.where(mass > 0, 2.0 * mass, np.inf)
    bounds = FitBounds((None,) * n, 0.5 * mass, upper, np.zeros(n), np.full(n, np.inf), pressure)
    (found,) = envelope_findings(upright, bounds, standard, equations, np.array([1.0]), np.zeros(1), np.ones(n))
    assert (found.link, found.absorbs, found.joint, found.pressed) == (1, "counterbalance", 1, True)
    assert found.refused_sigma == pytest.approx(2.0) and "joint 1" not in found.message
    assert "counterbalance or spring on joint 2" in found.message


def test_a_refit_names_the_diagnose_command_of_the_model_files_own_run():
    """diagnose --apply refits a model file: its warnings' suggested command names the robot file and recordings
    identify put in the model file's warnings, not the placeholders (before: 'psdm diagnose ROBOT --train DATA
    --validate OTHER' in the written model and every command that prints its warnings)."""
    from identification.calibration.envelope_report import DIAGNOSE_COMMAND, DIAGNOSE_ROUTE, with_concrete_route

    concrete = "psdm diagnose /data/gen3.urdf --train /data/run1.csv --validate /data/run3.csv --rate 1000.0"
    said = ["a recording warning", "link 7 is pushed: " + DIAGNOSE_ROUTE.format(what="a payload").replace(
        DIAGNOSE_COMMAND, concrete)]  # fmt: skip
    refit = ["link 7 is pushed (refit): " + DIAGNOSE_ROUTE.format(what="a payload"), "another warning"]
    assert with_concrete_route(refit, said) == [
        f"link 7 is pushed (refit): run '{concrete}' against the robot file: it fits a payload jointly with the rigid "
        "body",
        "another warning",
    ]
    assert with_concrete_route(refit, ["a recording warning", refit[0]]) == refit  # none named: as they are
