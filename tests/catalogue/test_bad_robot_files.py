"""The bad-input catalogue for robot files (TOML and URDF) and payload.json: each refused cleanly, naming input and fix.

Most cases run ``psdm derive`` (the quickest command that loads a robot); some run the other
commands that load one (``codegen``, ``excite``, ``experiment``, ``simulate``) and the payload.json
cases run ``psdm identify`` on a one-joint robot, which reads the payload from the data folder.
"""

import gzip
from pathlib import Path

import pytest

import psdm_casadi.text_file
from tests.catalogue.harness import BadInput, check_refusal

JOINT = '[[joint]]\nname = "J{k}"\na = 0.1\nalpha = "pi/2"\nd = 0.0\ntheta = 0.0\n'
LINK = "[[link]]\nmass = 1.0\ncom = [0.0, 0.0, 0.1]\ninertia = [0.01, 0.01, 0.01, 0.0, 0.0, 0.0]\n"
DRIVE = "[[drive]]\nkt = 2.0\nfc = 1.0\nfv = 0.5\n"
ONE = JOINT.format(k=1)


def robot(*extra: str, header: str = "", joint: str = ONE) -> str:
    """A one-joint robot file with ``extra`` lines appended to its joint table (then any further tables)."""
    return header + joint + "".join(extra)


def urdf(mass="1.0", ixx="0.1", lower="-1.0", upper="1.0"):
    return (
        f'<robot name="r"><link name="base"/><link name="l1"><inertial><mass value="{mass}"/>'
        f'<inertia ixx="{ixx}" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>'
        f'<limit lower="{lower}" upper="{upper}" velocity="2" effort="10"/></joint></robot>'
    )


def dh_robot(n_dof: int) -> str:
    return "".join(JOINT.format(k=k + 1) for k in range(n_dof))


def derive(name, text, *expect):
    """``psdm derive robot.toml`` on ``text``: the message names robot.toml and the expected words."""
    return BadInput(name, ("derive", "robot.toml"), expect=("robot.toml", *expect), files={"robot.toml": text})


def derive_urdf(name, text, *expect):
    return BadInput(name, ("derive", "arm.urdf"), expect=("arm.urdf", *expect), files={"arm.urdf": text})


FINITE = "give a finite value"
INERTIA_FIX = "about the centre of mass"

NUMBERS = [
    derive("joint a is nan", robot().replace("a = 0.1", "a = nan"), "joint[1].a", "got nan", FINITE),
    derive("joint d is inf", robot().replace("d = 0.0", "d = inf"), "joint[1].d", "got inf", FINITE),
    derive("theta overflows", robot().replace("theta = 0.0", 'theta = "1e308 * 10"'), "joint[1].theta", "= inf"),
    derive("q_min is nan", robot("q_min = nan\n"), "joint[1].q_min", "got nan", FINITE),
    derive("q_max is inf", robot("q_max = inf\n"), "joint[1].q_max", "got inf", FINITE),
    derive("q_min is -inf", robot("q_min = -inf\n"), "joint[1].q_min", "got -inf", FINITE),
    derive("qd_max is nan", robot("qd_max = nan\n"), "joint[1].qd_max", "got nan", FINITE),
    derive("qd_max is inf", robot("qd_max = inf\n"), "joint[1].qd_max", "got inf", FINITE),
    derive("qdd_max is inf", robot("qdd_max = inf\n"), "joint[1].qdd_max", "got inf", FINITE),
    derive("tau_max is nan", robot("tau_max = nan\n"), "joint[1].tau_max", "got nan", "leave tau_max out"),
    derive("tau_max is inf", robot("tau_max = inf\n"), "joint[1].tau_max", "got inf", "leave tau_max out"),
    derive("qd_max is a huge integer", robot("qd_max = 1" + "0" * 400 + "\n"), "joint[1].qd_max", "got inf"),
    derive("swapped limits", robot("q_min = 1.0\nq_max = -1.0\n"), "joint[1]", "q_min must be below q_max", "swap"),
    derive("gravity is nan", robot(header="gravity = [0.0, 0.0, nan]\n"), "gravity[2]", "got nan", FINITE),
    derive("gravity is inf", robot(header="gravity = [inf, 0.0, 0.0]\n"), "gravity[0]", "got inf", FINITE),
    derive("duplicate joint names", robot(joint=ONE + ONE), "joint[2].name", "'J1'", "rename one"),
    derive("empty joint name", robot().replace('"J1"', '""'), "joint[1].name", "non-empty string", "quotes"),
]

