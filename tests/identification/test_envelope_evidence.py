"""The envelope report names what a pushed link absorbs from the same evidence as the parameters the fit holds back.

References: the virtual robot's hidden truth. A tool at the flange alone is a payload on every pushed link and no
counterbalance is named; a cam counterbalance on joint 2 beside the tool is named on joint 2 although the tool's
parameters of link 5 are the most significant (a second effect is not crowded out); the heavy virtual arm (slow) with
its cam counterbalance taken into link 2 up to its envelope, named by joint 2's gravity departure. The naming itself
(``named_from_evidence``, ``named_by_departure``) against hand-made findings, held-back items and departures.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.diagnosis_prior import diagnosis_prior
from identification.calibration.envelope_report import (
    EnvelopeFinding,
    named_by_departure,
    named_from_evidence,
    pressed_findings,
    where,
)
from identification.calibration.gravity_departure import GravityDeparture
from identification.calibration.held_back import HeldBack, stored_held_back
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.virtual import effects as xp
from tests.identification.diagnosis_data import rigid_recording

TOOL = xp.Payload(mass=4.0, com=(0.0, 0.0, 0.1))
CAM = xp.CamCounterbalance(joint=1, amplitude=12.0, lobe=0.3)


def test_a_tool_alone_is_a_payload_on_every_pushed_link_from_the_evidence(denso, denso_model):
    """4 kg at the flange: links 3-5 pushed outward. Link 5's finding takes the effects of its held-back gravity
    torque (a body at the flange gives that sign, the torque spread over the joints): a payload, a counterbalance the
    alternative, the evidence stated in the message with the route that fits both. Nothing the robot file explains
    is picked beyond the tool's own parameters: no counterbalance is named anywhere first."""
    fit = identify_trajectories(denso, denso_model, [rigid_recording(denso, [TOOL])], TrajectoryOptions())
    assert fit.envelope and {f.absorbs for f in fit.envelope} == {"payload"}
    (flange,) = [f for f in fit.envelope if f.link == 4]
    assert flange.evidence.startswith("more gravity torque") and "a body at the flange can give it" in flange.evidence
    assert flange.alternatives == ("counterbalance",) and flange.effect_joint == -1
    assert f"The evidence ({flange.evidence}) fits a counterbalance or spring on" in flange.message
    assert "'psdm diagnose' against the robot file fits a spring or counterbalance too" in flange.message
    held = stored_held_back(fit.envelope_bounds)
    assert held and all(h.absorbs == "payload" for h in held), [(h.words, h.absorbs) for h in held]
    stored = flange.to_dict()
    assert stored["alternatives"] == ["counterbalance"] and stored["evidence"] == flange.evidence
    assert flange.message.startswith(f"{flange.pushed}. This is most likely a payload") and "pushed" not in stored
    assert flange.pushed.startswith("link 5 is pushed against its physical envelope")


def test_a_counterbalance_beside_a_tool_is_named_on_its_joint(denso, denso_model):
    """A cam counterbalance on joint 2 and the 4 kg tool: the tool's three parameters of link 5 are the most
    significant (thousands of standard deviations), the gravity torque of link 2 the data want (the cam's first
    harmonic has joint 2's gravity shape) is held by the pull; it is named a counterbalance on joint 2, its own
    joint, because no body at the flange gives it and the data ask for far more than a rough robot file explains."""
    fit = identify_trajectories(denso, denso_model, [rigid_recording(denso, [CAM, TOOL])], TrajectoryOptions())
    held = stored_held_back(fit.envelope_bounds)
    assert [h.absorbs for h in held[:3]] == ["payload"] * 3 and all("link 5" in h.words for h in held[:3])
    cam = [h for h in held if h.absorbs == "counterbalance"]
    assert cam and cam[0].words.startswith("the gravity torque of link 2") and cam[0].effect_joint == 1
    assert "a counterbalance or spring on joint 2" in cam[0].message and "psdm diagnose" in cam[0].message
    assert "no body at the flange gives it" in cam[0].message
    flange = [f for f in fit.envelope if f.link == 4]
    assert flange and flange[0].absorbs == "payload"


def _finding(link, bounds, absorbs, joint):
    return EnvelopeFinding(link, bounds, 1.0, 1.0, 1.0, 1.0, 0.1, 0.1, absorbs, joint, 2.0, 3.0, 100.0, "old")


def _item(parameter, absorbs, alternatives, effect_joint, evidence="less inertia; moves between rests"):
    return HeldBack(parameter, "words", 2, 0.0, -1.0, 0.1, 0.0, -10.0, 5.0, 20.0, absorbs, "envelope", "",
                    alternatives, effect_joint, evidence)  # fmt: skip


