"""What the data pushed against in the plausible fit, and what that most likely is.

A bound of the consistent fit (``consistent_fit``: a link's envelope, its mass bounds, a drive inertia's
bounds) that is active at the solution means the recordings ask for a link the robot cannot have: the
torque of something the rigid body does not model is being pushed into it. :func:`envelope_findings` lists
those bounds and names the likely cause:

- a link of the arm (not one of the last two that carry mass) pushed to its envelope or a mass bound: a
  **counterbalance or spring** on the joint whose torque the bound refuses most (a gravity-like torque the
  link's first moment was absorbing, e.g. a shoulder's balancer), among the joints the link's weight gives a torque
  (``gravity_load.joints_carrying_gravity`` up to the link: an upright arm's base axis carries none, so it holds no
  balancer);
- one of the last two links pushed outward (envelope, upper mass bound): a **payload** or tool at the flange;
- a drive inertia at a bound: a **drive inertia** unlike the file's (below it: a torque measured on the link
  side of the gearbox; above it: extra inertia such as a coupled load); one joint's alone pressed down, a **spring or
  counterbalance** on it, or beside links a payload pulls outward, the **payload** (the links at their bounds take
  its weight with more inertia than it has).

That is the bounds' naming (where the link is, which way it is pushed). Where the fit holds back parameters of the
link (``held_back``), the finding is named from the same evidence as they are (:func:`named_from_evidence`,
``absorbed_effect.likely_effects``: the sign each effect can give the parameter, the joints that carry the torque,
gravity or inertial, the motion), with the alternatives that fit it too, the evidence in words and the joint the
effect acts on (``effect_joint``); files written before read as none. A proximal link the bounds name a payload (a
payload pulls every link outward) is named a counterbalance where the fitted gravity torque of a joint its weight
carries leaves the robot file's on that joint alone (``gravity_departure``, :func:`named_by_departure`): without an
offset column a shoulder's balancer goes into that link's first moment beside the tool, and a body at the flange does
not give a departure of one joint alone.

A link that only rests on a bound, the data pressing on it lightly, is listed as well (``pressed`` False) with a
note rather than a warning: its mass or extent was set by the bound, not by the data.

"Refused" is measured on the joints' own training data: the growth of each joint's residual from the
unconstrained least-squares estimate to the bounded fit, in units of its noise. The route that finds the
cause is ``psdm diagnose`` against the robot file, which fits a spring, counterbalance or payload jointly
with the rigid body; the messages say so.
"""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass, replace

import numpy as np

from identification.calibration.absorbed_effect import ABSORBED_EFFECTS, absorbed_phrase, effect_phrase, owned_columns
from identification.calibration.envelope import ellipsoid_fill, envelope_fill
from identification.calibration.gravity_load import joints_carrying_gravity
from identification.data.excitation_check import joint_label

__all__ = [
    "ABSORBED_EFFECTS",
    "DIAGNOSE_COMMAND",
    "with_concrete_route",
    "bounds_note",
    "effect_phrase",
    "ACTIVE_TOLERANCE",
    "MIN_PRESSURE",
    "MIN_REFUSED_SIGMA",
    "EnvelopeFinding",
    "envelope_findings",
    "named_by_departure",
    "named_from_evidence",
    "where",
    "pressed_findings",
]

#: A bound counts as active when the solution is within this fraction of it ...
ACTIVE_TOLERANCE = 0.01
#: ... and reported when it costs at least this many noise variances per sample of its joint (first order) ...
MIN_PRESSURE = 0.05
#: ... or (a link's bounds) its joint gives up this many noise levels of RMS torque to the bounds.
MIN_REFUSED_SIGMA = 1.0
#: The command the messages suggest; the command line puts its own robot and recordings in.
DIAGNOSE_COMMAND = "psdm diagnose ROBOT --train DATA --validate OTHER"
DIAGNOSE_ROUTE = "run '" + DIAGNOSE_COMMAND + "' against the robot file: it fits {what} jointly with the rigid body"


def with_concrete_route(warnings, said) -> list:
    """``warnings`` with the suggested command's placeholders (``DIAGNOSE_COMMAND``) replaced by the concrete command
    an earlier run put in ``said`` (a model file's own warnings: identify's, with its robot file and recordings), so
    a refit of that model file (diagnose --apply) names the same files; as they are when ``said`` names none."""
    concrete = next((m.group(1) for w in said if (m := re.search(r"'(psdm diagnose (?!ROBOT )[^']*)'", w))), None)
    return [w.replace(DIAGNOSE_COMMAND, concrete) if concrete else w for w in warnings]


