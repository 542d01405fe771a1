"""An absorbed effect is named only where the data clearly ask for it (issue 25, item 1).

The consistent fit's bounds (a link's envelope and its centre of mass's reach, its mass bounds, a drive inertia's
bounds) refuse the data some torque, and the report names what that torque most likely is: a counterbalance or
spring, a payload (``envelope_report``, ``held_back``, ``gravity_departure``). A bound can be active with no such
effect behind it: a robot file whose link is off by more than the bounds allow, or a rotor inertia the file does not
state, which the base parameters merge into a link. The bounds then refuse a torque of the order of the noise, and
the reading of which parameters moved names an effect the arm does not have (a cobot on motor currents whose file
states no rotors, link 2 held at its reach: "a counterbalance or spring on joint 2" at 1.1 x the noise, and it has
none).

The rule (``NAMING_RULE``): a counterbalance or spring, or a payload named on a link other than the last two with
mass, is named only where the torque the bounds refuse on the joint it acts on (a counterbalance or spring: its own
joint; a payload: every joint that carries it, the one refused most) is at least ``NAME_SIGMA`` times that joint's
noise. The refused torque is what the unbounded least squares show and the bounded fit does not give: the RMS by which
the bounded fit's residual on the training data exceeds theirs, per joint (``refused_noise``). The noise is one the
effect cannot inflate (``angle_noise``): the residual of the same least squares less what a torque of each joint's
own angle (a counterbalance's or spring's law; a payload is in the links' columns already) explains beyond a torque
offset per joint; where that is above the least squares' own noise, theirs. Their residual alone held the effect's
part their columns cannot give, and a large counterbalance raised the noise it was judged against. A constant is no
torque of the angle: a true offset the model lacks (its column off) is never evidence for a counterbalance, and where
the data hold one (the joint's own offset takes its noise down ``NAME_SIGMA``-fold: ``JointNoise``) the finding
names it. ``NAME_SIGMA`` is 2: a
torque a single sample shows beyond two standard deviations of its noise, where a plot of the residual shows it. The
statistics of many samples do not decide it: over thousands of samples a refusal of a tenth of the noise is already
significant, and a robot file's link off beyond its bounds, or an unstated rotor, gives that (the warning itself
starts at ``envelope_report.MIN_REFUSED_SIGMA``, 1). The last two links with mass pushed outward are a payload's own
signature, not a reading of what moved: a tool at the flange sits there and moves them either way
(``absorbed_effect``), so they name it at any refusal the warning reports (the Kinova Gen3's vendor URDF, link 7 at
its mass bound: its undocumented tool, at 0.9 x the noise).

That noise keeps the part of a counterbalance an offset gives as well, and over a short travel that is most of what
the links leave of it (the Denso's cam, a cobot's cam on joint 2: judged against a noise of several times the
sensor's, their margins over ``NAME_SIGMA`` were thin). So a counterbalance is also asked for by the refused torque's
part a torque of its joint's own angle gives beyond an offset (``angle_refused``: on the joint's rows, its projection
on the angle's Fourier series and a constant less its projection on the constant, ``angle_noise.AngleShare``), against
the joint's own noise, the residual with the series and an offset on every joint (``JointNoise.own``: neither the
effect nor an offset the model lacks inflates it), where that part is most of the refused torque beyond its offset
(``ANGLE_SHARE``): a counterbalance's torque is one of its angle alone. A true offset gives that part
nothing, and the links an offset or a robot file bent refuse a torque of several angles, of which a joint's own
angle gives a part and never most of it.

A counterbalance or gravity spring balances a gravity torque: on a joint gravity can give no torque over the recorded
poses (an upright arm's base axis, ``gravity_free``: ``gravity_load.joints_carrying_gravity``, the arm's kinematics
and not the robot file's masses, so a joint whose distal links the file states massless still carries a tool) none
is named, whatever the data ask; the finding then names no effect.

A counterbalance the links take inside their envelopes is not refused: beside a tool that pulls every link outward,
a shoulder's balancer goes into a proximal link's first moment, the bounds refuse its joint less than the noise, and
the link is named after the departure of that joint's gravity torque from the robot file's alone
(``envelope_report.named_by_departure``). The data ask for it there by that departure: where their own least squares
depart on that joint alone by at least ``NAME_SIGMA`` noise levels (``departure_ask``), it is named as the refused
torque would name it.

Below it a pressed finding is still reported (the bounds hold the link and the data press on it), naming no effect
(``UNNAMED``) and no route: with motor currents as the torque source and no rotor inertia stated for the joint, the
joint's rotor inertia is named instead (``drive_inertia``: the base parameters merge it into the link, and so does a
held-back inertia about the joint the data want larger); otherwise the robot file's link off by more than its bounds
allow, or an effect too small to tell. Only bounds are judged so: a parameter only the pull towards the robot file
holds back (``held_back``, holder ``"pull"``) keeps its naming.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache, partial

import numpy as np

from identification.calibration.envelope_report import outward, where
from identification.data.excitation_check import joint_label

__all__ = [
    "ANGLE_SHARE",
    "NAMED_EFFECTS",
    "NAME_SIGMA",
    "NAMING_RULE",
    "UNNAMED",
    "angle_refused",
    "gravity_free",
    "named_where_asked",
    "refused_noise",
]

#: The torque the bounds refuse on an effect's joint, in noise levels of the joint, from which the effect is named.
NAME_SIGMA = 2.0
#: The share of the refused torque beyond its offset that a torque of a joint's own angle must give for it to ask for
#: a counterbalance there: most of it (a counterbalance's torque is one of its angle alone; links an offset or a robot
#: file bent refuse a torque of several angles, of which the joint's own gives a part).
ANGLE_SHARE = 0.5
#: The effects this rule judges (``absorbed_effect.ABSORBED_EFFECTS``' absorbed loads and torques of the angle; a
#: payload on the last two links with mass is its own signature and not judged).
NAMED_EFFECTS = ("counterbalance", "payload")
#: What a finding under the rule names: no effect.
UNNAMED = "unnamed"
#: The rule in the report's words.
NAMING_RULE = (
    f"a counterbalance, or a payload on a link before the last two, is named only where the bounds refuse the joint it "
    f"acts on at least {NAME_SIGMA:g} x its noise of RMS torque (the bounded fit's residual over the unbounded least "
    "squares'), a torque each sample shows beyond two standard deviations of its noise (the least squares' residual "
    "less what a torque of each joint's angle explains beyond an offset: a noise the effect cannot inflate), or a "
    "counterbalance where the refused torque's part a torque of its joint's angle gives beyond an offset is as large "
    "against the joint's noise with such a torque and an offset, or one the links take inside their envelopes where "
    "the unbounded least squares' gravity torque of that joint alone departs from the robot file's by as much; never "
    "a counterbalance on a joint gravity gives no torque"
)


def refused_noise(equations, x_fit, x_ols, sigma) -> np.ndarray:
    """Per joint, the RMS torque by which the bounded fit's residual (``x_fit``) exceeds the unbounded least squares'
    (``x_ols``) on the training data's normal ``equations``, in noise levels ``sigma`` of the joint (or a callable
    giving them: ``angle_noise.effect_free_noise``)."""
    sigma = sigma() if callable(sigma) else sigma
    return _refused_rms(equations, x_fit, x_ols) / np.maximum(np.asarray(sigma, dtype=float), 1e-12)


def _refused_rms(equations, x_fit, x_ols) -> np.ndarray:
    """Per joint, the RMS torque [N m] by which the residual of ``x_fit`` exceeds that of ``x_ols``."""
    growth = equations.residual_sum(np.asarray(x_fit)) - equations.residual_sum(np.asarray(x_ols))
    return np.sqrt(np.maximum(growth, 0.0) / np.maximum(equations.count, 1))


def angle_refused(equations, x_fit, x_ols, noise) -> np.ndarray:
    """Per joint, the part of the torque the bounded fit (``x_fit``) refuses the unbounded least squares (``x_ols``)
    that a torque of the joint's own angle gives beyond a torque offset (``angle_noise.AngleShare``; never more than
    the refused torque, ``refused_noise``'s RMS on ``equations``: where the bounded fit leaves a joint no worse,
    nothing is refused it), counted where it is more than ``ANGLE_SHARE`` of the refused torque beyond its offset
    (a torque of that angle alone, as a counterbalance's; links a robot file or an offset bent refuse a
    torque of several angles, of which a joint's own angle gives a part), in noise levels of the joint's own noise
    (``JointNoise.own``: neither such a torque nor an offset inflates it); ``noise``: a callable giving the
    ``angle_noise.JointNoise``. Zero without an ``AngleShare``."""
    joint_noise = noise()
    if joint_noise.angle is None:
        return np.zeros(len(joint_noise.noise))
    delta = np.asarray(x_ols, dtype=float) - np.asarray(x_fit, dtype=float)
    rms = np.minimum(joint_noise.angle.rms(delta), _refused_rms(equations, x_fit, x_ols))
    rms = np.where(joint_noise.angle.share(delta) > ANGLE_SHARE, rms, 0.0)  # a torque of that angle, not the links'
    return rms / np.maximum(np.asarray(joint_noise.own, dtype=float), 1e-12)


def gravity_free(noise) -> np.ndarray:
    """Per joint, whether gravity can give it no torque over the recorded poses (``JointNoise.carries``,
    ``gravity_load.joints_carrying_gravity``): no counterbalance can act there. ``noise``: None (nothing known: none)
    or a callable giving the ``angle_noise.JointNoise``."""
    joint_noise = None if noise is None else noise()
    if joint_noise is None or joint_noise.carries is None:
        return np.zeros(0, dtype=bool)
    return ~np.asarray(joint_noise.carries, dtype=bool)


def _asked(absorbs: str, joint: int, refused, departed, angle=None, free=tuple) -> bool:
    """Whether the data clearly ask for ``absorbs`` acting on ``joint`` (0-based): an effect this rule does not judge
    is asked for, one of ``NAMED_EFFECTS`` where the torque refused on its joint (a payload: the most refused;
    ``refused()``: ``refused_noise``) is at least ``NAME_SIGMA`` noise levels, a counterbalance also where the data's
    gravity torque of its joint departs alone by as much (``departed()``: ``departure_ask.departed_noise``) or the
    refused torque's part a torque of its angle gives beyond an offset is (``angle()``: ``angle_refused``), and never
    on a joint gravity gives no torque (``free()``: ``gravity_free``, asked only for a counterbalance: it asks for the
    noise's pass over the recordings)."""
    if absorbs not in NAMED_EFFECTS:
        return True
    if absorbs == "payload":
        return float(np.max(refused())) >= NAME_SIGMA
    free = free()
    if joint < len(free) and free[joint]:
        return False
    by_angle = angle is not None and float(angle()[joint]) >= NAME_SIGMA
    return by_angle or float(refused()[joint]) >= NAME_SIGMA or float(departed()[joint]) >= NAME_SIGMA


def named_where_asked(findings, held, refused, robot, currents: bool = False, noise=None, departed=None,
                      angle=None) -> tuple:  # fmt: skip
    """``(findings, held)``: the envelope's findings (``envelope_report.EnvelopeFinding``) and the parameters held
    back by a bound (``held_back.HeldBack``, holder ``"envelope"``) with each counterbalance, spring or payload the
    data do not clearly ask for (``NAMING_RULE``; ``refused``: ``refused_noise``, or a callable giving it, called
    once and only when an effect is judged; ``departed``: per joint the departure of the data's gravity torque on it
    alone in noise levels, ``departure_ask.departed_noise``, or a callable giving it, called once and only when a
    counterbalance is refused less; None: none) named as none, or on motor currents (``currents``) as the joint's
    rotor inertia where the robot file states none (module docstring). ``noise``: None, or a callable giving the
    ``angle_noise.JointNoise`` the refusal was judged against: a finding named as none then names the torque offset
    the data hold and the model lacks, and a counterbalance is never named on a joint gravity gives no torque over
    the recorded poses (``gravity_free``). ``angle``: None, or per joint the refused torque's part a torque of the
    joint's angle gives beyond an offset in noise levels (``angle_refused``), or a callable giving it."""
    refused = cache(refused) if callable(refused) else partial(np.asarray, refused)
    angle = None if angle is None else cache(angle) if callable(angle) else partial(np.asarray, angle)
    departed = np.zeros(robot.n_dof) if departed is None else departed
    departed = cache(departed) if callable(departed) else partial(np.asarray, departed)
    free = cache(partial(gravity_free, noise))  # asked only where a counterbalance is judged
    prior = robot.nominal_dynamic_parameters() if robot.links is not None else np.zeros((0, 1))
    distal = set(np.flatnonzero(prior[:, 0] > 0)[-2:].tolist())  # a payload's own links: it sits beyond them
    out = []
    for finding in findings:
        at, own = where(finding), finding.absorbs == "payload" and finding.link in distal
        judged = finding.pressed and not own and not _asked(finding.absorbs, at, refused, departed, angle, free)
        out.append(_unnamed_finding(finding, at, refused(), robot, currents, noise) if judged else finding)
    kept = []
    for item in held:
        at, own = item.effect_joint if item.effect_joint >= 0 else item.joint, item.absorbs == "payload"
        judged = (
            item.holder == "envelope"
            and not (own and item.joint in distal)
            and not _asked(item.absorbs, at, refused, departed, angle, free)
        )
        kept.append(_unnamed_item(item, at, refused(), robot, currents, noise) if judged else item)
    return tuple(out), tuple(kept)


def _under(absorbs: str, at: int, refused, robot) -> str:
    """The clause saying the data do not clearly ask for ``absorbs`` at joint ``at``."""
    j = int(np.argmax(refused)) if absorbs == "payload" else at
    return f"the bounds refuse {joint_label(j, robot)} {refused[j]:.2g} x its noise, and {NAMING_RULE}"


def _lacked_offset(noise, robot) -> str:
    """The clause naming the joints whose data hold a torque offset the model lacks (``noise``: None or a callable
    giving ``angle_noise.JointNoise``; the joint's own offset takes its least squares' noise down ``NAME_SIGMA``-fold
    or more), or ""."""
    joint_noise = None if noise is None else noise()
    joints = [] if joint_noise is None else np.flatnonzero(joint_noise.others >= NAME_SIGMA * joint_noise.offset)
    if not len(joints):
        return ""
    down = ", ".join(f"{joint_label(j, robot)} {joint_noise.others[j]:.2g} -> {joint_noise.offset[j]:.2g} N m"
                     for j in joints)  # fmt: skip
    return (
        f"a torque offset the model does not hold (the least squares' noise falls with one: {down}); "
        "identify with the offset column on (--offset on)"
    )


def _unnamed_finding(finding, at: int, refused, robot, currents: bool, noise=None):
    """``finding`` naming no effect, or (motor currents, no rotor stated) its joint's rotor inertia."""
    i, pushed = finding.link, finding.pushed
    drive = any(b.startswith("drive") for b in finding.bounds)
    under = _under(finding.absorbs, at, refused, robot)
    if currents and not drive and finding.prior_drive_inertia == 0 and finding.drive_inertia == 0 and outward(finding):
        message = (f"{pushed}. With motor currents as the torque source this is most likely joint {i + 1}'s rotor "
                   f"inertia: the base parameters merge it into link {i + 1} and the robot file states none; state "
                   f"rotor_inertia in link {i + 1}'s [[link]] table and identify holds it there. No counterbalance or "
                   f"payload is named: {under}.")  # fmt: skip
        return replace(finding, absorbs="drive_inertia", alternatives=(), evidence="", effect_joint=i, message=message)
    cause = (f"the robot file's link {i + 1} is off by more than its bounds allow (state its mass, centre of mass or "
             "envelope in the robot file), or an effect too small to tell from these recordings")  # fmt: skip
    offset = _lacked_offset(noise, robot)  # the data hold an offset the model lacks: say so first
    likely = f"{offset}; otherwise {cause}" if offset else cause
    message = f"{pushed}. No counterbalance or payload is named: {under}. Most likely {likely}."
    return replace(finding, absorbs=UNNAMED, alternatives=(), evidence="", effect_joint=-1, message=message)


def _unnamed_item(item, at: int, refused, robot, currents: bool, noise=None):
    """A held-back parameter naming no effect, or (motor currents, an inertia about a joint the data want larger)
    that joint's rotor inertia."""
    head = item.message.split(". The data most likely hold ")[0]
    under = _under(item.absorbs, at, refused, robot)
    if currents and item.kind == "axis" and item.data > item.fitted:
        message = (f"{head}. With motor currents as the torque source the data most likely hold the rotor inertia of "
                   f"{joint_label(item.joint, robot)}, which the robot file does not state (state its rotor_inertia "
                   f"in the robot file); no counterbalance or payload is named: {under}.")  # fmt: skip
        return replace(item, absorbs="drive_inertia", alternatives=(), evidence="", effect_joint=item.joint,
                       message=message)  # fmt: skip
    offset = _lacked_offset(noise, robot)
    message = f"{head}. No counterbalance or payload is named: {under}{f'. Most likely {offset}' if offset else ''}."
    return replace(item, absorbs=UNNAMED, alternatives=(), evidence="", effect_joint=-1, message=message)
