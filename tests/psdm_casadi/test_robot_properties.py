"""Property tests of the robot readers: whatever the bytes, a RobotDescription or a ParameterError, nothing else.

Random bytes exercise the text checks (binary, compressed, not UTF-8, not TOML or XML); mutated
copies of good files (a value replaced, a line dropped or repeated) exercise the value checks;
random mappings exercise the table-structure checks of ``robot_from_mapping``.
"""

import json
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from psdm_casadi import load_robot
from psdm_casadi.errors import ParameterError
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, RobotDescription, robot_from_mapping

SETTINGS = settings(
    max_examples=150,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)

URDF = """<robot name="arm">
<link name="base"/>
<link name="l1">
<inertial>
<origin xyz="0 0 0.1" rpy="0 0 0"/>
<mass value="2.0"/>
<inertia ixx="0.02" iyy="0.02" izz="0.01" ixy="0" ixz="0" iyz="0"/>
</inertial>
</link>
<link name="l2"><inertial><mass value="1.0"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
</inertial></link>
<joint name="j1" type="revolute">
<parent link="base"/>
<child link="l1"/>
<axis xyz="0 0 1"/>
<limit lower="-2" upper="2" velocity="3" effort="50"/>
</joint>
<joint name="j2" type="prismatic">
<parent link="l1"/>
<child link="l2"/>
<origin xyz="0.3 0 0"/>
<axis xyz="1 0 0"/>
<limit lower="-0.2" upper="0.2" velocity="1" effort="100"/>
</joint>
</robot>
"""
URDF_TABLE = (
    'name = "arm"\ngravity = [0.0, 0.0, -9.81]\n[urdf]\npath = "arm.urdf"\nlocked_joints = []\n'
    "[urdf.limits.j1]\nqdd_max = 12.0\ntau_max = 40.0\n[assumptions]\ndrive_inertia = true\n"
    "[[drive]]\nkt = 2.0\nfc = 1.0\n[[drive]]\nkt = 3.0\nfv = 0.5\n"
)
GOOD_FILES = [(BUILTIN_ROBOTS_DIR / name).read_text() for name in ("denso_vs6556g.toml", "scara.toml")] + [URDF_TABLE]

TOML_VALUES = st.one_of(
    st.sampled_from(
        ["nan", "inf", "-inf", "-1", "0", "1e400", "1" + "0" * 400, "true", "[]", "{}", '""', '"pi/0"', '"-pi/2"']
        + ["[nan, 0, 0]", "[1, 2]", "[[1]]", '"1e308*10"', "[true]", '["x"]', "{a = 1}", '"J1"', '"revolute"']
    ),
    st.floats().map(repr),
    st.integers().map(str),
    st.text(max_size=12).map(json.dumps),
)
XML_VALUES = st.one_of(
    st.sampled_from(["nan", "inf", "-1", "0", "", "1e400", "abc", "1 2", "0 0 0 0", "revolute", "continuous", "j1"]),
    st.floats().map(repr),
    st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters='"<>&'), max_size=8),
)


def load_or_refuse(path):
    """The RobotDescription of ``path``, or None when it is refused with a ParameterError; anything else fails."""
    try:
        robot = load_robot(path)
    except ParameterError:
        return None
    assert isinstance(robot, RobotDescription)
    assert robot.n_dof >= 1
    return robot


@st.composite
def mutated(draw, texts, values, pattern):
    """A good text with 1-3 edits: a value (``pattern`` group 1) replaced, a line dropped, or a line repeated."""
    text = draw(st.sampled_from(texts))
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["value", "value", "drop", "repeat"]))
        matches = list(re.finditer(pattern, text))
        lines = text.splitlines(keepends=True)
        if kind == "value" and matches:
            match = draw(st.sampled_from(matches))
            text = text[: match.start(1)] + draw(values) + text[match.end(1) :]
        elif lines:
            k = draw(st.integers(0, len(lines) - 1))
            lines[k : k + 1] = [] if kind == "drop" else [lines[k], lines[k]]
            text = "".join(lines)
    return text


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    path = tmp_path_factory.mktemp("robots")
    (path / "arm.urdf").write_text(URDF)
    return path