@dataclass(frozen=True)
class EnvelopeFinding:
    """A link (or a drive) the data pushed against its bounds.

    Attributes
    ----------
    link : int
        0-based link (and joint).
    bounds : tuple of str
        The active bounds among ``"envelope"``, ``"mass upper"``, ``"mass lower"`` (a link's), or
        ``"drive inertia upper"``, ``"drive inertia lower"`` (its drive's).
    mass, prior_mass : float
        [kg] identified and in the robot file.
    fill, prior_fill : float
        How much of its bounding ellipsoid the link's mass spreads over (``envelope.ellipsoid_fill``: 1 on the
        boundary), and the robot file link's; nan without an envelope.
    drive_inertia, prior_drive_inertia : float
        [kg m^2] identified and in the robot file.
    absorbs : str
        One of ``ABSORBED_EFFECTS`` (or, from the evidence, ``"drive_dynamics"``, ``absorbed_effect.UNEXPLAINED``):
        what the bounds most likely keep out of the link (``clear_ask.UNNAMED``: the data do not clearly ask for one).
    joint : int
        0-based joint on which the bounds refuse the most torque (where to look for it).
    refused_rms : float
        [N m] RMS torque of ``joint`` that the unconstrained least squares gives and the bounded fit does not.
    refused_sigma : float
        ``refused_rms`` over that joint's noise level (its residual standard deviation).
    pressure : float
        How hard the data press on the bounds (``consistent_fit.FitBounds.pressure``: the weighted squared residual,
        in noise variances, they cost to first order).
    message : str
        The report's sentence: the bounds, the likely cause, the route that finds it.
    pushed : str
        The sentence's opening, what is pushed against which bound by how much (a resting link's whole note): what
        a later naming of the cause keeps (``inertia_departure``, ``clear_ask``). Not stored: ``message`` holds it.
    pressed : bool
        Whether the data press on the bounds (``MIN_PRESSURE``, ``MIN_REFUSED_SIGMA``): the warnings, identify's
        counterbalance route and the diagnosis's choice of rigid body act on those only. A link resting on a bound
        the data press lightly (False) is reported too (the bound, not the data, set its mass or extent), as a note.
    alternatives : tuple of str
        Other effects the evidence fits too, likelier first (``absorbed_effect.likely_effects``; none for a drive's
        bounds, nor in files written before they were stored).
    evidence : str
        What the effects were chosen from, in words ("" without the data's evidence, and in files written before).
    effect_joint : int
        0-based joint the effect acts on where the evidence puts it elsewhere than ``joint`` (a counterbalance's or a
        drive's own joint: identify's counterbalance route takes its spring there); -1: ``joint`` (``where``).
    reach, prior_reach, reach_limit : float
        [m] How far the link's centre of mass lies along the link towards the next joint's origin, the robot file
        link's, and the most its envelope allows (``LinkEnvelope.reach``); nan for a link without a reach.
    """

    link: int
    bounds: tuple
    mass: float
    prior_mass: float
    fill: float
    prior_fill: float
    drive_inertia: float
    prior_drive_inertia: float
    absorbs: str
    joint: int
    refused_rms: float
    refused_sigma: float
    pressure: float
    message: str = ""
    pressed: bool = True
    alternatives: tuple = ()
    evidence: str = ""
    effect_joint: int = -1
    reach: float = np.nan
    prior_reach: float = np.nan
    reach_limit: float = np.nan
    pushed: str = ""

    def to_dict(self) -> dict:
        out = asdict(self)
        del out["pushed"]
        out["bounds"], out["alternatives"] = list(self.bounds), list(self.alternatives)
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in out.items()}


def _refused(equations, x_fit, x_ols) -> np.ndarray:
    """Per joint, the RMS torque [N m] by which the bounded fit's residual exceeds the least-squares one."""
    growth = equations.residual_sum(np.asarray(x_fit)) - equations.residual_sum(np.asarray(x_ols))
    return np.sqrt(np.maximum(growth, 0.0) / np.maximum(equations.count, 1))


