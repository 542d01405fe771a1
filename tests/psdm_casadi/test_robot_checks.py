"""Every value check of the robot description and its readers: one ``pytest.raises(match=field)`` per check."""

import gzip
import math
import re
import time
from pathlib import Path

import numpy as np
import pytest

from identification.data.payload import Payload, read_payload
from psdm_casadi import load_robot
from psdm_casadi.derive import (
    MAX_DOF,
    DeriveOptions,
    check_derivation_size,
    derivation_grid_points,
    derivation_memory_bytes,
    derive_psdm,
)
from psdm_casadi.errors import ParameterError, RobotFileError
from psdm_casadi.robot import DriveParameters, Joint, LinkInertia, RobotDescription, from_dh, from_urdf
from psdm_casadi.text_file import read_text_file
from psdm_casadi.urdf import captured_stderr
from psdm_casadi.values import format_value, inertia_violation
from tests.conftest import example_robot_urdf

JOINT = '[[joint]]\nname = "J1"\na = 0.1\nalpha = 0.0\nd = 0.0\ntheta = 0.0\n'
LINK = "[[link]]\nmass = 1.0\ncom = [0.0, 0.0, 0.1]\ninertia = [0.01, 0.01, 0.01, 0.0, 0.0, 0.0]\n"


def write(folder: Path, content, name="robot.toml") -> Path:
    path = folder / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path


def urdf_text(mass="1.0", ixx="0.1", lower="-1.0", upper="1.0", joint="j1", extra=""):
    return (
        f'<robot name="r"><link name="base"/><link name="l1"><inertial><mass value="{mass}"/>'
        f'<origin xyz="0 0 0.1"/><inertia ixx="{ixx}" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        f'<joint name="{joint}" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>'
        f'<limit lower="{lower}" upper="{upper}" velocity="2" effort="10"/></joint>{extra}</robot>'
    )


# --- numbers in a robot file -----------------------------------------------------------------------


@pytest.mark.parametrize("key", ["a", "alpha", "d", "theta", "q_min", "q_max", "qd_max", "qdd_max", "tau_max"])
@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_joint_numbers_must_be_finite(tmp_path, key, value):
    text = re.sub(rf"(?m)^{key} = .*\n", "", JOINT)
    with pytest.raises(RobotFileError, match=rf"robot\.toml joint\[1\]\.{key} must be a finite number; got {value}\."):
        load_robot(write(tmp_path, text + f"{key} = {value}\n"))


def test_an_infinite_limit_prints_as_inf_and_names_the_fix(tmp_path):
    with pytest.raises(RobotFileError, match=r"tau_max must be a finite number; got inf\. .*leave tau_max out"):
        load_robot(write(tmp_path, JOINT + "tau_max = inf\n"))


@pytest.mark.parametrize(
    "text, match",
    [
        (LINK.replace("mass = 1.0", "mass = nan"), r"link\[1\]\.mass must be a finite number; got nan"),
        (LINK.replace("mass = 1.0", "mass = inf"), r"link\[1\]\.mass must be a finite number; got inf"),
        (LINK.replace("mass = 1.0", "mass = -2.0"), r"link\[1\]\.mass must be >= 0 \[kg\]; got -2\.0"),
        (LINK.replace("0.0, 0.0, 0.1]", "0.0, nan, 0.1]"), r"link\[1\]\.com\[1\] must be a finite number; got nan"),
        (LINK.replace("[0.01, 0.01, 0.01,", "[0.01, inf, 0.01,"), r"link\[1\]\.inertia.*\[1\] must be a finite"),
        (LINK.replace("[0.01, 0.01, 0.01,", "[-0.01, 0.01, 0.01,"), r"link\[1\].*inertia must be positive semi-def"),
        (LINK.replace("[0.01, 0.01, 0.01,", "[0.01, 0.01, 0.05,"), r"link\[1\].*inertia must satisfy the triangle"),
        (LINK.replace("0.0, 0.0, 0.0]", "0.02, 0.0, 0.0]"), r"link\[1\].*inertia must be positive semi-definite"),
        (LINK + "rotor_inertia = nan\n", r"link\[1\]\.rotor_inertia must be a finite number; got nan"),
        (LINK + "rotor_inertia = -1.0\n", r"link\[1\]\.rotor_inertia must be >= 0"),
    ],
    ids=["nan mass", "inf mass", "negative mass", "nan com", "inf inertia", "negative moment", "triangle", "not PD",
         "nan rotor", "negative rotor"],
)  # fmt: skip
def test_link_values_are_checked(tmp_path, text, match):
    with pytest.raises(RobotFileError, match=match):
        load_robot(write(tmp_path, JOINT + text))