def test_a_pushed_link_takes_the_effects_of_its_most_significant_held_parameter(denso, denso_model):
    """A link whose parameters the fit holds back is named as the most significant of them is; a link without one,
    and a drive's bound, keep the bounds' naming; a payload keeps the joint the bounds refuse most on. Files written
    before the alternatives were stored read as none, their effect at the finding's joint."""
    owner = {}
    for k, name in enumerate(denso_model.base_names):
        owner.setdefault(int(np.argmax(np.abs(denso_model.parameter_map[k]).reshape(-1, 11).sum(axis=1))), name)
    link3, drive2, link5 = _finding(2, ("envelope",), "counterbalance", 2), _finding(1, ("drive inertia lower",),
                           "counterbalance", 1), _finding(4, ("mass upper",), "payload", 4)  # fmt: skip
    items = (_item(owner[2], "drive_dynamics", ("counterbalance",), 2), _item(owner[1], "payload", (), 1))
    named = named_from_evidence((link3, drive2, link5), items, denso_model, denso)
    three, two, five = named
    assert (three.absorbs, three.alternatives, where(three)) == ("drive_dynamics", ("counterbalance",), 2)
    assert "most likely a dynamic of the drive of joint 3" in three.message
    assert (
        "fits a counterbalance or spring on joint 3 (J3) as well" in three.message
        and "moves between rests" in three.message
    )
    assert two == drive2 and five == link5  # a drive's bound, a link with nothing held back
    old = {k: v for k, v in three.to_dict().items() if k not in ("alternatives", "evidence", "effect_joint")}
    assert pressed_findings([old]) == (old,) and diagnosis_prior({"standard": {"envelope_findings": [old]}}, denso)
    assert where(replace(three, effect_joint=-1)) == three.joint


def test_a_proximal_link_named_a_payload_is_a_counterbalance_where_its_joints_gravity_departs_alone(denso):
    """The bounds name every link pushed outward beside a payload a payload; a proximal one is named a counterbalance
    on the joint whose gravity torque departs from the file's alone, among those its weight carries up to its own (not a
    joint beyond it; the largest where several depart), the payload the alternative and the departure the evidence. The
    last two links with mass and a drive's bound keep their naming; no departures, nothing renamed; the departures are
    not computed where no link could be renamed."""
    link2, link3, link5 = (replace(_finding(i, ("envelope",), "payload", 4), pressed=True) for i in (1, 2, 4))
    drive = _finding(1, ("drive inertia upper",), "payload", 1)
    on_2, on_3, on_5 = (GravityDeparture(j, size, 5e3, 0.95, 0.6) for j, size in ((1, 900.0), (2, 1200.0), (4, 3e3)))
    named = named_by_departure((link2, link3, link5, drive), {1: on_2, 2: on_3, 4: on_5}, denso)
    two, three, five, same = named
    assert (two.absorbs, two.effect_joint, two.alternatives) == ("counterbalance", 1, ("payload",))
    assert two.evidence == on_2.evidence and "counterbalance or spring on joint 2" in two.message
    assert "The evidence (the fitted gravity torque of joint 2 leaves" in two.message and "payload" in two.message
    assert (three.absorbs, three.effect_joint) == ("counterbalance", 2)  # the largest up to its own joint, not joint 5
    assert five == link5 and same == drive
    assert named_by_departure((link2, link5), {}, denso) == (link2, link5)
    assert named_by_departure((link5,), lambda: pytest.fail("computed"), denso) == (link5,)


@pytest.mark.slow
def test_the_heavy_arms_counterbalance_inside_its_envelope_is_named(benchmark_modules):
    """The heavy virtual arm (``benchmarks/heavy_arm.py``, seed 0) without an offset column: a 100-200 kg tool pushes
    link 5, and link 2 takes the cam counterbalance on joint 2 into its first moment up to its envelope. Because a
    payload pulls every link outward, link 2's bound was named a payload too and the counterbalance was never named
    (the fit holds none of link 2's parameters back: it gives them what the data want). Now the fitted gravity
    torque of joint 2, which departs from the robot file's on that joint alone, names it on joint 2 beside the payload,
    opposing about the share of the file's gravity torque the simulated balancer takes on the recorded poses."""
    from diagnosis import _scenario
    from heavy_arm import EFFECTS, heavy_industrial_arm

    from identification.virtual.counterbalance import balance
    from psdm_casadi import derive_psdm

    robot = heavy_industrial_arm()
    truth, train, _ = _scenario("heavy", robot, EFFECTS, np.random.default_rng(0), 0)
    fit = identify_trajectories(robot, derive_psdm(robot), [train], TrajectoryOptions())
    assert any(f.link == 4 and f.absorbs == "payload" for f in fit.envelope)
    (link2,) = [f for f in fit.envelope if f.link == 1 and f.pressed]
    assert (link2.absorbs, link2.effect_joint, link2.alternatives) == ("counterbalance", 1, ("payload",))
    assert "counterbalance or spring on joint 2" in link2.message and "payload" in link2.message
    cam = next(effect for _, _, effect, p in truth if "share" in p)
    stated = float(link2.evidence.split("opposing ")[1].split("%")[0]) / 100.0
    assert stated == pytest.approx(balance(robot, cam, train.q[::20]).share, abs=0.15)