def _active(bounds, standard, i) -> tuple:
    """(link bounds, drive bounds) active at link ``i``: names, and the pressure on each group."""
    pressure = np.zeros((standard.shape[0], 3)) if bounds.pressure is None else bounds.pressure
    mass, rotor = float(standard[i, 0]), float(standard[i, -1])
    link, drive = [], []
    envelope = bounds.envelopes[i]
    if envelope is not None and envelope_fill(standard[i], envelope) >= 1.0 - ACTIVE_TOLERANCE:
        link.append("envelope")
    for names, value, low, high in ((link, mass, bounds.mass_lower[i], bounds.mass_upper[i]),
                                    (drive, rotor, bounds.rotor_lower[i], bounds.rotor_upper[i])):  # fmt: skip
        what = "mass" if names is link else "drive inertia"
        if names is drive and i in bounds.held_rotors:  # held with its links: no bound the data push on
            continue
        if np.isfinite(high) and value >= high * (1.0 - ACTIVE_TOLERANCE):
            names.append(f"{what} upper")
        elif low > 0 and value <= low * (1.0 + ACTIVE_TOLERANCE):
            names.append(f"{what} lower")
    return tuple(link), tuple(drive), float(pressure[i, 0] + pressure[i, 1]), float(pressure[i, 2])


def envelope_findings(robot, bounds, standard, equations, x_fit, x_ols, sigma, currents: bool = False) -> tuple:
    """The links and drives of a bounded consistent fit that the data push against (module docstring).

    A bound counts when it is active (within ``ACTIVE_TOLERANCE``) and the data press on it: its pressure is at
    least ``MIN_PRESSURE`` noise variances per sample of the joint, or (a link's) the joint it refuses most torque
    on gives up at least ``MIN_REFUSED_SIGMA`` noise levels of RMS torque. A link's active bound the data press on
    less is listed too, ``pressed`` False: the link rests where the bound stopped it (the unseen KR6-like arm on slow
    gravity poses had links 4 and 6 at their mass bounds, unreported).

    Parameters
    ----------
    robot : RobotDescription
    bounds : consistent_fit.FitBounds
        With the fit's ``pressure``.
    standard : array, shape (n_dof, 11)
        The fit's standard parameters (drive inertias in the last column).
    equations : trajectory_data.NormalEquations
        The training data's normal equations over (base parameters, drive parameters).
    x_fit, x_ols : array
        (base, drive) parameters of the bounded fit and of the unconstrained least squares.
    sigma : array, shape (n_dof,)
        Per joint noise level [N m].
    currents : bool
        Whether the torque is motor current times torque constant: a link pushed outward may then hold an unmodelled
        drive effect (the rotors' inertia, a gear efficiency by power-flow direction) rather than a load, and the
        message names both with the options that fit them.

    Returns
    -------
    tuple of EnvelopeFinding
    """
    if robot.links is None:
        return ()
    refused = _refused(equations, x_fit, x_ols)
    ratio = refused / np.maximum(np.asarray(sigma, dtype=float), 1e-12)
    floor = MIN_PRESSURE * np.asarray(equations.count, dtype=float)
    masses = [i for i in range(robot.n_dof) if bounds.envelopes[i] is not None or np.isfinite(bounds.mass_upper[i])]
    prior = robot.nominal_dynamic_parameters()
    pushed = {}
    for i in range(robot.n_dof):
        link, drive, link_push, drive_push = _active(bounds, standard, i)
        if link:
            outward = "envelope" in link or "mass upper" in link
            pushed[(i, "link")] = (link, "payload" if outward and i in masses[-2:] else "counterbalance", link_push)
        if drive and drive_push >= floor[i]:
            pushed[(i, "drive")] = (drive, "drive_inertia", drive_push)

    def joint_and_pressure(i, kind, absorbs, push) -> tuple:
        if kind == "drive":
            return i, True
        if absorbs == "payload":
            joint = int(np.argmax(ratio))
        else:  # a counterbalance acts where the link's weight gives a torque: not on a vertical base axis
            carriers = np.flatnonzero(joints_carrying_gravity(robot)[: i + 1])
            near = carriers if carriers.size else np.arange(i + 1)
            joint = int(near[np.argmax(ratio[near])])
        return joint, bool(push >= floor[joint] or ratio[joint] >= MIN_REFUSED_SIGMA)

    payload = any(absorbs == "payload" for _, absorbs, _ in pushed.values())
    low = [i for (i, kind), (names, _, _) in pushed.items() if kind == "drive" and "drive inertia lower" in names]
    rotors = int(np.sum(bounds.rotor_lower > 0))
    out = []
    for (i, kind), (names, absorbs, push) in pushed.items():
        if payload and kind == "link" and ("envelope" in names or "mass upper" in names):
            absorbs = "payload"  # a payload pulls every link outward: the proximal ones too
        if i in low and kind == "drive" and len(low) <= rotors // 2:  # one joint's, not the torque signal's
            # beside links a payload pulls outward, the payload's too: held at their bounds, the links take its weight
            # with more inertia than it has (their centres of mass short of it), and the drive gives it back
            absorbs = "payload" if payload else "counterbalance"
        joint, pressed = joint_and_pressure(i, kind, absorbs, push)
        if not pressed and standard[i, 0] <= 0:  # a massless link at its bound of 0: nothing rests there
            continue
        envelope = bounds.envelopes[i]
        fill = [ellipsoid_fill(body, envelope) if envelope else np.nan for body in (standard[i], prior[i])]
        finding = EnvelopeFinding(i, names, float(standard[i, 0]), float(prior[i, 0]), *fill, float(standard[i, -1]),
                                  float(prior[i, -1]), absorbs, joint, float(refused[joint]), float(ratio[joint]),
                                  push, pressed=pressed, **_reach(envelope, standard[i], prior[i]))  # fmt: skip
        out.append(worded(finding, robot, currents))
    return tuple(out)