@pytest.mark.parametrize("key", ["kt", "fc", "fs", "vs", "fv", "dv", "sigma0", "sigma1"])
@pytest.mark.parametrize("value", ["nan", "inf"])
def test_drive_values_must_be_finite(tmp_path, key, value):
    with pytest.raises(RobotFileError, match=rf"drive\[1\]\.{key} must be a finite number; got {value}"):
        load_robot(write(tmp_path, JOINT + f"[[drive]]\n{key} = {value}\n"))


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_gravity_must_be_finite(tmp_path, value):
    with pytest.raises(RobotFileError, match=rf"robot\.toml gravity\[2\] must be a finite number; got {value}"):
        load_robot(write(tmp_path, f"gravity = [0.0, 0.0, {value}]\n" + JOINT))


@pytest.mark.parametrize(
    "value, match",
    [
        ('"1e308 * 10"', r"'1e308 \* 10' \(= inf\)"),
        ("1" + "0" * 400, r"got inf"),
        ('"pi/0"', "a number or an expression"),
    ],
    ids=["expression overflow", "huge integer", "division by zero"],
)
def test_numbers_beyond_the_float_range(tmp_path, value, match):
    with pytest.raises(RobotFileError, match=rf"joint\[1\]\.qd_max must be .*{match}"):
        load_robot(write(tmp_path, JOINT + f"qd_max = {value}\n"))


def test_duplicate_joint_names(tmp_path):
    with pytest.raises(RobotFileError, match=r"joint\[2\]\.name must differ .*got 'J1', the name of joint\[1\]"):
        load_robot(write(tmp_path, JOINT + JOINT))


@pytest.mark.parametrize(
    "text, match",
    [
        ("joint = [1]\n", r"joint\[1\] must be a table; got 1"),
        ("link = [2.0]\n" + JOINT, r"link\[1\] must be a table; got 2\.0"),
        ("urdf = 5\n" + JOINT, r"\[urdf\] must be a table; got 5"),
        ("assumptions = 1\n" + JOINT, r"\[assumptions\] must be a table"),
        ("[assumptions]\nzero_parameters = 5\n" + JOINT, r"zero_parameters must be a list of strings; got 5"),
        ("[assumptions]\nmassless_links = [true]\n" + JOINT, r"massless_links must be a list of link numbers"),
        ("name = 3\n" + JOINT, r"robot\.toml name must be a non-empty string; got 3"),
        (JOINT.replace('"J1"', "[1]"), r"joint\[1\]\.name must be a non-empty string; got \[1\]"),
        ('[urdf]\npath = "missing.urdf"\n', r"\[urdf\]\.path must name an existing URDF; got 'missing.urdf'"),
        ("[urdf]\npath = 3\n", r"\[urdf\]\.path must be a non-empty string; got 3"),
    ],
    ids=str,
)
def test_values_of_the_wrong_kind(tmp_path, text, match):
    with pytest.raises(RobotFileError, match=match):
        load_robot(write(tmp_path, text))


# --- files that are not TOML text ------------------------------------------------------------------


@pytest.mark.parametrize(
    "content, match",
    [
        (b"\x00\x01\x02robot", "must be plain text; got a binary file"),
        (gzip.compress(JOINT.encode(), mtime=0), "must be plain text; got gzip-compressed data. Decompress"),
        (b"PK\x03\x04rest", "must be plain text; got a ZIP archive"),
        (("# caf\xe9\n" + JOINT).encode("latin-1"), r"must be UTF-8 text; got byte 0xe9 at line 1, column 6"),
    ],
    ids=["binary", "gzip", "zip", "latin-1"],
)
def test_files_that_are_not_text(tmp_path, content, match):
    with pytest.raises(RobotFileError, match=rf"robot file 'robot\.toml' {match}"):
        load_robot(write(tmp_path, content))


