import json
import math

import numpy as np
import pytest

from psdm_casadi import load_robot
from psdm_casadi.errors import RobotFileError
from psdm_casadi.robot import LinkInertia, from_dh, physical_to_dynamic
from tests.conftest import DENSO_FILE, example_robot_urdf

GOOD_JOINT = 'a = 0.1\nalpha = "pi/2"\nd = 0.0\ntheta = 0.0\n'


def write(tmp_path, text, name="robot.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_denso_file_matches_the_paper_table_1(denso):
    a = [j.a for j in denso.joints]
    d = [j.d for j in denso.joints]
    alpha = [j.alpha for j in denso.joints]
    assert a == pytest.approx([0.075, -0.27, -0.09, 0, 0, 0])
    assert d == pytest.approx([0.132, 0, 0, 0.295, 0, 0.080])
    assert alpha == pytest.approx([-math.pi / 2, 0, math.pi / 2, -math.pi / 2, math.pi / 2, 0])
    assert denso.gravity == pytest.approx([9.806132, 0, 0])
    assert denso.massless_links == (6,)
    assert denso.drive_inertia == (True,) * 6
    assert [dr.kt for dr in denso.drives] == pytest.approx([36.07, 40.29, 24.41, 17.93, 14.58, 5.428])


def test_expressions_with_pi_are_read(tmp_path):
    robot = load_robot(write(tmp_path, "[[joint]]\n" + GOOD_JOINT))
    assert robot.joints[0].alpha == pytest.approx(math.pi / 2)


@pytest.mark.parametrize(
    "text, match",
    [
        ("[[joint]]\na = 0.1\nalpha = 0\nd = 0\n", r"joint\[1\]\.theta is missing"),
        ("[[joint]]\n" + GOOD_JOINT + 'type = "spherical"\n', r"joint\[1\]\.type must be"),
        ("[[joint]]\n" + GOOD_JOINT + "q_min = 1.0\nq_max = -1.0\n", r"joint\[1\].*q_min must be below q_max"),
        ("[[joint]]\n" + GOOD_JOINT + "qd_max = 0\n", r"joint\[1\].*qd_max must be positive"),
        ("[[joint]]\n" + GOOD_JOINT + "alpha2 = 1\n", r"joint\[1\] has unknown key.*alpha2"),
        ('[[joint]]\na = "pi/"\nalpha = 0\nd = 0\ntheta = 0\n', r"joint\[1\]\.a must be a number"),
        ('convention = "craig"\n[[joint]]\n' + GOOD_JOINT, r"convention must be"),
        ("gravity = [0, 0]\n[[joint]]\n" + GOOD_JOINT, r"gravity must be a list of 3"),
        ("[assumptions]\nzero_parameters = ['rq1']\n[[joint]]\n" + GOOD_JOINT, r"zero_parameters entry 'rq1'"),
        (
            "[assumptions]\nmassless_links = [3]\n[[joint]]\n" + GOOD_JOINT,
            r"massless_links must be a list of link numbers",
        ),
        ("[assumptions]\ndrive_inertia = [true, false]\n[[joint]]\n" + GOOD_JOINT, r"drive_inertia must be"),
        ("[[joint]]\n" + GOOD_JOINT + "[[link]]\nmass = 1\n[[link]]\nmass = 2\n", r"exactly 1 \[\[link\]\]"),
        ("[[joint]]\n" + GOOD_JOINT + "[[link]]\nmass = -1\n", r"link\[1\].*mass must be >= 0"),
        ("[[joint]]\n" + GOOD_JOINT + "[[link]]\ninertia = [1, 2]\n", r"link\[1\]\.inertia"),
        ("[[joint]]\n" + GOOD_JOINT + "[[drive]]\nkt = -1\n", r"drive\[1\].*kt must be positive"),
        ('format = "psdm-robot/9"\n[[joint]]\n' + GOOD_JOINT, r"format must be"),
        ("name = 'x'\n", r"at least one \[\[joint\]\]"),
        ("[[joint]\n", r"must be valid TOML"),
    ],
)
def test_malformed_files_name_the_field(tmp_path, text, match):
    with pytest.raises(RobotFileError, match=match):
        load_robot(write(tmp_path, text))


def test_missing_file_and_wrong_suffix(tmp_path):
    with pytest.raises(RobotFileError, match="does not exist"):
        load_robot(tmp_path / "none.toml")
    with pytest.raises(RobotFileError, match="must end in .toml, .urdf or .xml"):
        load_robot(write(tmp_path, "x", name="robot.yaml"))


def test_physical_to_dynamic_is_the_parallel_axis_theorem():
    inertia = np.diag([0.1, 0.2, 0.3])
    com = np.array([0.1, -0.2, 0.3])
    params = physical_to_dynamic(2.0, com, inertia)
    assert params[:4] == pytest.approx([2.0, 0.2, -0.4, 0.6])
    # Ixx about the origin = Ixx_c + m (ry^2 + rz^2); Ixy = Ixy_c - m rx ry
    assert params[4] == pytest.approx(0.1 + 2.0 * (0.04 + 0.09))
    assert params[5] == pytest.approx(-2.0 * 0.1 * -0.2)
    assert LinkInertia(2.0, com, [0.1, 0.2, 0.3, 0, 0, 0]).dynamic_parameters() == pytest.approx(params)


def test_urdf_locked_joint_must_exist():
    path = example_robot_urdf("panda_description/urdf/panda.urdf")
    with pytest.raises(RobotFileError, match="locked_joints names 'nope'"):
        load_robot_from_urdf(path, ["nope"])


def test_urdf_panda_loads_with_locked_gripper_and_limits():
    path = example_robot_urdf("panda_description/urdf/panda.urdf")
    robot = load_robot_from_urdf(path, ["panda_finger_joint1", "panda_finger_joint2"])
    assert robot.n_dof == 7
    assert robot.q_max[3] == pytest.approx(-0.0698, abs=1e-3)


def test_urdf_from_toml_wrapper(tmp_path):
    path = example_robot_urdf("panda_description/urdf/panda.urdf")
    toml = write(
        tmp_path,
        f'name = "panda"\n[urdf]\npath = "{path}"\n'
        'locked_joints = ["panda_finger_joint1", "panda_finger_joint2"]\n'
        "[assumptions]\ndrive_inertia = true\n",
    )
    robot = load_robot(toml)
    assert robot.n_dof == 7 and robot.drive_inertia == (True,) * 7 and robot.name == "panda"


def test_malformed_urdf(tmp_path):
    with pytest.raises(RobotFileError, match="could not read the URDF"):
        load_robot(write(tmp_path, "<robot name='x'><link name='a'/><joint/></robot>", name="bad.urdf"))


def test_from_dh_row_length():
    with pytest.raises(RobotFileError, match=r"rows\[0\] must be \(a, alpha, d, theta\)"):
        from_dh([(1.0, 0.0, 0.0)])


def load_robot_from_urdf(path, locked):
    from psdm_casadi.robot import from_urdf

    return from_urdf(path, locked_joints=locked)


def test_denso_file_is_the_shipped_one():
    assert DENSO_FILE.exists()


def test_robot_is_the_one_import_path_of_each_concept_home():
    from psdm_casadi import description, robot, robot_file, urdf

    assert robot.RobotDescription is description.RobotDescription
    assert robot.load_robot is robot_file.load_robot
    assert robot.BUILTIN_ROBOTS_DIR == robot_file.BUILTIN_ROBOTS_DIR
    assert robot.from_urdf is urdf.from_urdf
    assert all(hasattr(robot, name) for name in robot.__all__)


def test_parse_parameter_name():
    from psdm_casadi.description import parse_parameter_name

    assert parse_parameter_name("Ixz4", 6) == ("Ixz", 4)
    assert parse_parameter_name("m1", 2) == ("m", 1)
    with pytest.raises(RobotFileError, match="zero_parameters entry 'rx7'"):
        parse_parameter_name("rx7", 6)


def test_a_calibrated_model_given_as_the_robot_says_so_and_what_to_run(tmp_path, capsys):
    """A new user ran 'psdm identify model.json ...' to identify a calibrated model again: it was refused as a robot
    file with the wrong suffix. It is named a calibrated model, with the commands that read one (exit 2); any other
    .json keeps the suffix refusal."""
    from psdm_casadi.cli import main

    model = tmp_path / "model.json"
    model.write_text(json.dumps({"format": "psdm-calibrated-model", "version": 2, "robot": {"main_file": "gen3.urdf"}}))
    recording = tmp_path / "run.csv"
    recording.write_text("t,q1,tau1\n0,0,0\n0.01,0,0\n")
    assert main(["identify", str(model), "--data", str(recording), "--out", str(tmp_path / "again.json")]) == 2
    err = capsys.readouterr().err
    assert "'model.json' is a calibrated model" in err and "must end in" not in err
    assert "psdm diagnose model.json --train REC --validate REC --apply" in err and "psdm validate model.json" in err
    assert "gen3.urdf" in err and not (tmp_path / "again.json").exists()
    other = tmp_path / "other.json"
    other.write_text('{"format": "something else"}')
    with pytest.raises(RobotFileError, match="must end in .toml, .urdf or .xml"):
        load_robot(other)
