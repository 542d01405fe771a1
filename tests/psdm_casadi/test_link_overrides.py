"""A robot file's ``[[link]]`` tables replace a URDF's link inertials (``psdm_casadi.link_overrides``).

Checked against Pinocchio's own model of the same URDF (what is not stated stays the file's) and against the
stated numbers (what is stated replaces it, for the whole body the joint moves).
"""

from __future__ import annotations

import logging

import numpy as np
import pinocchio as pin
import pytest

from psdm_casadi import load_robot
from psdm_casadi.errors import RobotFileError
from tests.psdm_casadi.test_urdf_stand_in import two_links

FIXED_TIP = '<link name="tip"/><joint name="t" type="fixed"><parent link="l2"/><child link="tip"/></joint></robot>'


def robot_file(tmp_path, links: str, urdf: str | None = None):
    (tmp_path / "arm.urdf").write_text(urdf or two_links().replace("</robot>", FIXED_TIP))
    path = tmp_path / "arm.toml"
    path.write_text('format = "psdm-robot/1"\n[urdf]\npath = "arm.urdf"\n' + links)
    return load_robot(path)


def test_a_stated_mass_com_and_inertia_replace_the_urdfs(tmp_path):
    stated = robot_file(tmp_path, '[[link]]\nname = "l2"\nmass = 2.5\ncom = [0.1, 0.0, 0.02]\n'
                        "inertia = [0.02, 0.03, 0.04, 0.001, 0.0, 0.0]\nrotor_inertia = 0.3\n")  # fmt: skip
    reference = pin.buildModelFromUrdf(str(tmp_path / "arm.urdf"))
    first = reference.inertias[1]
    assert stated.links[0].mass == first.mass and np.allclose(stated.links[0].com, first.lever)
    assert stated.links[1].mass == 2.5 and np.allclose(stated.links[1].com, [0.1, 0.0, 0.02])
    np.testing.assert_allclose(stated.links[1].inertia, [[0.02, 0.001, 0], [0.001, 0.03, 0], [0, 0, 0.04]])
    assert stated.rotor_inertia.tolist() == [0.0, 0.3]
    prior = stated.nominal_dynamic_parameters()
    assert prior[1, 0] == 2.5 and prior[1, 1] == pytest.approx(0.25)  # the prior's mass and first moment


def test_a_mass_alone_keeps_the_com_and_scales_the_inertia(tmp_path):
    stated = robot_file(tmp_path, '[[link]]\nname = "tip"\nmass = 3.0\n')  # a fixed link names its joint's body
    urdf = load_robot(tmp_path / "arm.urdf")
    assert stated.links[1].mass == 3.0 and np.allclose(stated.links[1].com, urdf.links[1].com)
    np.testing.assert_allclose(stated.links[1].inertia, 3.0 * urdf.links[1].inertia)  # URDF mass 1.0
    np.testing.assert_array_equal(stated.nominal_dynamic_parameters()[0], urdf.nominal_dynamic_parameters()[0])


def test_a_stated_inertia_replaces_an_unusable_one_and_a_mass_alone_keeps_it_reported(tmp_path, caplog):
    bad = two_links(ixx1="0.05")  # link 1 breaks the triangle inequality
    with caplog.at_level(logging.WARNING, logger="psdm_casadi"):
        kept = robot_file(tmp_path, '[[link]]\nname = "l1"\nmass = 4.0\n', bad)
    assert [r.joint for r in kept.replaced_inertias] == [0] and "'l1' (joint 1) is unusable" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="psdm_casadi"):
        fixed = robot_file(tmp_path, '[[link]]\nname = "l1"\ninertia = [0.01, 0.01, 0.01, 0, 0, 0]\n', bad)
    assert fixed.replaced_inertias == () and np.allclose(fixed.links[0].inertia, 0.01 * np.eye(3))
    assert "unusable" not in caplog.text  # stated: no stand-in, no warning


@pytest.mark.parametrize(
    "links, message",
    [
        (
            '[[link]]\nname = "l9"\nmass = 1.0\n',
            r"link\[1\]\.name must be a URDF link moved by a joint; got 'l9'\. "
            r"Links are \['l1', 'l2', 'tip'\]",
        ),
        ("[[link]]\nmass = 1.0\n", r"link\[1\]\.name must name a URDF link; got None"),
        ('[[link]]\nname = "l2"\n', r"link\[1\] states nothing about 'l2'; give mass, com, inertia or rotor_inertia"),
        ('[[link]]\nname = "l2"\nmas = 1.0\n', r"link\[1\] has unknown key\(s\) \['mas'\]"),
        ('[[link]]\nname = "l2"\nmass = -1.0\n', r"link\[1\]\.mass must be >= 0 \[kg\]; got -1\.0"),
        ('[[link]]\nname = "l2"\nmass = nan\n', r"link\[1\]\.mass must be a finite number; got nan"),
        ('[[link]]\nname = "l2"\ninertia = [0.01, 0.01, 0.05, 0, 0, 0]\n', r"link\[1\]: .*triangle inequality"),
        (
            '[[link]]\nname = "l2"\nmass = 1.0\n[[link]]\nname = "tip"\nmass = 2.0\n',
            r"link\[2\] names 'tip', moved by the same joint as link\[1\] \(l2 \+ tip are one body\)",
        ),
    ],
    ids=["unknown link", "no name", "nothing stated", "typo", "negative", "nan", "not physical", "twice"],
)
def test_bad_link_tables_are_refused_naming_the_table_and_the_fix(tmp_path, links, message):
    with pytest.raises(RobotFileError, match=r"arm\.toml " + message):
        robot_file(tmp_path, links)