def test_a_directory_and_an_unreadable_file(tmp_path, monkeypatch):
    (tmp_path / "robot.toml").mkdir()
    with pytest.raises(RobotFileError, match="'robot.toml' must be a file; got a directory"):
        load_robot(tmp_path / "robot.toml")
    path = write(tmp_path, JOINT, "locked.toml")

    def denied(self):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(Path, "read_bytes", denied)
    with pytest.raises(RobotFileError, match="'locked.toml' must be readable; got permission denied"):
        load_robot(path)


def test_a_byte_order_mark_is_accepted(tmp_path):
    assert load_robot(write(tmp_path, b"\xef\xbb\xbf" + JOINT.encode())).n_dof == 1


def test_read_text_file_takes_only_parameter_errors(tmp_path):
    with pytest.raises(TypeError, match="error must be a ParameterError"):
        read_text_file(write(tmp_path, "x"), error=ValueError)


# --- the values themselves (the Python API) ---------------------------------------------------------


def test_joint_checks():
    assert Joint("j", tau_max=math.inf).tau_max == math.inf  # no torque limit
    with pytest.raises(RobotFileError, match="Joint 'j'.q_max must be finite .*; got inf"):
        Joint("j", q_max=math.inf)
    with pytest.raises(RobotFileError, match=r"Joint 'j'.a must be a number \[m\]; got nan"):
        Joint("j", a=np.float64("nan"))
    with pytest.raises(RobotFileError, match="Joint.name must be a non-empty string"):
        Joint("")
    with pytest.raises(RobotFileError, match="Joint 'j'.tau_max must be finite"):
        Joint("j", tau_max=-math.inf)


def test_link_inertia_checks():
    assert LinkInertia(0.0).mass == 0.0  # a massless link
    assert LinkInertia(1.0, inertia=[0.1, 0.1, 0.2, 0, 0, 0]).inertia[2, 2] == 0.2  # triangle equality
    with pytest.raises(RobotFileError, match=r"LinkInertia.mass must be a finite number >= 0 \[kg\]; got nan"):
        LinkInertia(float("nan"))
    with pytest.raises(RobotFileError, match=r"LinkInertia.com must be 3 finite numbers \[m\]; got \[0.0, inf, 0.0\]"):
        LinkInertia(1.0, com=[0, np.inf, 0])
    with pytest.raises(RobotFileError, match="LinkInertia.inertia must be finite"):
        LinkInertia(1.0, inertia=[np.nan, 0, 0, 0, 0, 0])
    with pytest.raises(RobotFileError, match="LinkInertia.inertia must satisfy the triangle inequality"):
        LinkInertia(1.0, inertia=np.diag([0.1, 0.1, 0.3]))
    with pytest.raises(RobotFileError, match="LinkInertia.com must be 3 numbers"):
        LinkInertia(1.0, com=["a", "b", "c"])


def test_drive_parameter_checks():
    with pytest.raises(RobotFileError, match="DriveParameters.fc must be a finite number; got nan"):
        DriveParameters(fc=float("nan"))
    with pytest.raises(RobotFileError, match="DriveParameters.sigma1 must be a finite number; got inf"):
        DriveParameters(sigma1=math.inf)


def test_robot_description_checks():
    with pytest.raises(RobotFileError, match=r"RobotDescription.joints must have distinct names; got 'j'"):
        RobotDescription("r", joints=(Joint("j"), Joint("j")))
    with pytest.raises(RobotFileError, match=r"RobotDescription.gravity must be 3 finite .*got \[0.0, 0.0, nan\]\."):
        RobotDescription("r", joints=(Joint("j"),), gravity=[0, 0, np.nan])
    with pytest.raises(RobotFileError, match=r"RobotDescription.rotor_inertia must be 1 finite .*got \[nan\]"):
        RobotDescription("r", joints=(Joint("j"),), rotor_inertia=[np.nan])
    with pytest.raises(RobotFileError, match=r"RobotDescription.joints\[0\] must be a Joint"):
        RobotDescription("r", joints=("j",))
    with pytest.raises(RobotFileError, match=r"RobotDescription.links\[0\] must be a LinkInertia"):
        RobotDescription("r", joints=(Joint("j"),), links=(1.0,))
    with pytest.raises(RobotFileError, match="RobotDescription.name must be a string"):
        RobotDescription(3, joints=(Joint("j"),))