def _reach(envelope, link, prior) -> dict:
    """The finding's ``reach``, ``prior_reach`` and ``reach_limit`` [m] of a link (none without a reach)."""
    reach = None if envelope is None else envelope.reach
    if reach is None:
        return {}
    along = [reach.along(body[1:4] / body[0]) * reach.limit if body[0] > 0 else np.nan for body in (link, prior)]
    return {"reach": float(along[0]), "prior_reach": float(along[1]), "reach_limit": reach.limit}


def named_from_evidence(findings, held, model, robot, currents: bool = False) -> tuple:
    """``findings`` (``envelope_findings``) with each pushed link named as the parameters the fit holds back name
    theirs (``held_back``, ``absorbed_effect.likely_effects``): a link with a parameter among ``held`` takes the effects
    of its most significant one (the sign each effect can give it, the joints that carry the torque, gravity or
    inertial, the motion), first and alternatives, the joint the effect acts on (the refused torque's for a payload)
    and the evidence in words. A link none of whose parameters the data want beyond their noise keeps the bounds'
    naming (``envelope_findings``: where it is and which way it is pushed); so does a drive's bound (one joint's
    drive pressed down, or every joint's: the torque signal)."""
    out = []
    for finding in findings:
        own = set() if any(b.startswith("drive") for b in finding.bounds) else owned_columns(model, robot, finding.link)
        items = [h for h in held if h.parameter in model.base_names and model.base_names.index(h.parameter) in own]
        if not items:
            out.append(finding)
            continue
        item = max(items, key=lambda h: abs(h.sigma_off))
        at = -1 if item.absorbs == "payload" else item.effect_joint if item.effect_joint >= 0 else item.joint
        named = replace(finding, absorbs=item.absorbs, alternatives=tuple(item.alternatives), evidence=item.evidence,
                        effect_joint=at)  # fmt: skip
        out.append(worded(named, robot, currents))
    return tuple(out)


def named_by_departure(findings, departures, robot, currents: bool = False) -> tuple:
    """``findings`` with each pressed link pushed outward that the bounds name a payload, other than the last two links
    with mass (a tool moves those either way), named a counterbalance on the joint whose fitted gravity torque leaves
    the robot file's alone (``departures``: ``{0-based joint: gravity_departure.GravityDeparture}``, or a callable
    giving them, called only where such a link is pushed), among the joints its weight carries up to its own
    (``gravity_load.joints_carrying_gravity``): the link's first moment holds that joint's balancer. The payload
    stays the alternative, the departure is the evidence; the largest departure is taken where several joints
    depart."""
    prior = robot.nominal_dynamic_parameters() if robot.links is not None else np.zeros((0, 1))
    distal = set(np.flatnonzero(prior[:, 0] > 0)[-2:].tolist())
    candidates = {k for k, f in enumerate(findings) if f.pressed and f.absorbs == "payload" and outward(f)
                  and f.link not in distal and not any(b.startswith("drive") for b in f.bounds)}  # fmt: skip
    if not candidates:
        return tuple(findings)
    found = departures() if callable(departures) else departures
    out = []
    for k, finding in enumerate(findings):
        carried = joints_carrying_gravity(robot) if k in candidates and found else ()
        joints = [j for j in found if k in candidates and j <= finding.link and carried[j]]
        if not joints:
            out.append(finding)
            continue
        j = max(joints, key=lambda joint: found[joint].departure)
        named = replace(finding, absorbs="counterbalance", alternatives=("payload",), evidence=found[j].evidence,
                        effect_joint=j)  # fmt: skip
        out.append(worded(named, robot, currents))
    return tuple(out)


