"""Naming a low-harmonic "ripple" as large as the joint's gravity torque: a counterbalance, not motor ripple.

A ``torque_ripple`` term ``A sin(h q + phase)`` fits any torque periodic in the joint angle. Motor cogging and gear
ripple repeat at harmonics of the motor or gear angle (the gear ratio times the joint angle: tens to hundreds of
periods per joint revolution) and are small against the joint's load. A torque of one to ``LOW_HARMONIC`` periods
per joint revolution reaching ``GRAVITY_SHARE`` of the joint's gravity torque (its amplitude, or the ripples of such
low harmonics on the joint summed over the recorded angles: over part of a revolution one smooth torque may be fitted
as several) is a position-dependent load instead: a counterbalance (a cam, a spring or gas-spring balancer) or a
spring, whose smooth curve over the joint's range a low harmonic fits as well as a polynomial. Such a finding keeps
its term (the augmented model and the model file hold the same ``A sin(h q + phase)``) but is reported as
``COUNTERBALANCE`` with its numbers: the peak torque, the harmonics and its share of the joint's gravity torque.

A ``torque_offset`` no sensor has (``calibration.offset_reading``: on a joint gravity loads, at least a tenth of its
peak measured torque and a fifth of its gravity torque) is the same load seen over a short range: a balancer's torque
is nearly constant over the half radian an arm sweeps near horizontal. It too keeps its term and is reported as
``COUNTERBALANCE``, its explanation saying why it is not a sensor offset, unless the data say it is one: with the
training residual (``offset_verdicts``), the offset and a sinusoid of the joint's angle (a balancer's torque) are
compared on the training blocks and the validation recording (``calibration.offset_or_balancer``); where the constant
predicts the torque better beyond the noise, over a swing where a balancer's would follow the angle (a re-zeroed
sensor), the finding stays a ``torque_offset``, its note saying why.

A low-harmonic ripple found beside such an offset on its joint, of any size, is that counterbalance's shape
(``counterbalance_shapes``): a balancer's torque is nearly constant over a short swing and bends over a longer one,
and ``A sin(h q + phase)`` fits the bend while the offset holds the rest. It is named ``COUNTERBALANCE`` too, its
explanation naming the offset it shapes: one counterbalance, not a motor ripple beside it (the unseen heavy arm's cam,
held by identify as an offset, came back as a second harmonic below the gravity share that names a ripple alone).
``diagnose --apply`` writes such a shape beside the model's offset by the rule it applies to any torque the two
would share (``calibration.offset_split``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identification.calibration.offset_or_balancer import UNDECIDED, offset_or_balancer
from identification.calibration.offset_reading import oversized_offset

#: The effect name a low-harmonic, gravity-sized ripple is reported under.
COUNTERBALANCE = "counterbalance"
LOW_HARMONIC = 3  # highest periods per joint revolution of a position-dependent load named a counterbalance
GRAVITY_SHARE = 0.2  # its amplitude at least this share of the joint's gravity torque amplitude
LOADED_SHARE = 0.1  # a joint gravity loads: gravity amplitude at least this share of its peak measured torque


def gravity_amplitude(context, joint: int) -> float:
    """The nominal model's gravity torque amplitude [N m] on ``joint`` over the recorded angles; 0 without it or on a
    joint gravity barely loads (below ``LOADED_SHARE`` of its peak measured torque: no gravity to balance)."""
    gravity = getattr(context, "gravity", None)
    if gravity is None:
        return 0.0
    amplitude = float(np.max(np.abs(np.asarray(gravity)[:, joint])))
    measured = float(np.max(np.abs(np.asarray(context.tau)[:, joint])))
    return amplitude if amplitude >= LOADED_SHARE * measured else 0.0


def _low_ripple(finding) -> bool:
    """A ``torque_ripple`` finding on one joint of at most ``LOW_HARMONIC`` periods per revolution."""
    harmonic = finding.parameters.get("harmonic")
    return (
        finding.effect == "torque_ripple"
        and len(finding.joints) == 1
        and harmonic is not None
        and harmonic <= LOW_HARMONIC
        and len(finding.coefficients) == 2
    )


def low_harmonic_torque(findings, context, joint: int) -> np.ndarray:
    """The summed torque [N m] of the low-harmonic ripples among ``findings`` on ``joint`` at its recorded angles
    (one counterbalance over part of a revolution may be fitted as several low harmonics)."""
    q = np.asarray(context.q)[:, joint]
    torque = np.zeros_like(q)
    for f in findings:
        if _low_ripple(f) and int(f.joints[0]) == joint:
            x = float(f.parameters["harmonic"]) * q
            torque += f.coefficients[0] * np.sin(x) + f.coefficients[1] * np.cos(x)
    return torque


def counterbalance_joints(findings, context) -> dict:
    """``{joint: (peak torque, gravity amplitude)}`` of the joints whose low-harmonic ripples reach ``GRAVITY_SHARE``
    of the joint's gravity torque amplitude (``gravity_amplitude``): their summed torque's peak over the recorded
    angles, or the largest one's amplitude (the torque it claims over a whole revolution)."""
    out = {}
    for j in sorted({int(f.joints[0]) for f in findings if _low_ripple(f)}):
        gravity = gravity_amplitude(context, j)
        amplitudes = [float(f.parameters["amplitude"]) for f in findings if _low_ripple(f) and f.joints[0] == j]
        peak = max(float(np.max(np.abs(low_harmonic_torque(findings, context, j)))), *amplitudes)
        if gravity > 0.0 and peak >= GRAVITY_SHARE * gravity:
            out[j] = (peak, gravity)
    return out