def test_messages_show_plain_numbers():
    assert format_value(np.float64(0.1)) == "0.1"
    assert format_value(np.array([np.inf, -np.inf, np.nan])) == "[inf, -inf, nan]"
    assert format_value(list(range(100))).endswith("...]")
    assert format_value("x" * 200).endswith("...")
    with pytest.raises(RobotFileError) as info:
        Joint("j", qd_max=np.float64(-1.0))
    assert "np.float64" not in str(info.value) and "got -1.0" in str(info.value)


def test_inertia_violation_allows_round_off_and_point_masses():
    assert inertia_violation(np.zeros((3, 3))) is None
    assert inertia_violation(np.diag([-5e-20, -5e-20, 0.0])) is None
    assert inertia_violation(np.diag([0.1, 0.2, 0.3 + 1e-9])) is None
    assert "triangle" in inertia_violation(np.diag([0.1, 0.2, 0.31]))


# --- URDF -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, match",
    [
        ("not xml", r"URDF 'robot\.urdf' must be a valid URDF; .*XML_ERROR"),
        (urdf_text(mass="nan"), r"URDF 'robot\.urdf' .*Inertial: mass \[nan\] is not a float"),
        (urdf_text(lower="nan"), r"lower value \(nan\) is not a valid float"),
        (urdf_text(mass="-1.0"), r"robot\.urdf joint 'j1' \(link 'l1'\): LinkInertia.mass must be .*got -1\.0"),
        (urdf_text(lower="1.0", upper="-1.0"), r"robot\.urdf joint 'j1' .*lower must be below upper; got lower=1\.0"),
        ('<robot name="r"><link name="base"/></robot>', r"robot\.urdf must hold at least one revolute or prismatic"),
    ],
    ids=["not xml", "nan mass", "nan limit", "negative mass", "swapped limits", "no joints"],
)
def test_bad_urdf_files(tmp_path, capfd, text, match):
    path = write(tmp_path, text, "robot.urdf")
    with pytest.raises(RobotFileError, match=match):
        load_robot(path)
    out, err = capfd.readouterr()
    assert "Error:" not in out + err and "urdf_parser" not in out + err  # the parser's C++ noise stays captured


def test_captured_stderr_restores_the_terminal(capfd):
    import os

    with captured_stderr() as lines:
        os.write(2, b"noise from C++\n")
    os.write(2, b"after\n")
    assert lines == ["noise from C++"]
    assert capfd.readouterr().err == "after\n"


def test_urdf_table_limits_drives_and_refusals(tmp_path):
    write(tmp_path, urdf_text(), "arm.urdf")
    base = '[urdf]\npath = "arm.urdf"\n'
    robot = load_robot(write(tmp_path, base + "[urdf.limits.j1]\nqdd_max = 7.5\n[[drive]]\nkt = 2.0\n"))
    assert robot.qdd_max[0] == 7.5 and robot.drives[0].kt == 2.0 and robot.q_max[0] == 1.0
    with pytest.raises(RobotFileError, match=r"\[urdf.limits.j9\] must name a joint of the URDF; got 'j9'"):
        load_robot(write(tmp_path, base + "[urdf.limits.j9]\nqdd_max = 7.5\n"))
    with pytest.raises(RobotFileError, match=r"\[urdf.limits.j1\]\.qd_max must be a finite number; got nan"):
        load_robot(write(tmp_path, base + "[urdf.limits.j1]\nqd_max = nan\n"))
    with pytest.raises(RobotFileError, match=r"\[urdf.limits.j1\]: Joint 'j1'.q_min must be below q_max"):
        load_robot(write(tmp_path, base + "[urdf.limits.j1]\nq_min = 2.0\n"))
    with pytest.raises(RobotFileError, match=r"\[urdf.limits.j1\] has unknown key.*qdd_mx"):
        load_robot(write(tmp_path, base + "[urdf.limits.j1]\nqdd_mx = 2.0\n"))
    with pytest.raises(RobotFileError, match=r"must take its joints from the URDF; got \[\[joint\]\]"):
        load_robot(write(tmp_path, base + JOINT))
    with pytest.raises(RobotFileError, match=r"robot\.toml \[urdf\]\.path: URDF 'bad\.urdf' must be a valid URDF"):
        write(tmp_path, "<robot", "bad.urdf")
        load_robot(write(tmp_path, '[urdf]\npath = "bad.urdf"\n'))