def pressed_findings(findings) -> tuple:
    """The findings (``EnvelopeFinding`` or their dicts from a model file, where a file written before ``pressed``
    counts every one) whose bounds the data press on."""
    return tuple(f for f in findings if (f.get("pressed", True) if isinstance(f, dict) else f.pressed))


def worded(finding: EnvelopeFinding, robot, currents: bool = False) -> EnvelopeFinding:
    """``finding`` with its ``message`` and ``pushed`` (a pressed one's, else a resting link's note)."""
    if not finding.pressed:
        note = _resting_message(finding, robot)
        return replace(finding, message=note, pushed=note)
    pushed = _pushed(finding, robot)
    return replace(finding, message=f"{pushed}. This is {_cause(finding, robot, currents)}", pushed=pushed)


def _resting_message(finding: EnvelopeFinding, robot) -> str:
    """The report's note on a link resting on a bound the data press lightly: what rests where, how lightly, what
    it may hold, and which bound to revisit."""
    k = finding.joint
    cause = absorbed_phrase((finding.absorbs, *finding.alternatives), where(finding), robot)
    fixes = []
    if any(b.startswith("mass") for b in finding.bounds):
        fixes.append("pass --mass-bounds LOW HIGH if the robot file's masses are rough")
    if "envelope" in finding.bounds:
        fixes.append(f"give link {finding.link + 1} its envelope in the robot file ([[link]] envelope) if its "
                     "kinematic lengths understate the link")  # fmt: skip
    return (
        f"link {finding.link + 1} rests against {_pushed_what(finding)}, the data pressing on it lightly "
        f"({joint_label(k, robot)} gives up {finding.refused_rms:.2g} N m RMS, {finding.refused_sigma:.2g} x its "
        f"noise, to the bounds): these recordings hardly fix this link, and the bound, not the data, set it. If "
        f"anything it holds {cause}; {', or '.join(fixes)}, or record motions that move this link apart from its "
        "neighbours."
    )


def _pushed_what(finding: EnvelopeFinding) -> str:
    parts = []
    for bound in finding.bounds:
        if bound == "envelope" and finding.reach >= (1.0 - ACTIVE_TOLERANCE) * finding.reach_limit:
            parts.append(
                f"its physical envelope (its centre of mass {finding.reach:.3g} m along the link, the most it "
                f"may: the next joint's origin plus a margin; the robot file's {finding.prior_reach:.3g} m)"
            )
        elif bound == "envelope":
            parts.append(f"its physical envelope (its mass spreads over {finding.fill:.2f} of its bounding ellipsoid; "
                         f"the robot file's link over {finding.prior_fill:.2f})")  # fmt: skip
        elif bound.startswith("mass"):
            parts.append(f"its {bound} bound ({finding.mass:.4g} kg; robot file {finding.prior_mass:.4g} kg)")
        else:
            parts.append(f"its {bound} bound ({finding.drive_inertia:.4g} kg m^2; held to "
                         f"{finding.prior_drive_inertia:.4g} kg m^2)")  # fmt: skip
    return " and ".join(parts)


def where(finding: EnvelopeFinding) -> int:
    """The 0-based joint the finding's effect acts on: its ``effect_joint``, else (a payload, the bounds' naming, a
    file written before) the joint the bounds refuse most torque on."""
    return finding.effect_joint if finding.effect_joint >= 0 else finding.joint


def outward(finding: EnvelopeFinding) -> bool:
    """Whether the data push the link outward (its envelope or its upper mass bound): a load it does not hold."""
    return "envelope" in finding.bounds or "mass upper" in finding.bounds


def _pushed(finding: EnvelopeFinding, robot) -> str:
    """The opening of a pressed finding's sentence: what is pushed against which bound, by how much."""
    size = f"{finding.refused_rms:.3g} N m RMS ({finding.refused_sigma:.1f} x its noise)"
    refused = f"the data ask {joint_label(finding.joint, robot)} for {size} more than the bounded model gives"
    drive = any(b.startswith("drive") for b in finding.bounds)
    label = f"the drive of {joint_label(finding.link, robot)}" if drive else f"link {finding.link + 1}"
    return f"{label} is pushed against {_pushed_what(finding)}: {refused}"