LINKS = [
    derive("mass is nan", robot(LINK.replace("mass = 1.0", "mass = nan")), "link[1].mass", "got nan", "in kg"),
    derive("mass is inf", robot(LINK.replace("mass = 1.0", "mass = inf")), "link[1].mass", "got inf", "in kg"),
    derive("negative mass", robot(LINK.replace("mass = 1.0", "mass = -3.0")), "link[1].mass", ">= 0", "in kg"),
    derive("com is nan", robot(LINK.replace("[0.0, 0.0, 0.1]", "[nan, 0.0, 0.1]")), "link[1].com[0]", "got nan"),
    derive("com is inf", robot(LINK.replace("[0.0, 0.0, 0.1]", "[0.0, 0.0, inf]")), "link[1].com[2]", "got inf"),
    derive(
        "inertia is nan",
        robot(LINK.replace("[0.01, 0.01, 0.01,", "[0.01, nan, 0.01,")),
        "link[1].inertia",
        "[1]",
        "got nan",
    ),
    derive(
        "negative principal moment",
        robot(LINK.replace("[0.01, 0.01, 0.01,", "[-0.01, 0.01, 0.01,")),
        "link[1]",
        "inertia must be positive semi-definite",
        INERTIA_FIX,
    ),
    derive(
        "inertia not positive definite",
        robot(LINK.replace("0.0, 0.0, 0.0]", "0.0, 0.0, 0.05]")),
        "link[1]",
        "positive semi-definite",
        INERTIA_FIX,
    ),
    derive(
        "triangle inequality",
        robot(LINK.replace("[0.01, 0.01, 0.01,", "[0.01, 0.02, 0.04,")),
        "link[1]",
        "triangle inequality",
        "ixx + iyy >= izz",
        INERTIA_FIX,
    ),
    derive("rotor inertia is nan", robot(LINK + "rotor_inertia = nan\n"), "link[1].rotor_inertia", "got nan"),
    derive("negative rotor inertia", robot(LINK + "rotor_inertia = -0.1\n"), "link[1].rotor_inertia", "fix the sign"),
    derive("link is not a table", robot(header="link = [1.0]\n"), "link[1]", "must be a table", "[[link]]"),
]

DRIVES = [
    derive("kt is nan", robot(DRIVE.replace("kt = 2.0", "kt = nan")), "drive[1].kt", "got nan", FINITE),
    derive("kt is negative", robot(DRIVE.replace("kt = 2.0", "kt = -2.0")), "drive[1]", "kt must be positive", "fix"),
    derive("fc is inf", robot(DRIVE.replace("fc = 1.0", "fc = inf")), "drive[1].fc", "got inf", FINITE),
    derive("fv is nan", robot(DRIVE.replace("fv = 0.5", "fv = nan")), "drive[1].fv", "got nan", FINITE),
    derive("sigma0 is inf", robot(DRIVE + "sigma0 = inf\n"), "drive[1].sigma0", "got inf", FINITE),
    derive("dv is nan", robot(DRIVE + "dv = nan\n"), "drive[1].dv", "got nan", FINITE),
    derive("negative friction", robot(DRIVE.replace("fc = 1.0", "fc = -1.0")), "drive[1]", "fc must be >= 0", "sign"),
]