def test_the_shipped_urdfs_still_load():
    panda = from_urdf(example_robot_urdf("panda_description/urdf/panda.urdf"))
    assert panda.n_dof == 9


# --- the size of the derivation ---------------------------------------------------------------------


@pytest.mark.parametrize("n_dof", [12, 50])
def test_the_sum_form_refuses_too_many_joints_quickly(n_dof):
    robot = from_dh([(0.1, math.pi / 2, 0.0, 0.0)] * n_dof)
    start = time.perf_counter()
    with pytest.raises(ParameterError, match=rf"n_dof must be at most {MAX_DOF} .*got {n_dof} joints.*Lock joints"):
        derive_psdm(robot, DeriveOptions(form="sum"))
    assert time.perf_counter() - start < 2.0


def test_the_largest_supported_robot_passes_the_size_check():
    check_derivation_size(from_dh([(0.1, math.pi / 2, 0.0, 0.0)] * MAX_DOF))
    assert derivation_memory_bytes(MAX_DOF) < 16 * 2**30 < derivation_memory_bytes(MAX_DOF + 1)
    with pytest.raises(ParameterError, match="1953125 points"):
        check_derivation_size(from_dh([(0.1, math.pi / 2, 0.0, 0.0)] * (MAX_DOF + 1)))


def test_prismatic_joints_count_by_their_smaller_grid():
    # the Panda with both fingers free: 7 revolute and 2 prismatic joints, derived by the slow lane test
    panda = from_urdf(example_robot_urdf("panda_description/urdf/panda.urdf"))
    assert panda.n_dof == 9 and derivation_grid_points(panda) == 5**7 * 3**2
    check_derivation_size(panda)


# --- payload.json -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "content, match",
    [
        ("{", r"payload\.json must be JSON such as"),
        ("[2.0]", r"payload\.json must hold a JSON object"),
        ('{"com": [0, 0, 0]}', r"payload\.json: Payload\.mass is missing"),
        ('{"mass": 1, "intertia": null}', r"payload\.json has unknown key\(s\) \['intertia'\]"),
        ('{"mass": "2"}', r"payload\.json: Payload\.mass must be a number; got '2'"),
        ('{"mass": NaN}', r"payload\.json: Payload\.mass must be a finite number >= 0 \[kg\]; got nan"),
        ('{"mass": -1.0}', r"payload\.json: Payload\.mass must be a finite number >= 0 \[kg\]; got -1\.0"),
        ('{"mass": 1, "com": [0, 0]}', r"Payload\.com must be 3 numbers .*got \[0, 0\]"),
        ('{"mass": 1, "com": [0, Infinity, 0]}', r"Payload\.com must be 3 finite coordinates"),
        ('{"mass": 1, "com": [0, 0, 0], "inertia": [[1, 0, 0], [0, 1]]}',
         r"Payload\.inertia must be 3x3 numbers \(every row complete\)"),
        ('{"mass": 1, "com": [0, 0, 0], "inertia": [1, 2, 3]}', r"Payload\.inertia must be 3x3 numbers"),
        ('{"mass": 1, "com": [0, 0, 0], "inertia": [[1, 0, 0], [0, 1, 0], [0, 0, 3]]}',
         r"Payload\.inertia must satisfy the triangle"),
        ('{"mass": 1, "com": [0, 0, 0], "inertia": [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]}',
         r"Payload\.inertia must be symmetric"),
        (b"\x1f\x8b\x08\x00", r"payload file 'payload\.json' must be plain text; got gzip"),
    ],
    ids=["not JSON", "a list", "no mass", "unknown key", "string mass", "nan mass", "negative mass", "short com",
         "inf com", "ragged inertia", "flat inertia", "triangle", "asymmetric", "gzip"],
)  # fmt: skip
def test_bad_payload_files(tmp_path, content, match):
    with pytest.raises(ParameterError, match=match):
        read_payload(write(tmp_path, content, "payload.json"))


def test_a_good_payload_file(tmp_path):
    payload = read_payload(
        write(tmp_path, '{"mass": 2, "com": [0, 0, 0], "inertia": [[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]]}', "p.json")
    )
    assert payload == Payload(mass=2.0, com=(0.0, 0.0, 0.0), inertia=((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))