def _cause(finding: EnvelopeFinding, robot, currents: bool = False) -> str:
    """The rest of a pressed finding's sentence: what it most likely is, what to run, and the alternatives."""
    i, at = finding.link, where(finding)
    file_off = (
        (
            ", or a robot file whose mass of this link is off by more than the bounds allow (pass --mass-bounds "
            "LOW HIGH if the file's masses are rough)"
        )
        if any(b.startswith("mass") for b in finding.bounds)
        else ""
    )
    drive = any(b.startswith("drive") for b in finding.bounds)
    if finding.absorbs == "counterbalance" and drive:
        cause = (
            f"most likely a spring or counterbalance on {joint_label(at, robot)}: on a periodic motion a torque "
            "that follows the position looks like a negative inertia, and this joint alone presses its drive "
            "inertia down (a torque signal without the rotors would press every joint's); or the robot file's "
            f"rotor inertia of this joint is off; {DIAGNOSE_ROUTE.format(what='a spring or counterbalance')}"
        )
    elif finding.absorbs == "counterbalance":
        cause = (f"most likely a counterbalance or spring on {joint_label(at, robot)} (a gravity-like torque the "
                 f"link's mass would otherwise absorb){file_off}; "
                 f"{DIAGNOSE_ROUTE.format(what='a spring or counterbalance')}")  # fmt: skip
    elif finding.absorbs == "payload":
        cause = (
            "most likely a payload or tool at the flange that the robot file does not hold; add it to the robot "
            f"file, or {DIAGNOSE_ROUTE.format(what='a payload')}"
        )
    elif finding.absorbs not in ABSORBED_EFFECTS:  # a drive's dynamics, or an effect none of them gives
        cause = f"most likely {absorbed_phrase((finding.absorbs,), at, robot)}; {DIAGNOSE_ROUTE.format(what='it')}"
    elif "drive inertia lower" in finding.bounds:
        cause = (
            "a torque signal with less drive inertia than the robot file's: torques measured on the link side of "
            "the gearbox (joint torque sensors) hold none (identify with --drive-inertia off); or a spring or "
            "counterbalance on the joint, which a periodic motion makes look like a negative inertia; "
            f"{DIAGNOSE_ROUTE.format(what='a spring')}"
        )
    else:
        cause = ("extra inertia on the joint (a coupled load, a heavier gear), or the rotor inertia it is held to is "
                 "off (the robot file's, or on currents the drive inertia of the joints with its torque constant: "
                 "state its rotor_inertia in the robot file's [[link]] table)")  # fmt: skip
    if currents and not drive and finding.prior_drive_inertia == 0 and finding.drive_inertia == 0 and outward(finding):
        cause += (f". With motor currents as the torque source it is most likely joint {i + 1}'s rotor inertia: the "
                  f"base parameters merge it into link {i + 1} and the robot file states none, nor does a joint with "
                  f"the same torque constant give one; state rotor_inertia in link {i + 1}'s [[link]] table and "
                  "identify holds it there")  # fmt: skip
    elif currents and not drive:
        cause += (". With motor currents as the torque source it may instead be a drive effect the currents hold: the "
                  "rotors' inertia (identify --drive-inertia on) or a gear efficiency that depends on the power flow "
                  "(identify --drive-loss on)")  # fmt: skip
    return f"{cause}.{_alternatives(finding, robot)}"


#: What ``psdm diagnose`` fits for each effect (``DIAGNOSE_ROUTE``).
ROUTE_WHAT = {"counterbalance": "a spring or counterbalance", "payload": "a payload"}


def _alternatives(finding: EnvelopeFinding, robot) -> str:
    """The report's words on the other effects the evidence fits (``finding.alternatives``), the evidence, and the
    route that finds them; "" where there are none."""
    if not finding.alternatives:
        return ""
    what = " or ".join(ROUTE_WHAT.get(e, "them") for e in dict.fromkeys(finding.alternatives))
    return (f" The evidence ({finding.evidence}) fits "
            f"{absorbed_phrase(finding.alternatives, where(finding), robot)} as well: 'psdm diagnose' against the "
            f"robot file fits {what} too.")  # fmt: skip


def bounds_note(options, bounds) -> tuple:
    """The ``envelope_bounds`` of a fit (``TrajectoryFit``)."""
    if bounds is None or all(e is None for e in bounds.envelopes):
        return ()
    sources = [None if e is None else e.source for e in bounds.envelopes]
    return (("mass_ratio", list(options.mass_ratio)), ("drive_inertia_ratio", list(options.drive_inertia_ratio)),
            ("envelopes", sources))  # fmt: skip
