"""A link's centre of mass held short of the next joint's origin (``envelope.CentreReach``, issue 25, item 1).

References: the robot files that ship (their own centres of mass, which real arms' CAD places within their links'
lengths), the DH rows themselves (the joint origins computed here from ``a``, ``d``, ``theta``, ``alpha``), and
synthetic links whose centre of mass is known.
"""

import numpy as np
import pytest

from identification.calibration.envelope import (
    NEXT_JOINT_MARGIN,
    envelope_fill,
    link_envelopes,
    reach_weights,
)
from psdm_casadi.description import physical_to_dynamic
from psdm_casadi.errors import RobotFileError
from psdm_casadi.link_envelope import CentreReach
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, load_robot
from tests.conftest import DATASETS, DENSO_FILE, ROOT, example_robot_urdf
from tests.identification.test_envelope import ARM_URDF

KINOVA_URDF = DATASETS / "kinova_gen3_dynid" / "gen3.urdf"
#: Robot files of real arms (vendor or CAD figures): their centres of mass lie within their links' lengths.
REAL = ("denso", "scara", "tx40", "kinova", "kinova_vendor", "panda")


def _kinova_example(folder):
    text = (ROOT / "examples" / "kinova_gen3.toml").read_text()
    path = folder / "kinova_gen3.toml"
    path.write_text(text.replace("../../shared/datasets/kinova_gen3_dynid/gen3.urdf", str(KINOVA_URDF)))
    return load_robot(path)


