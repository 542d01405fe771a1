"""Where identify's report names a counterbalance, and how strictly the spring it tries there is judged.

``counterbalance_column`` tries a spring on each joint its report names a counterbalance on:

- a link (or one joint's drive inertia) pushed against its bounds (``envelope_report``), or a gravity term the fit
  holds back from the data (``held_back``): ``named_joints``;
- a torque offset the data chose that no sensor has by its size (``offset_reading``) and the data do not say is an
  offset (``offset_or_balancer``: the constant against a sinusoid of the joint's angle on the training blocks and
  the held-out part), or one that, with the robot file's rigid body held, stands for a torque of the angle taking
  more of the file's gravity torque than its masses can be off by (``file_held_offset``: identify's links had
  absorbed it, so its spring spans what the links and the offset hold, and is judged as one that replaces them);
- the fitted gravity torque of one joint alone off the robot file's (``gravity_departure``), unless the fit stored
  it as the inertia about that joint it holds back (``inertia_departure``: the data's own least squares keep the
  file's gravity torque there), which the report then names instead and no spring is tried for.

A spring named by an offset takes that offset's place (its constant). How it is judged depends on what the data said
(``CounterbalanceNaming.lenient``): where they say balancer, the spring must lower its joint beyond the blocks' noise
and on every held-out part, as any spring (``Opinion.lowers``); where the recorded swing cannot tell a balancer from a
constant, the reading by size stands and the spring is kept where no joint is worse than with the offset, as one
named by the gravity departure (it spans what it replaces).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from identification.calibration.envelope_report import where
from identification.calibration.file_held_offset import file_held_offsets
from identification.calibration.finding_value import validation_rmse
from identification.calibration.gravity_departure import gravity_departures
from identification.calibration.held_back import stored_held_back
from identification.calibration.inertia_departure import stored_inertia_departures
from identification.calibration.offset_or_balancer import UNDECIDED, offset_or_balancer
from identification.calibration.offset_reading import data_chosen_offsets

__all__ = [
    "BY_DEPARTURE",
    "BY_ENVELOPE",
    "BY_HELD_BACK",
    "BY_OFFSET",
    "CounterbalanceNaming",
    "counterbalance_joints",
    "fit_verdicts",
    "named_counterbalances",
    "named_joints",
]


def counterbalance_joints(fit) -> tuple:
    """0-based joints the fit's envelope report names a counterbalance or spring on: through a link's bounds (its
    first moment absorbing a gravity-like torque) or one joint's drive inertia pressed down (a torque following the
    position looks like a negative inertia on a periodic motion)."""
    return tuple(sorted({where(f) for f in fit.envelope if f.absorbs == "counterbalance" and f.pressed}))


#: ``named_joints``' sources, in the report's words.
BY_ENVELOPE, BY_HELD_BACK = "the envelope report", "a parameter the fit holds back"
BY_OFFSET, BY_DEPARTURE = "a torque offset no sensor has", "the fitted gravity torque of one joint alone"


def named_joints(fit) -> dict:
    """``{0-based joint: where it is named}`` of the counterbalances identify's report names: a pushed link or drive
    (``counterbalance_joints``), or a gravity term the fit holds back whose likeliest absorbed effect is a
    counterbalance (``held_back.HeldBack``: ``absorbs``, ``kind`` ``"gravity"``; on its ``effect_joint``).

    The effect the evidence puts first is the one tried (an alternative is not), and the judges out of sample decide
    whether it holds. A held-back inertia the data want smaller on a periodic motion is not tried: a counterbalance
    is only one reading of it beside a drive's dynamics (its alternative), and its joint is the inertia's, not the
    torque's (a 1.5 kg payload on the virtual Denso names one on joint 3, its torque on joints 4-5; a spring on joint 2
    of 5 N m/rad one on joint 1). A gravity term is what a counterbalance's torque of the angle passes for: the heavy
    virtual arm's cam on joint 2, held inside link 2's envelope by the pull (seeds 0-1: 98 and 72 times its size in
    the robot file)."""
    out = dict.fromkeys(counterbalance_joints(fit), BY_ENVELOPE)
    for item in stored_held_back(getattr(fit, "envelope_bounds", ())):
        if item.absorbs == "counterbalance" and item.kind == "gravity":
            out.setdefault(item.effect_joint if item.effect_joint >= 0 else item.joint, BY_HELD_BACK)
    return dict(sorted(out.items()))


@dataclass(frozen=True)
class CounterbalanceNaming:
    """The joints identify names a counterbalance on and why.

    Attributes
    ----------
    named : dict
        0-based joint -> where it is named (``BY_*``).
    said : str
        The evidence of the offsets and gravity departures read, in the report's words (also of an offset the data
        kept as one).
    readings : dict
        0-based joint -> ``offset_reading.OffsetReading`` of the offsets the springs replace.
    lenient : tuple
        0-based joints whose spring is kept where no joint is worse (module docstring).
    verdicts : dict
        0-based joint -> ``offset_or_balancer.OffsetVerdict`` of every offset read.
    """

    named: dict = field(default_factory=dict)
    said: str = ""
    readings: dict = field(default_factory=dict)
    lenient: tuple = ()
    verdicts: dict = field(default_factory=dict)


def named_counterbalances(robot, model, recordings, options, fit, calibrated, validation=(), kt=None,
                          configurations=None):  # fmt: skip
    """The ``CounterbalanceNaming`` of ``fit`` (its model file ``calibrated``) on the raw training ``recordings`` and
    held-out ``validation`` (``kt``: torque constants for recordings of currents; ``configurations``: the training
    recordings' payloads). A data-chosen offset the size does not read as no sensor's is read with the robot file's
    rigid body held (``file_held_offset``), where identify's links cannot absorb the balancer it stands for."""
    readings = data_chosen_offsets(robot, model, recordings, options, fit, kt)
    verdicts = fit_verdicts(model, calibrated, readings, recordings, validation, kt)
    said, absorbed = [r.sentence(verdicts[j]) for j, r in readings.items()], []
    if "offset" in options.friction and options.offset_joints is not None:
        rest = [j for j in options.offset_joints if j not in readings]
        problem = (robot, model, recordings, options, configurations)
        for j, held in file_held_offsets(problem, fit, calibrated, validation, rest, kt).items():
            said.append(held.sentence())
            if held.balancer:  # the links hold it in identify's fit: a spring spans what they and the offset hold
                readings[j], verdicts[j] = held.reading(), held.verdict
                absorbed.append(j)
    inertias = stored_inertia_departures(getattr(fit, "envelope_bounds", ()))  # a held-back inertia's, said once
    departures = {j: d for j, d in gravity_departures(robot, model, recordings, fit).items() if j not in inertias}
    said += [d.sentence() for d in (*departures.values(), *inertias.values())]
    readings = {j: r for j, r in readings.items() if verdicts[j].named}  # the data did not say offset
    found = {**dict.fromkeys(departures, BY_DEPARTURE), **dict.fromkeys(readings, BY_OFFSET)}
    undecided = tuple(j for j in readings if verdicts[j].verdict == UNDECIDED)
    return CounterbalanceNaming(dict(sorted({**named_joints(fit), **found}.items())), "; ".join(said), readings,
                                (*departures, *undecided, *absorbed), verdicts)  # fmt: skip


def fit_verdicts(model, calibrated, readings, recordings, validation=(), kt=None) -> dict:
    """``{joint: OffsetVerdict}`` of a fit's offsets no sensor has by size (``readings``: ``{joint: offset_reading.
    OffsetReading}``): the torque each takes on the raw training ``recordings`` and the held-out ``validation``, the
    offset plus the residual of the fit's model file ``calibrated`` there (prepared as the file says; ``kt`` for
    recordings of currents)."""
    if not readings:
        return {}
    sides = [[validation_rmse(calibrated, model, r, kt)[2:] for r in group] for group in (recordings, validation)]
    out = {}
    for j, reading in readings.items():
        pairs = [[(np.asarray(ready.q)[:, j], np.asarray(ready.tau)[:, j] - np.asarray(y)[:, j] + reading.offset)
                  for ready, y in side] for side in sides]  # fmt: skip
        out[j] = offset_or_balancer(j, *pairs)
    return out