def named_counterbalance(finding, peak: float, gravity: float, harmonics: tuple):
    """``finding`` (a low-harmonic ripple on a counterbalanced joint) reported as the counterbalance it is, its
    explanation giving the numbers and why it is not motor ripple."""
    j = int(finding.joints[0])
    amplitude, harmonic = float(finding.parameters["amplitude"]), int(finding.parameters["harmonic"])
    shape = "harmonic" if len(harmonics) == 1 else "harmonics"
    explanation = (
        f"a position-dependent torque on joint {j + 1}: a counterbalance or spring (peak {peak:.4g} N m, "
        f"{peak / gravity:.0%} of the joint's gravity torque {gravity:.4g} N m), fitted as the "
        f"{shape} {', '.join(str(h) for h in harmonics)} of the joint angle (this one A sin({harmonic} q + phase), "
        f"A = {amplitude:.4g} N m); not motor or gear ripple, which repeats at the gear ratio times the joint angle "
        "and is small against the load"
    )
    parameters = {**finding.parameters, "peak_torque": peak, "gravity_torque": gravity, "gravity_share": peak / gravity}
    return replace(finding, effect=COUNTERBALANCE, explanation=explanation, parameters=parameters,
                   signature="residual follows joint position over the whole range, as large as gravity")  # fmt: skip


def whole_offset(finding) -> tuple:
    """``(whole, held)`` [N m] of a ``torque_offset`` finding: the joint's whole offset, its ``parameters["offset"]``
    (a model file's held offset plus the fit's part, ``report_assembly.held_offset_correction``; the fit's coefficient
    where nothing is held), and the part the nominal model holds (0: none). A sensor's zero error or a balancer is
    the joint's whole constant torque, not the part by which the file's offset is off."""
    whole = float(finding.parameters.get("offset", finding.coefficients[0]))
    return whole, whole - float(finding.coefficients[0])


def _reading(finding, context):
    """The ``offset_reading.OffsetReading`` of a one-joint ``torque_offset`` finding no sensor has by size (its joint's
    whole offset, ``whole_offset``, against the nominal model's gravity torque amplitude and the peak measured torque
    of its joint); None otherwise."""
    if finding.effect != "torque_offset" or len(finding.joints) != 1 or getattr(context, "gravity", None) is None:
        return None
    j = int(finding.joints[0])
    peak = float(np.max(np.abs(np.asarray(context.tau)[:, j])))
    (whole, held), gravity = whole_offset(finding), float(np.max(np.abs(np.asarray(context.gravity)[:, j])))
    reading = oversized_offset(j, whole, gravity, peak)
    return None if reading is None else replace(reading, held=held)


#: Why a constant remainder is no evidence of an offset where the diagnosis identified the rigid body beside it.
LINKS_FREE = (
    "the rigid body was identified beside the offset, and its links' gravity torque on the joint is a "
    "sinusoid of its angle that takes a balancer's curve, so the constant the offset holds says nothing"
)


def offset_verdicts(findings, context, residual, held=None, links_free: bool = False) -> dict:
    """``{joint: offset_or_balancer.OffsetVerdict}`` of the ``torque_offset`` findings no sensor has by size: the
    torque each takes (its joint's whole offset, ``whole_offset``, plus the final model's ``residual`` (n, n_dof) on
    the training ``context``) compared
    as a constant and as a sinusoid of the joint's angle (a balancer's) on the training blocks and on ``held`` (the
    validation context and its residual), when given. ``links_free``: the rigid body was identified beside them
    (``LINKS_FREE``): an offset verdict is undecided."""
    out = {}
    for f in findings:
        if _reading(f, context) is None:
            continue
        j, offset = int(f.joints[0]), whole_offset(f)[0]
        pairs = [(np.asarray(ctx.q)[:, j], np.asarray(res)[:, j] + offset)
                 for ctx, res in [(context, residual), *([held] if held is not None else [])]]  # fmt: skip
        pairs = [(q[np.isfinite(t)], t[np.isfinite(t)]) for q, t in pairs]  # a joint left out: no torque
        verdict = offset_or_balancer(j, pairs[:1], pairs[1:])
        out[j] = replace(verdict, verdict=UNDECIDED, note=LINKS_FREE) if links_free and not verdict.named else verdict
    return out