@pytest.fixture(scope="module")
def robots(tmp_path_factory):
    """Every robot file that ships with links (those whose data are absent left out), by name."""
    import sys

    from psdm_casadi import from_urdf
    from psdm_casadi.samples import serial_arm

    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from heavy_arm import heavy_industrial_arm
        from torque_constant import cobot7
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))

    out = {"denso": load_robot(BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"),
           "scara": load_robot(BUILTIN_ROBOTS_DIR / "scara.toml"),
           "tx40": load_robot(ROOT / "examples" / "staubli_tx40.toml"),
           "serial_arm_12": load_robot(ROOT / "examples" / "serial_arm_12.toml"),
           "dual_arm_torso": load_robot(ROOT / "examples" / "dual_arm_torso.toml"),
           "serial_arm": serial_arm(6), "heavy_industrial_arm": heavy_industrial_arm(tmp_path_factory.mktemp("heavy")),
           "cobot7_truth": cobot7().truth}  # fmt: skip
    if KINOVA_URDF.exists():
        out["kinova"] = _kinova_example(tmp_path_factory.mktemp("kinova"))
        out["kinova_vendor"] = load_robot(KINOVA_URDF)
    try:  # the Panda of example-robot-data, its fingers locked (benchmarks/bench_support.PANDA_LOCKED)
        urdf = example_robot_urdf("panda_description/urdf/panda.urdf")
        out["panda"] = from_urdf(urdf, locked_joints=("panda_finger_joint1", "panda_finger_joint2"))
    except pytest.skip.Exception:
        pass
    return out


def _rows(robot):
    """Per link, (joint origin, next joint origin) in the link frame from the DH rows (standard convention)."""
    out = []
    for joint in robot.joints:
        c, s, ca, sa = np.cos(joint.theta), np.sin(joint.theta), np.cos(joint.alpha), np.sin(joint.alpha)
        rotation = np.array([[c, -s * ca, s * sa], [s, c * ca, -c * sa], [0.0, sa, ca]])
        offset = np.array([joint.a * c, joint.a * s, joint.d])
        out.append((-rotation.T @ offset, np.zeros(3)))  # the link frame sits on the next joint's axis
    return out


def test_every_shipped_robot_files_centres_of_mass_lie_inside_their_tightened_envelopes(robots):
    assert {"denso", "scara", "tx40", "heavy_industrial_arm"} <= robots.keys()
    reached = 0
    for name, robot in robots.items():
        prior = robot.nominal_dynamic_parameters()
        envelopes = link_envelopes(robot)
        assert envelopes[-1].reach is None, name  # the last link: a tool may sit beyond its flange
        for i, envelope in enumerate(envelopes):
            if envelope is None or prior[i, 0] <= 0:
                continue
            com = prior[i, 1:4] / prior[i, 0]
            assert envelope.holds_centre(com), (name, i + 1)
            assert envelope_fill(prior[i], envelope) <= 1.0, (name, i + 1)
            reach = envelope.reach
            if reach is None or name not in REAL:
                continue
            # a real arm's file: its centre of mass is within the link's own length, the margin not needed
            reached += 1
            length = reach.limit / (1.0 + NEXT_JOINT_MARGIN)
            assert reach.direction @ (com - reach.origin) <= length, (name, i + 1)
    assert reached >= 10


def test_the_reach_runs_from_the_links_joint_to_the_next_joints_origin_as_the_dh_rows_say(robots):
    denso = robots["denso"]
    envelopes = link_envelopes(denso)
    for i, (origin, following) in enumerate(_rows(denso)[:-1]):
        length = np.linalg.norm(following - origin)
        reach = envelopes[i].reach
        if length < 0.08 * 0.787:  # the wrist's joints meet in one point: no length of its own, no reach
            assert reach is None
            continue
        np.testing.assert_allclose(reach.origin, origin, atol=1e-12)
        np.testing.assert_allclose(reach.direction, (following - origin) / length, atol=1e-12)
        assert reach.limit == pytest.approx((1.0 + NEXT_JOINT_MARGIN) * length, rel=1e-12)


def test_a_synthetic_links_centre_of_mass_is_held_short_of_the_next_joint(tmp_path):
    """The URDF arm's first link runs 0.4 m up to joint 2: a rod of 2 kg with its centre at z is inside its reach up to
    z = 0.44 m; the linear form the fit constrains is the mass times the share of the reach left, ``(0.44 - z) / 0.44``.
    """
    (tmp_path / "arm.urdf").write_text(ARM_URDF.format(l1="", l2="", tip=""))
    robot = load_robot(tmp_path / "arm.urdf")
    first, last = link_envelopes(robot)
    assert last.reach is None and first.source == "kinematic lengths"
    np.testing.assert_allclose(first.reach.direction, [0.0, 0.0, 1.0], atol=1e-12)
    assert first.reach.limit == pytest.approx(0.44)
    for z in (0.1, 0.3, 0.43, 0.45, 0.6):
        rod = physical_to_dynamic(2.0, [0.0, 0.0, z], np.diag([0.02, 0.02, 1e-4]))
        assert reach_weights(first) @ rod == pytest.approx(2.0 * (0.44 - z) / 0.44, rel=1e-12)
        assert first.holds_centre([0.0, 0.0, z]) == (z <= 0.44)
        assert (envelope_fill(rod, first) > 1.0) == (z > 0.44)


def test_a_robot_files_own_envelope_gets_no_reach(tmp_path):
    head, first, second = DENSO_FILE.read_text().split("\n[[link]]\n", 2)
    line = "envelope = { center = [0.13, 0, -0.03], half_extents = [0.2, 0.06, 0.06] }"
    head = head.replace('format = "psdm-robot/1"', 'format = "psdm-robot/2"')
    (tmp_path / "arm.toml").write_text(f"{head}\n[[link]]\n{first}\n[[link]]\n{line}\n{second}")
    envelopes = link_envelopes(load_robot(tmp_path / "arm.toml"))
    assert envelopes[1].source == "robot file" and envelopes[1].reach is None and reach_weights(envelopes[1]) is None
    assert envelopes[0].reach is not None and "reach" in envelopes[0].to_dict()


def test_a_bad_reach_is_refused():
    with pytest.raises(RobotFileError, match="unit direction"):
        CentreReach([0, 0, 0], [0, 0, 2.0], 0.3)
    with pytest.raises(RobotFileError, match="limit must be finite and > 0"):
        CentreReach([0, 0, 0], [0, 0, 1.0], 0.0)


@pytest.mark.slow
def test_the_kinova_vendor_urdfs_link_6_keeps_its_centre_of_mass_inside_its_reach(tmp_path, capsys):
    """The Kinova Gen3's vendor URDF (no tool stated), ``psdm identify`` on defaults from the joint-torque sensors as
    ``benchmarks/kinova_gen3.py`` runs it: the kinematic ellipsoid alone let link 6 take the undocumented tool's weight
    with its centre of mass 0.127 m along its 0.106 m; its reach holds it within the next joint's origin plus the
    margin, and the report says so with the tool named at the flange."""
    import json

    from psdm_casadi.cli import main

    if not KINOVA_URDF.exists():
        pytest.skip(f"the Kinova Gen3 dataset is absent ({KINOVA_URDF.parent})")
    path = tmp_path / "kinova_gen3_vendor.toml"  # the URDF alone, the logs' 1 kHz (their time column counts samples)
    path.write_text(f'format = "psdm-robot/1"\nname = "kinova_gen3_vendor"\n\n[urdf]\npath = "{KINOVA_URDF}"\n\n'
                    "[recording]\nsample_rate = 1000.0\n")  # fmt: skip
    data, out = KINOVA_URDF.parent, tmp_path / "model.json"
    training = [str(data / name) for name in ("opti_traj_testing1.csv", "RunTrajectory1.csv")]
    assert main(["identify", str(path), "--data", *training, "--validate", str(data / "opti_traj_testing2.csv"),
                 "--columns", "t=Time,q=Position,tau=TorqueSm", "--out", str(out), "--json"]) == 0  # fmt: skip
    report = json.loads(capsys.readouterr().out)
    robot = load_robot(path)
    standard = np.array(json.loads(out.read_text())["standard"]["values"]).reshape(robot.n_dof, -1)
    reach = link_envelopes(robot)[5].reach
    assert reach.limit / (1.0 + NEXT_JOINT_MARGIN) == pytest.approx(0.1059, abs=1e-3)  # joint 6 to joint 7's origin
    assert 0.99 <= reach.along(standard[5, 1:4] / standard[5, 0]) <= 1.0 + 1e-6  # pushed there, held there
    link6 = next(f for f in report["envelope_findings"] if f["link"] == 5)
    assert link6["reach_limit"] == pytest.approx(reach.limit) and "its centre of mass" in link6["message"]
    assert any(w.startswith("link 7 ") and "tool at the flange" in w for w in report["warnings"])