FILES = [
    derive("binary file", b"\x00\x01\x02\x03robot\xff", "must be plain text", "binary", "give the text file"),
    derive("gzip data", gzip.compress(ONE.encode(), mtime=0), "gzip-compressed", "decompress it first"),
    derive(
        "latin-1 comment", ("# réglé\n" + ONE).encode("latin-1"), "utf-8", "0xe9", "line 1", "save the file as utf-8"
    ),
    derive("not TOML", "[[joint]\na = 1\n", "must be valid toml", "line 1", "fix the syntax"),
    derive("empty file", "", "[[joint]]", "needs at least one"),
    derive("joint is not a table", "joint = [1]\n", "joint[1]", "must be a table", "[[joint]]"),
    derive(
        "zero_parameters not a list", robot(header="[assumptions]\nzero_parameters = 5\n"), "zero_parameters", "list"
    ),
    BadInput(
        "robot file is a directory",
        ("derive", "robot.toml"),
        expect=("robot.toml", "got a directory", "give the path of the robot file inside it"),
        files={"robot.toml/readme.txt": "not a robot"},
    ),
]

URDFS = [
    derive_urdf("urdf not xml", "not xml at all", "must be a valid urdf", "xml_error", "fix the file"),
    derive_urdf("urdf binary", b"\x00\x01urdf", "must be plain text", "binary"),
    derive_urdf("urdf gzip", gzip.compress(urdf().encode(), mtime=0), "gzip-compressed", "decompress"),
    derive_urdf("urdf nan mass", urdf(mass="nan"), "mass [nan] is not a float", "fix the file"),
    derive_urdf("urdf nan limit", urdf(lower="nan"), "lower value (nan)", "fix the file"),
    derive_urdf("urdf negative mass", urdf(mass="-1.0"), "joint 'j1'", "link 'l1'", "mass must be", "in kg"),
    derive_urdf("urdf swapped limits", urdf(lower="1.0", upper="-1.0"), "joint 'j1'", "lower must be below", "swap"),
    BadInput(
        "urdf table names a missing file",
        ("derive", "robot.toml"),
        expect=("robot.toml", "[urdf].path", "'missing.urdf'", "check the path"),
        files={"robot.toml": '[urdf]\npath = "missing.urdf"\n'},
    ),
    BadInput(
        "urdf table with dh rows",
        ("derive", "robot.toml"),
        expect=("robot.toml", "[[joint]]", "[urdf.limits."),
        files={"robot.toml": '[urdf]\npath = "arm.urdf"\n' + ONE, "arm.urdf": urdf()},
    ),
    BadInput(
        "urdf limits for an unknown joint",
        ("derive", "robot.toml"),
        expect=("robot.toml", "[urdf.limits.j9]", "'j9'", "check the spelling"),
        files={"robot.toml": '[urdf]\npath = "arm.urdf"\n[urdf.limits.j9]\nqdd_max = 5.0\n', "arm.urdf": urdf()},
    ),
    BadInput(
        "urdf limit is nan",
        ("derive", "robot.toml"),
        expect=("robot.toml", "[urdf.limits.j1].qd_max", "got nan", FINITE),
        files={"robot.toml": '[urdf]\npath = "arm.urdf"\n[urdf.limits.j1]\nqd_max = nan\n', "arm.urdf": urdf()},
    ),
]


def derive_sum_form(name, text, *expect):
    """``psdm derive robot.toml --form sum``: the paper's monomial table, refused beyond 8 revolute joints."""
    return BadInput(
        name, ("derive", "robot.toml", "--form", "sum"), expect=("robot.toml", *expect), files={"robot.toml": text}
    )


SIZE = [
    derive_sum_form("12 joints", dh_robot(12), "12 joints", "at most 8", "lock joints", "--form auto"),
    derive_sum_form("50 joints", dh_robot(50), "50 joints", "at most 8", "lock joints", "--form auto"),
]