def test_the_good_files_load(folder):
    (folder / "arm_table.toml").write_text(URDF_TABLE)
    assert load_or_refuse(folder / "arm_table.toml").qdd_max[0] == 12.0
    (folder / "good.urdf").write_text(URDF)
    assert load_or_refuse(folder / "good.urdf").n_dof == 2


@SETTINGS
@given(data=st.binary(max_size=400))
def test_any_bytes_as_a_toml_robot_file(folder, data):
    path = folder / "any.toml"
    path.write_bytes(data)
    load_or_refuse(path)


@SETTINGS
@given(data=st.binary(max_size=400))
def test_any_bytes_as_a_urdf(folder, data):
    path = folder / "any.urdf"
    path.write_bytes(data)
    load_or_refuse(path)


@SETTINGS
@given(text=mutated(GOOD_FILES, TOML_VALUES, r"(?m)^\s*[A-Za-z_0-9]+\s*=\s*(.+?)\s*(?:#.*)?$"))
def test_mutated_toml_robot_files(folder, text):
    path = folder / "mutated.toml"
    path.write_text(text)
    load_or_refuse(path)


@SETTINGS
@given(text=mutated([URDF], XML_VALUES, r'="([^"]*)"'))
def test_mutated_urdf_files(folder, text):
    path = folder / "mutated.urdf"
    path.write_text(text)
    load_or_refuse(path)


KEYS = ["format", "name", "convention", "gravity", "joint", "link", "drive", "assumptions", "urdf", "a", "alpha", "d"]
KEYS += ["theta", "type", "mass", "com", "inertia", "kt", "fc", "path", "locked_joints", "limits", "zero_parameters"]
KEYS += ["massless_links", "drive_inertia", "q_min", "qd_max", "rotor_inertia", "j1", "extra"]
SCALARS = st.one_of(
    st.booleans(), st.integers(), st.floats(), st.text(max_size=6), st.sampled_from(["-pi/2", "arm.urdf", "revolute"])
)
TOML_LIKE = st.recursive(
    SCALARS,
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.sampled_from(KEYS), children, max_size=5),
    max_leaves=20,
)
DH_ROW = st.fixed_dictionaries(
    {key: st.one_of(st.floats(-1, 1), SCALARS) for key in ("a", "alpha", "d", "theta")},
    optional={key: TOML_LIKE for key in ("name", "type", "q_min", "qd_max", "tau_max")},
)
TABLE_ROWS = st.lists(st.dictionaries(st.sampled_from(KEYS), TOML_LIKE, max_size=4), min_size=1, max_size=3)
MAPPINGS = st.fixed_dictionaries(
    {},
    optional={
        "joint": st.lists(DH_ROW, min_size=1, max_size=3) | TOML_LIKE,
        "link": TABLE_ROWS | TOML_LIKE,
        "drive": TABLE_ROWS | TOML_LIKE,
        "assumptions": st.dictionaries(st.sampled_from(KEYS), TOML_LIKE, max_size=3) | TOML_LIKE,
        "urdf": st.fixed_dictionaries(
            {"path": st.sampled_from(["arm.urdf", "none.urdf"])},
            optional={"locked_joints": TOML_LIKE, "limits": TOML_LIKE},
        )
        | TOML_LIKE,
        **{key: TOML_LIKE for key in ("format", "name", "convention", "gravity")},
    },
)


@SETTINGS
@given(data=MAPPINGS)
def test_any_mapping_of_robot_keys(folder, data):
    try:
        robot = robot_from_mapping(data, source=folder / "mapping.toml")
    except ParameterError:
        return
    assert isinstance(robot, RobotDescription)
