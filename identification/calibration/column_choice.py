"""Which drive columns the data want: per joint the friction shape, a torque offset and a drive inertia.

On default settings ``psdm identify`` does not ask whether the torque signal carries an offset, holds the
rotors' inertia (motor currents do; link-side joint-torque sensors, as on the Franka Panda or KUKA iiwa,
do not) or shows Stribeck friction: :func:`choose_columns` lets the data say, before the fit.

1. The training recordings are prepared as the fit prepares them and summed into normal equations with
   every candidate column (the Stribeck shape's two Coulomb columns, its velocities found first; each
   joint's offset where the joint reverses; each separate drive-inertia column), in contiguous blocks.
2. Every candidate model is a linear map of these columns (a joint of the Coulomb-viscous shape is one of the
   Stribeck shape with ``fs = fc``: its two Coulomb columns summed; a dropped column is left out), fitted by
   weighted least squares with each joint's weight ``1 / sigma_j^2`` of the full model.
3. A candidate is kept when the Bayesian information criterion on the training data prefers it (per joint: the joint's
   own columns, its Stribeck shape, offset or drive inertia, dropped with every other candidate in), with the number of
   samples divided by the residual's correlation time (filtered samples are not independent), **and** it lowers the
   joint's error on held-out data: the validation recordings when given, else a cross-validation over the training
   blocks (each block predicted by the fit on the others). One verdict (``column_verdict``) serves every kind of column
   (offset, Stribeck shape, drive inertia, drive loss): a column the training criterion is indifferent to
   (``INDIFFERENT_BIC``, either way) is kept only when the held-out data want it clearly (``HELD_OUT_GAIN``), as is one
   it is against short of strongly (``STRONG_BIC``): a sensor's offset that viscous friction would otherwise absorb, and
   not a knife-edge one (the TX40's joint 6 with six filter periods trimmed: BIC +0.96, 8 % lower on the training
   blocks, 38 % worse on the held-out end; the Panda's joint-5 Stribeck shape at BIC +0.89 and 7 % was kept by the plain
   rule where the TX40's joint 6 at +1.11 was refused). A column must also lower its own joint's error on each
   validation recording, as a diagnosis's finding and identify's counterbalance must (a pooled gain on one does not
   outvote a rise on another). A verdict the held-out data alone made (``Evidence.departs``) rests on free least-squares
   fits that can be far from the model identify writes; with validation recordings identify decides it again on that
   model (``column_check``: never worse on any joint than the column as the training BIC decides it). The training
   blocks are judged together: each block's own noise margin (``never_worse``) refused the Panda's joint-3 offset for
   block 5 (0.262 -> 0.280 N m, margin 0.012) that the held-out part confirms (0.245 -> 0.227 N m), and the TX40's
   joint-4 offset rises on three of five blocks within their noise. With validation recordings, an offset the plain
   rule keeps is checked on the written model too (``Evidence.written``): the joint's friction error, odd in its
   velocity, has a mean a constant column takes wherever the joint moves at other speeds one way than the other (a
   Stribeck hump the choice refused, slow motions: a KR6-like arm's vertical axis on slow gravity poses took -0.13 N m
   with no offset in its truth), and the free fits' held-out check cannot see it where the slow motions leave the free
   rigid body far from the written one (held-out error 0.76 against 0.30 N m on that joint). A joint's Stribeck shape
   must also be a Stribeck
   effect: its static friction above its Coulomb level by ``STRIBECK_Z`` standard deviations (a fit with ``fs < fc``
   only follows the low-pass filter's smearing of the Coulomb step at each reversal, which Coulomb-viscous truth shows
   too). Each joint gets the shape its own data want; the fit holds the others' static friction at their Coulomb level
   (``TrajectoryOptions.stribeck_joints``).
4. A drive inertia the data want negative is dropped: a torque measured behind the gearbox holds no rotor
   inertia. That is an expected situation, stated in the choice, not a warning. A torque from motor currents holds
   the rotors' inertia by construction (the motor side of the gearbox): there every separate drive-inertia column is
   kept (the consistent fit bounds it at >= 0; its evidence says so): the free least squares of the choice cannot
   tell it from the links' inertias on short recordings (Kinova Gen3 currents: 0.2 +- 0.2 kg m^2, some negative;
   against joint-torque sensors 0.4-0.5 on the large actuators, 0.1 on the small), and left out the links absorb it.
5. When currents are the torque source, each joint's drive loss (``drive_loss``: a gear efficiency that depends on
   the power flow, the column ``|tau| tanh(qd / v)`` of the robot file's rigid-body torque) is a candidate like an
   offset, kept only with a coefficient inside ``(0, MAX_LOAD_FRICTION)``. Joint-torque sensors sit behind the
   gearbox: no candidate.

LuGre friction is not a candidate here (its fit is a multiple-shooting problem per joint, too costly to try on
every joint's evidence): identify tries it after the fit, where the held-out residual lags the velocity at the
reversals as pre-sliding does (``lugre_trial``), and with ``--friction lugre``. With it, the offsets and drive
inertias are chosen under the Stribeck shape it starts from, on every joint. An explicit ``on``/``off`` or shape
(``ColumnRequest``, ``--friction X``) is taken as given, for every joint.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, replace

import numpy as np

from identification.calibration.column_candidates import (
    Candidates,
    PreparedTraining,
    candidates,
    prepare_training,
)
from identification.calibration.column_verdict import INDIFFERENT_BIC, Evidence, verdict
from identification.calibration.coulomb_smoothing import SmoothingChoice, smoothing_velocity
from identification.calibration.coulomb_width import positive_widths
from identification.calibration.drive_loss import efficiency
from identification.calibration.merged_rotors import without_lone_inertia
from identification.calibration.separate_inertia import separate_inertia_joints
from identification.calibration.trajectory_fit import TrajectoryOptions
from identification.calibration.viscous_power import viscous_evidence, viscous_exponents, viscous_lines
from identification.physical_bounds import MAX_LOAD_FRICTION
from psdm_casadi.errors import ParameterError
from psdm_casadi.state_cache import remembering

__all__ = ["FRICTION_CHOICES", "SWITCH_CHOICES", "ColumnChoice", "ColumnRequest", "Evidence", "choose_columns"]

logger = logging.getLogger(__name__)

FRICTION_CHOICES = ("auto", "coulomb-viscous", "stribeck", "lugre")
SWITCH_CHOICES = ("auto", "on", "off")
#: Parameters the Stribeck shape adds per joint: the static friction and the Stribeck velocity.
STRIBECK_PARAMETERS = 2
#: Standard deviations by which the static friction must exceed the Coulomb level for a Stribeck effect.
STRIBECK_Z = 2.0
#: How ``describe`` names each kind of column and its estimate.
LABELS = {
    "offset": ("torque offset", "{:+.3g} N m"),
    "stribeck": ("Stribeck shape", "fs - fc = {:+.3g} N m"),
    "Ia": ("drive inertia", "{:+.3g} kg m^2"),
    "loss": ("drive loss", "mu = {:+.3g}"),
    "viscous": ("viscous power law", "dv = {:.3g}"),
}


@dataclass(frozen=True)
class ColumnRequest:
    """What the user asked for: ``"auto"`` (the data decide, the default) or an explicit choice each.

    ``coulomb_velocity`` [rad/s]: the Coulomb column's smoothing velocity ``v`` of ``tanh(qd / v)``, one for every joint
    or a tuple of one per joint (``coulomb_width``); None (the default) chooses it from the joints' reversals
    (``coulomb_smoothing``, at most ``TrajectoryOptions.coulomb_velocity``).
    """

    friction: str = "auto"
    offset: str = "auto"
    drive_inertia: str = "auto"
    drive_loss: str = "auto"  # currents only (``drive_loss``); "on": every joint's, "off": none
    coulomb_velocity: float | tuple | None = None

    def __post_init__(self):
        for name, allowed in (("friction", FRICTION_CHOICES), ("offset", SWITCH_CHOICES),
                              ("drive_inertia", SWITCH_CHOICES), ("drive_loss", SWITCH_CHOICES)):  # fmt: skip
            if getattr(self, name) not in allowed:
                raise ParameterError(f"ColumnRequest.{name} must be one of {allowed}; got {getattr(self, name)!r}.")
        if self.coulomb_velocity is not None:  # one width, or one per joint; None: chosen from the data
            object.__setattr__(
                self, "coulomb_velocity", positive_widths(self.coulomb_velocity, "ColumnRequest.coulomb_velocity")
            )


@dataclass(frozen=True)
class ColumnChoice:
    """The drive columns of a fit: friction shape, offset joints and drive-inertia joints (0-based), and why.

    ``friction`` is the model's shape (``"stribeck"`` when any joint has the Stribeck shape, whose joints are
    ``stribeck_joints``; the others are Coulomb-viscous); ``shapes`` gives it per joint.
    """

    friction: str
    offset_joints: tuple
    inertia_joints: tuple
    request: ColumnRequest
    check: str = ""
    evidence: tuple = ()
    stribeck_joints: tuple | None = None  # None: every joint of a Stribeck (or LuGre) model, none otherwise
    n_dof: int = 0  # joints of the robot (0: not stated; ``shapes`` then needs it)
    loss_joints: tuple = ()  # joints (0-based) with a drive loss (``drive_loss``; currents only)
    torque_source: str = ""  # "current" (kt i) or "torque" (measured joint torque); "" not stated
    smoothing: SmoothingChoice | None = None  # the Coulomb column's smoothing velocity (None: the options' own)
    replaced_offsets: tuple = ()  # chosen offsets a counterbalance spring identify kept replaced (0 in the model)
    viscous_exponent: tuple = ()  # per joint the viscous exponent dv (1: linear); empty: every joint linear

    def shapes(self, n_dof: int) -> list:
        """The friction shape of each joint."""
        if self.friction not in ("stribeck", "lugre"):
            return ["coulomb-viscous"] * n_dof
        joints = range(n_dof) if self.stribeck_joints is None else self.stribeck_joints
        return [self.friction if j in joints else "coulomb-viscous" for j in range(n_dof)]

    def options(self, options: TrajectoryOptions) -> TrajectoryOptions:
        """``options`` with these columns (the LuGre shape's fit starts from the Stribeck columns)."""
        terms = ("fc", "fs", "fv") if self.friction in ("stribeck", "lugre") else ("fc", "fv")
        offset = self.request.offset == "on" or bool(self.offset_joints)
        stribeck = None if self.stribeck_joints is None or self.friction != "stribeck" else self.stribeck_joints
        return replace(
            options,
            friction=(*terms, "offset") if offset else terms,
            offset_joints=None if self.request.offset == "on" else tuple(self.offset_joints),
            drive_inertia=self.request.drive_inertia != "off",
            inertia_joints=None if self.request.drive_inertia == "on" else tuple(self.inertia_joints),
            stribeck_joints=None if stribeck is None else tuple(stribeck),
            coulomb_velocity=options.coulomb_velocity if self.smoothing is None else self.smoothing.velocity,
            viscous_exponent=tuple(self.viscous_exponent) or None,
        )

    @property
    def departures(self) -> tuple:
        """The evidence of the columns the held-out data alone decided (``Evidence.departs``), drive losses aside
        (a loss changes the fit's route: ``drive_loss``)."""
        return tuple(e for e in self.evidence if e.departs and e.term != "loss")

    def decided(self, evidence: Evidence, kept: bool, reason: str) -> ColumnChoice:
        """This choice with ``evidence``'s column kept or not and ``reason`` its reason (``column_check``: the model
        identify writes decided it)."""
        j, term = evidence.joint, evidence.term
        items = tuple(replace(e, kept=kept, reason=reason) if e is evidence else e for e in self.evidence)

        def toggled(values) -> tuple:
            return tuple(sorted({*values, j})) if kept else tuple(k for k in values if k != j)

        if term == "stribeck":
            joints = toggled(self.stribeck_joints or ())
            return replace(self, friction="stribeck" if joints else "coulomb-viscous", evidence=items,
                           stribeck_joints=joints or None)  # fmt: skip
        if term == "viscous":
            return replace(self, evidence=items, viscous_exponent=viscous_exponents(items, self.n_dof))
        field = {"offset": "offset_joints", "Ia": "inertia_joints", "loss": "loss_joints"}[term]
        return replace(self, evidence=items, **{field: toggled(getattr(self, field))})

    def describe(self) -> list:
        """One sentence per choice: what was chosen, and whether the data or the user chose it."""

        def joints(values):
            return "joints " + ", ".join(str(j + 1) for j in values) if values else "no joint"

        auto = "chosen from the data"
        by = {k: auto if getattr(self.request, k) == "auto" else "as asked" for k in ("friction", "offset")}
        kept = [j for j in self.offset_joints if j not in self.replaced_offsets]
        named = ", ".join(str(j + 1) for j in self.replaced_offsets)
        replaced = (
            f"; on joint{'s' * (len(self.replaced_offsets) > 1)} {named} replaced by the counterbalance spring kept"
        )
        lines = [f"friction shape: {self._shape_text()} ({by['friction']})",
                 f"torque offset: {'every joint' if self.request.offset == 'on' else joints(kept)} ({by['offset']}"
                 f"{replaced if self.replaced_offsets else ''})"]  # fmt: skip
        lines += [f"{LABELS[e.term][0]} refused on joint {e.joint + 1} ({LABELS[e.term][1].format(e.estimate)}): "
                  f"{e.reason}" for e in self._near_misses()]  # fmt: skip
        if self.request.drive_inertia == "auto" and self.torque_source == "current":
            lines.append(f"drive-inertia columns: {joints(self.inertia_joints)} (motor currents hold the rotors' "
                         "inertia: every separate one identified, >= 0)")  # fmt: skip
        elif self.request.drive_inertia == "auto":
            negative = [e.joint for e in self.evidence if e.term == "Ia" and e.estimate is not None and e.estimate <= 0]
            line = f"drive-inertia columns: {joints(self.inertia_joints)} ({auto}"
            if negative:
                line += (f"; none on {joints(negative)}: the data want it negative, as a torque measured behind the "
                         "gearbox (link-side torque sensors) holds no rotor inertia")  # fmt: skip
            lines.append(line + ")")
        else:
            lines.append(f"drive-inertia columns: {'off' if self.request.drive_inertia == 'off' else 'on'} (as asked)")
        lines += self._loss_lines(joints) + viscous_lines(self.viscous_exponent, self.evidence)
        if self.check:
            lines.append(f"checked on {self.check}")
        return lines + ([] if self.smoothing is None else [self.smoothing.sentence()])

    def _near_misses(self) -> list:
        """The refused columns of every kind the training BIC wants or is indifferent to that lower the joint's pooled
        held-out error: those whose refusal the report explains (the check on each part, too small a gain, a static
        friction not clearly above the Coulomb level, a loss outside its range). A shape with ``fs <= fc`` is no
        Stribeck effect at all and a negative drive inertia has its own sentence: neither is a near miss."""
        return [e for e in self.evidence if not e.kept and e.term in LABELS and e.delta_bic > -INDIFFERENT_BIC
                and e.held_out_ratio < 1 and e.estimate is not None
                and not (e.term in ("Ia", "stribeck") and e.estimate <= 0)]  # fmt: skip

    def _loss_lines(self, joints) -> list:
        """The drive-loss sentence: where and with what efficiency, or why there is none."""
        if self.torque_source == "torque" and self.request.drive_loss != "on":
            if self.inertia_joints:  # the data want rotor inertia: a motor-side torque, not a sensor behind the gearbox
                return ["drive loss: not tried (a candidate on motor currents only; --drive-loss on tries it)"]
            return ["drive loss: none (joint torques measured behind the gearbox do not hold its efficiency)"]
        if self.torque_source != "current":
            return []
        if self.request.drive_loss != "auto":
            return [f"drive loss (gear efficiency by power-flow direction): {self.request.drive_loss} (as asked)"]
        found = {e.joint: e for e in self.evidence if e.term == "loss"}
        if not found:
            return ["drive loss: not tried (no rigid-body torque to scale: the robot file has no links, or LuGre)"]
        eta = ", ".join(f"{float(efficiency(found[j].estimate)):.3f} on joint {j + 1}" for j in self.loss_joints)
        text = (f"drive loss (motor currents: gear efficiency by power-flow direction, the current torque / eta "
                f"driving, x eta back-driven): {joints(self.loss_joints)} (chosen from the data")  # fmt: skip
        return [text + (f"; eta ~ {eta} before the fit)" if eta else ")")]

    def _shape_text(self) -> str:
        """``stribeck`` (every joint), or ``stribeck on joints 1, 3; coulomb-viscous on joints 2, 4``."""
        if self.stribeck_joints is None or self.friction != "stribeck":
            return self.friction
        n_dof = self.n_dof or max(self.stribeck_joints) + 1
        shapes = self.shapes(n_dof)
        parts = [(shape, [j + 1 for j in range(n_dof) if shapes[j] == shape]) for shape in dict.fromkeys(shapes)]
        return "; ".join(f"{shape} on joint{'s' if len(js) > 1 else ''} {', '.join(map(str, js))}"
                         for shape, js in parts)  # fmt: skip

    def to_dict(self) -> dict:
        """The choice as the model file and ``--json`` hold it (joints 1-based)."""
        stribeck = None if self.stribeck_joints is None else [j + 1 for j in self.stribeck_joints]
        offsets = [j + 1 for j in self.offset_joints if j not in self.replaced_offsets]  # as the model holds them
        return {"friction": self.friction, "friction_shapes": self.shapes(self.n_dof) if self.n_dof else None,
                "stribeck_joints": stribeck, "offset_joints": offsets,
                "offset_joints_replaced": [j + 1 for j in self.replaced_offsets],
                "inertia_joints": [j + 1 for j in self.inertia_joints], "request": asdict(self.request),
                "drive_loss_joints": [j + 1 for j in self.loss_joints], "torque_source": self.torque_source,
                "check": self.check, "evidence": [e.to_dict() for e in self.evidence],
                "smoothing": None if self.smoothing is None else self.smoothing.sentence(),
                "coulomb_velocity": None if self.smoothing is None else self.smoothing.velocity,
                "viscous_exponent": list(self.viscous_exponent) or None}  # fmt: skip


@remembering()  # the recordings' regressors evaluated once (state_cache)
def choose_columns(robot, model, recordings, options=None, request=None, validation=(), configurations=None):
    """The drive columns the recordings want (module docstring); explicit choices of ``request`` are kept.

    Parameters
    ----------
    robot, model : RobotDescription, PSDMModel
    recordings : sequence of Recording
        The training recordings (raw, as for ``identify_trajectories``).
    options : TrajectoryOptions, optional
        Cutoff, Coulomb velocity and torque constants as the fit will use them (its columns are ignored).
    request : ColumnRequest, optional
        ``"auto"`` for each by default.
    validation : sequence of Recording
        Held-out recordings the choice is checked on; without them, a block cross-validation over the training.
    configurations : sequence of data.configuration.PayloadConfiguration, optional
        The load each training recording carries (as for ``identify_trajectories``).

    Returns
    -------
    ColumnChoice
    """
    options = TrajectoryOptions() if options is None else options
    request = ColumnRequest() if request is None else request
    source = "current" if any(r.tau is None for r in recordings) else "torque"
    training = None if request.coulomb_velocity else prepare_training(robot, list(recordings), options)  # once
    smoothing = _smoothing(training, options, request)
    options = replace(options, coulomb_velocity=smoothing.velocity)
    if "auto" not in (request.friction, request.offset, request.drive_inertia) and (
        request.drive_loss != "auto" or source == "torque"
    ):  # nothing else to choose
        return _as_asked(robot, model, request, source, smoothing)
    training = training or prepare_training(robot, list(recordings), options)
    found, offsets, inertia = candidates(robot, model, training, options, request, list(validation), configurations)
    check = (f"{len(validation)} validation recording(s)" if validation else
             f"a cross-validation over {len(found.blocks)} contiguous blocks of the training data")  # fmt: skip
    every = tuple(range(robot.n_dof))
    evidence, stribeck = [], every if request.friction in ("stribeck", "lugre") else ()
    if request.friction == "auto":
        evidence += _shape_evidence(found)
        stribeck = tuple(e.joint for e in evidence if e.kept)
        evidence += viscous_evidence(found, stribeck)  # the viscous power law, its exponent found first
        found = found.with_viscous(e.joint for e in evidence if e.term == "viscous" and e.kept)
    train, held, x, std = found.evaluate(stribeck)
    asked = {"offset": "offset", "Ia": "drive_inertia", "loss": "drive_loss"}
    for name in found.names:
        term = next((t for t in asked if name.startswith(t)), None)
        if term is None or getattr(request, asked[term]) != "auto":
            continue
        evidence.append(_column_evidence(found, stribeck, name, term, (train, held, x, std), source == "current"))
    evidence = evidence if source == "current" else without_lone_inertia(robot, model, evidence)
    evidence = _offsets_to_check(evidence) if validation else evidence
    kept = {(e.term, e.joint) for e in evidence if e.kept}
    friction = request.friction if request.friction != "auto" else ("stribeck" if stribeck else "coulomb-viscous")
    choice = ColumnChoice(
        friction=friction,
        offset_joints=tuple(j for j in offsets if request.offset == "on" or ("offset", j) in kept),
        inertia_joints=tuple(j for j in inertia if request.drive_inertia == "on" or ("Ia", j) in kept
                             or (source == "current" and request.drive_inertia == "auto")),
        request=request, check=check, evidence=tuple(evidence),
        stribeck_joints=tuple(stribeck) if request.friction == "auto" and stribeck else None, n_dof=robot.n_dof,
        loss_joints=_loss_joints(robot, model, request, kept), torque_source=source, smoothing=smoothing,
        viscous_exponent=viscous_exponents(evidence, robot.n_dof),
    )  # fmt: skip
    logger.debug("identify: %s", "; ".join(choice.describe()))  # identify's report states it (IdentifyResult)
    return choice


def _smoothing(training: PreparedTraining | None, options, request) -> SmoothingChoice:
    """The Coulomb column's smoothing velocity: as asked (``request.coulomb_velocity``, or ``options``' widths stated
    per joint), else from the prepared training recordings' reversals (``coulomb_smoothing``), at most
    ``options.coulomb_velocity``."""
    if request.coulomb_velocity:
        return SmoothingChoice.as_asked(request.coulomb_velocity)
    if isinstance(options.coulomb_velocity, tuple):  # stated per joint (TrajectoryOptions): taken as asked
        return SmoothingChoice.as_asked(options.coulomb_velocity)
    return smoothing_velocity(training.prepared, min(training.cutoffs), options.coulomb_velocity)


def _as_asked(robot, model, request, source, smoothing) -> ColumnChoice:
    """The ``ColumnChoice`` of a request with nothing to choose (every column on or off, the shape given)."""
    every = tuple(range(robot.n_dof)) if request.offset == "on" else ()
    inertia = tuple(separate_inertia_joints(model, robot)) if request.drive_inertia == "on" else ()
    losses = tuple(range(robot.n_dof)) if request.drive_loss == "on" and request.friction != "lugre" else ()
    return ColumnChoice(request.friction, every, inertia, request, n_dof=robot.n_dof, loss_joints=losses,
                        torque_source=source, smoothing=smoothing)  # fmt: skip


def _offsets_to_check(evidence) -> list:
    """``evidence`` with each offset the plain rule keeps marked to be checked on the model identify writes
    (``Evidence.written``; module docstring, step 3)."""
    note = "; checked on the model identify writes: an offset the training data want may take friction they show at "
    note += "other speeds one way than the other"
    return [replace(e, departs=True, written=True, reason=e.reason + note)
            if e.term == "offset" and e.kept and not e.departs else e for e in evidence]  # fmt: skip


def _loss_joints(robot, model, request, kept) -> tuple:
    """The joints (0-based) with a drive loss: every one when asked ``"on"`` (not for LuGre), else those kept."""
    if request.drive_loss == "on":
        return tuple(range(robot.n_dof)) if request.friction != "lugre" else ()
    return tuple(j for j in range(robot.n_dof) if ("loss", j) in kept)


def _shape_evidence(found: Candidates) -> list:
    """Per joint, its Stribeck shape against the Coulomb-viscous one, every other joint Stribeck and every other
    candidate column in (one ``Evidence`` per joint, ``term`` ``"stribeck"``).

    Beside the criterion and the held-out error of the joint, the shape must be a Stribeck effect there: static
    friction above the Coulomb level (``fs > fc`` by ``STRIBECK_Z`` standard deviations, grown by the residual's
    correlation time). A fit with ``fs < fc`` only follows the low-pass filter's smearing of the Coulomb step at
    each reversal (it appears on Coulomb-viscous truth too).
    """
    n_dof = found.effective.size
    if not found.stribeck:
        return [Evidence("stribeck", j, float("nan"), float("nan"), False, "not a candidate") for j in range(n_dof)]
    every = tuple(range(n_dof))
    train_s, held_s, x, std = found.evaluate(every)
    out = []
    for j in range(n_dof):
        train_c, held_c, _, _ = found.evaluate(tuple(k for k in every if k != j))
        n = found.effective[j]
        delta = float(n * np.log(train_c[j] / train_s[j]) - STRIBECK_PARAMETERS * np.log(n))
        ratio = float(held_s[j] / held_c[j])
        fc, fs = (found.n_base + found.names.index(f"{term}{j + 1}") for term in ("fc", "fs"))
        spread = float(np.hypot(std[fc], std[fs]) * np.sqrt(found.blocks_count(j) / n))
        above = bool(x[fs] - x[fc] > STRIBECK_Z * spread)
        held, reason = verdict(found, (every, ()), (tuple(k for k in every if k != j), ()), j, delta, ratio)
        kept = held and above
        if held and not kept:
            reason = (f"static friction {x[fs]:.3g} not above the Coulomb level {x[fc]:.3g} by {STRIBECK_Z:g} standard "
                      "deviations: the fit follows the low-pass filter's smearing of the Coulomb step, not a Stribeck "
                      "effect")  # fmt: skip
        departs = kept != (delta > 0 and ratio < 1 and above)  # the plain rule's verdict
        out.append(Evidence("stribeck", j, delta, ratio, kept, reason, float(x[fs] - x[fc]), spread, departs))
    return out


def _column_evidence(found, stribeck, name, term, base, current=False) -> Evidence:
    """One joint's offset or drive-inertia column, dropped with every other candidate in (``current``: currents)."""
    train, held, x, std = base
    j = int(name[len(term) :]) - 1
    train_without, held_without, _, _ = found.evaluate(stribeck, dropped=(name,))
    n = found.effective[j]
    delta = float(n * np.log(train_without[j] / train[j]) - np.log(n))
    ratio = float(held[j] / held_without[j])
    k = found.n_base + found.names.index(name)
    # the standard deviation of the weighted fit, grown by the residual's correlation time
    estimate, sigma = float(x[k]), float(std[k] * np.sqrt(found.blocks_count(j) / found.effective[j]))
    if term == "Ia" and (current or estimate <= 0):  # currents hold the rotors' inertia: not a sensor's placement
        return Evidence(term, j, delta, ratio, current, "motor currents hold the rotor's inertia: kept, >= 0 in the "
                        "consistent fit" if current else "the data want it negative: no rotor inertia in the torque "
                        "signal (measured behind the gearbox)", estimate, sigma)  # fmt: skip
    if term == "loss" and not 0.0 < estimate < MAX_LOAD_FRICTION:
        return Evidence(term, j, delta, ratio, False, f"coefficient mu = {estimate:.3g} outside (0, "
                        f"{MAX_LOAD_FRICTION}): not a gear efficiency above 60 %", estimate, sigma)  # fmt: skip
    kept, reason = verdict(found, (stribeck, ()), (stribeck, (name,)), j, delta, ratio)
    return Evidence(term, j, delta, ratio, kept, reason, estimate, sigma, kept != (delta > 0 and ratio < 1))