OTHER_COMMANDS = [
    BadInput(
        "codegen nan mass",
        ("codegen", "robot.toml", "--out", "c"),
        expect=("robot.toml", "link[1].mass", "got nan"),
        files={"robot.toml": robot(LINK.replace("mass = 1.0", "mass = nan"))},
    ),
    BadInput(
        "codegen 12 joints in the sum form",
        ("codegen", "robot.toml", "--out", "c", "--form", "sum"),
        expect=("12 joints", "monomial table", "--form recursive"),
        files={"robot.toml": dh_robot(12)},
    ),
    BadInput(
        "excite inf velocity limit",
        ("excite", "robot.toml"),
        expect=("robot.toml", "joint[1].qd_max", "got inf", FINITE),
        files={"robot.toml": robot("qd_max = inf\n")},
    ),
    BadInput(
        "experiment duplicate names",
        ("experiment", "gravity", "robot.toml"),
        expect=("robot.toml", "joint[2].name", "rename one"),
        files={"robot.toml": robot(joint=ONE + ONE)},
    ),
    BadInput(
        "simulate triangle inequality",
        ("simulate", "robot.toml", "--experiment", "sine", "--out", "sim"),
        expect=("robot.toml", "link[1]", "triangle inequality", INERTIA_FIX),
        files={"robot.toml": robot(LINK.replace("[0.01, 0.01, 0.01,", "[0.01, 0.01, 0.03,"), DRIVE)},
    ),
    BadInput(
        "simulate latin-1 urdf table",
        ("simulate", "robot.toml", "--experiment", "sine", "--out", "sim"),
        expect=("robot.toml", "utf-8", "save the file as utf-8"),
        files={"robot.toml": ('# Müller\n[urdf]\npath = "arm.urdf"\n').encode("latin-1"), "arm.urdf": urdf()},
    ),
]


def identify(name, payload, *expect):
    """``psdm identify`` of a one-joint robot on a data folder whose payload.json is ``payload``."""
    return BadInput(
        name,
        ("identify", "robot.toml", "--data", "data", "--out", "out"),
        expect=("payload.json", *expect),
        files={"robot.toml": robot(LINK, DRIVE), "data/payload.json": payload},
    )


PAYLOADS = [
    identify("payload not JSON", "mass = 2\n", "must be json", '{"mass": 2.0'),
    identify("payload is a list", "[2.0, 0, 0]", "must hold a json object", '{"mass": 2.0'),
    identify("payload without mass", '{"com": [0, 0, 0.1]}', "payload.mass is missing", "add the mass in kg"),
    identify("payload misspelt key", '{"mass": 2, "intertia": null}', "'intertia'", "check the spelling"),
    identify("payload nan mass", '{"mass": NaN}', "payload.mass", "got nan", "give the mass in kg"),
    identify("payload negative mass", '{"mass": -2.0}', "payload.mass", ">= 0", "give the mass in kg"),
    identify("payload short com", '{"mass": 2, "com": [0.1, 0]}', "payload.com", "[0.1, 0]", '"com": [x, y, z]'),
    identify(
        "payload ragged inertia",
        '{"mass": 2, "com": [0, 0, 0], "inertia": [[0.1, 0, 0], [0, 0.1]]}',
        "payload.inertia",
        "3x3",
        "every row complete",
    ),
    identify(
        "payload unphysical inertia",
        '{"mass": 2, "com": [0, 0, 0], "inertia": [[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.5]]}',
        "payload.inertia",
        "triangle inequality",
        "about the centre of mass",
    ),
    identify("payload binary", b"\x1f\x8b\x08\x00\x00", "gzip-compressed", "decompress"),
]

CASES = NUMBERS + LINKS + DRIVES + FILES + URDFS + SIZE + OTHER_COMMANDS + PAYLOADS


def test_the_catalogue_is_large_and_its_names_unique():
    assert len(CASES) >= 45
    assert len({case.name for case in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=str)
def test_bad_robot_input_is_refused_cleanly(case, tmp_path, capsys, monkeypatch):
    check_refusal(case, tmp_path, capsys, monkeypatch)


class _LockedPath(type(Path())):
    """A path whose ``locked.toml`` cannot be read, as for a user without the permission (the tests run as root)."""

    def read_bytes(self):
        if self.name == "locked.toml":
            raise PermissionError(13, "Permission denied", str(self))
        return super().read_bytes()


def test_an_unreadable_robot_file_is_refused_cleanly(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(psdm_casadi.text_file, "Path", _LockedPath)
    case = BadInput(
        "unreadable robot file",
        ("derive", "locked.toml"),
        expect=("locked.toml", "permission denied", "check the file's permissions"),
        files={"locked.toml": ONE},
    )
    check_refusal(case, tmp_path, capsys, monkeypatch)