def offset_counterbalance(finding, context, verdict=None):
    """``finding`` named a counterbalance when it is a ``torque_offset`` no sensor has by size (``_reading``) and the
    data do not say offset (``verdict``, an ``OffsetVerdict``; None: size alone); the finding with a note saying why
    when they do; None otherwise."""
    reading = _reading(finding, context)
    if reading is None:
        return None
    if verdict is not None and not verdict.named:
        return replace(finding, notes=(*finding.notes, reading.sentence(verdict)))
    parameters = {**finding.parameters, "peak_torque": abs(reading.offset), "gravity_torque": reading.gravity,
                  "gravity_share": reading.gravity_share}  # fmt: skip
    explanation = reading.sentence(verdict)
    if verdict is None:
        explanation += " (nearly constant over the recorded range, as a balancer is near horizontal)"
    return replace(finding, effect=COUNTERBALANCE, explanation=explanation, parameters=parameters, correction="",
                   signature="a constant torque as large as a share of gravity: no sensor's offset")  # fmt: skip


def name_counterbalances(findings, context, verdicts=None, carried=frozenset()) -> tuple:
    """The ``findings``, the low-harmonic ripples of each counterbalanced joint (``counterbalance_joints``) and each
    offset no sensor has (``offset_counterbalance``; ``verdicts``: ``offset_verdicts``, None: by size alone) named a
    counterbalance (``named_counterbalance``), any other finding unchanged. ``carried``: labels of a model file's
    carried torque offsets, left as found: their column fits how far the file's offset is off, a parameter of the file
    (``diagnosis.file_offsets`` reads it), not an offset of its own."""
    findings = tuple(findings)
    joints = counterbalance_joints(findings, context)
    out = []
    for f in findings:
        j = int(f.joints[0]) if f.joints else None
        if _low_ripple(f) and j in joints:
            harmonics = tuple(int(g.parameters["harmonic"]) for g in findings if _low_ripple(g) and g.joints[0] == j)
            f = named_counterbalance(f, *joints[j], harmonics)
        named = None if f.label in carried else offset_counterbalance(f, context, (verdicts or {}).get(j))
        out.append(named or f)
    return counterbalance_shapes(findings, tuple(out))


def counterbalance_shapes(found, named) -> tuple:
    """``named`` (the ``found`` findings, one to one, as ``name_counterbalances`` named them) with each low-harmonic
    ripple of ``found`` on a joint whose torque offset is named a counterbalance named that counterbalance's shape
    (module docstring): effect ``COUNTERBALANCE``, the offset it shapes in its explanation and its parameters
    (``counterbalance_offset`` [N m])."""
    offsets = {
        int(f.joints[0]): f
        for f in named
        if f.effect == COUNTERBALANCE and len(f.joints) == 1 and f.label.startswith("torque_offset[")
    }
    out = []
    for original, f in zip(found, named):
        j = int(original.joints[0]) if _low_ripple(original) else None
        out.append(counterbalance_shape(original, offsets[j]) if j in offsets else f)
    return tuple(out)


def counterbalance_shape(ripple, offset):
    """The low-harmonic ``ripple`` found beside the torque ``offset`` (a finding named a counterbalance) on its joint,
    named that counterbalance's shape (``counterbalance_shapes``)."""
    j, (whole, _) = int(ripple.joints[0]) + 1, whole_offset(offset)
    amplitude, harmonic = float(ripple.parameters["amplitude"]), int(ripple.parameters["harmonic"])
    explanation = (
        f"the shape of joint {j}'s counterbalance, whose torque the offset {offset.label} ({whole:+.4g} N m) holds: "
        f"over the recorded swing the balancer's torque bends, and A sin({harmonic} q + phase) (A = {amplitude:.4g} "
        "N m) fits the bend beside the offset; one counterbalance, the offset and its shape, not motor or gear ripple "
        "(which repeats at the gear ratio times the joint angle). 'diagnose --apply' writes the shape only where "
        "the model it holds beside the offset does not split the offset's torque, or where it alone describes the "
        "counterbalance better than the offset"
    )
    parameters = {**ripple.parameters, "counterbalance_offset": whole}
    return replace(ripple, effect=COUNTERBALANCE, explanation=explanation, parameters=parameters,
                   signature="residual follows joint position beside a counterbalance's offset: its shape")  # fmt: skip
