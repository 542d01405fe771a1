"""Identify takes the payload its report names: a body at the flange, preferred to a spring taking the same torque.

A tool the robot file does not hold pushes the last links against their envelope, and the report names a payload
(``envelope_report``, ``held_back``: first or as an alternative). Without a route of its own the tool's torque was
left to the counterbalance route (``counterbalance_column``), which tries a spring on the joint a held-back gravity
term names: on the heavy virtual arm (a 100-200 kg tool, training only) a spring on joint 5 of k = +500 N m/rad passed
every block of the training recording, and the model file explained the tool's gravity on the wrist as a spring, the
tool's torque on joints 2-4 left to the links. A spring takes one joint's torque with two free parameters; one rigid
body at the flange (mass, centre of mass: four) takes the torque on every joint that carries it, consistently.

So where the report names a payload and the counterbalance route tried a spring (the two explanations compete for
the same torque), identify also takes the payload route (:func:`take_payload`; where no spring was tried the payload
stays named, its route suggested, as before):

- the payload is estimated as a point mass at the flange (the last link's mass and first moment columns) from the
  torque the robot file's rigid body leaves on the prepared training recordings, the drive columns of the fit
  and the springs the counterbalance route kept fitted beside it (weighted by each joint's residual variance, as
  ``payload_check.new_payload``): a balancer the model holds as a spring, not as an offset, is not the body's to
  explain. It is tried only as a body: a positive mass, its centre of mass within ``MAX_PAYLOAD_REACH`` of the flange.
  Its mass is stated with its standard deviation (``payload_weight``): the recording's noise, and the errors of the
  file's links, which the torque it is fitted on carries too and no motion of the loaded arm separates from the
  payload's mass (the report says so where they dominate, and that a recording without the tool separates them);
- the arm is identified again with the robot file's links carrying it (``carried_payload.carrying_payloads``, as
  ``psdm diagnose --apply`` takes a payload up: the pull and the envelope around the file with the load), and the
  counterbalance route runs again from that fit: a spring is kept beside the payload only where it still holds out
  of sample;
- the model with the payload (B) and the counterbalance route's model without it (A) are judged against each other by
  the same judges as a spring (the held-out recordings, each and together, and the block cross-validation of the
  training recordings: each fold's payload estimated, each model refitted, on its training blocks). The rule:

  * where B keeps fewer springs than A (the payload explains the torque a spring took), B is taken unless A is better
    beyond the noise margin on some joint for some judge (the spring clearly better out of sample);
  * where B keeps the same springs (the payload explains nothing a spring took), B is taken only if it lowers some
    joint beyond the noise margin for every judge and no joint is worse: the payload must earn its place.

The payload is stored as a ``findings`` entry of kind ``rigid_body`` (``source`` ``"identify"``; taken up by the rigid
body, as a diagnosis's payload), and ``identification.payload`` states the choice with its numbers: "spring[j5] not
kept: a payload on the flange explains the same torque on joints 2-6 ...".
"""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass, field

import numpy as np

from identification.calibration.carried_payload import carrying_payloads
from identification.calibration.counterbalance_column import (
    COUNTERBALANCE_SOURCE,
    CounterbalanceChoice,
    spring_model,
    try_counterbalance,
)
from identification.calibration.counterbalance_folds import FoldFailure, block_folds
from identification.calibration.findings import FindingColumns, FindingTerm
from identification.calibration.held_back import stored_held_back
from identification.calibration.never_worse import compare_each, pooled_comparison
from identification.calibration.payload_weight import (
    BODY,
    LinkRegressor,
    PayloadWeight,
    link_cross,
    point_mass_inertia,
    weigh_payload,
)
from identification.calibration.trajectory_data import drive_columns, fit_shape
from identification.calibration.trial_fits import trial_fit
from identification.data.torque_constants import recording_kt
from psdm_casadi.errors import PSDMError

__all__ = ["PAYLOAD_SOURCE", "PayloadChoice", "estimate_payload", "payload_named", "payload_wins", "take_payload"]

logger = logging.getLogger(__name__)

#: ``findings[].source`` of a payload identify took.
PAYLOAD_SOURCE = "identify payload route"


@dataclass(frozen=True)
class PayloadChoice:
    """What identify decided about the payload its report named.

    ``named``: the report of the fit before the counterbalance named one (``payload_named``; also where no spring was
    tried, the route not taken); ``tried``: a body was estimated and judged; ``kept``: it is in the model written
    (``mass`` [kg], ``com`` [m] in the flange frame; ``weight`` their standard deviations, ``payload_weight``);
    ``replaced``: the spring labels the counterbalance route kept
    that the model with the payload does not need; ``rmse_without``/``rmse_with``/``margin``: per joint, the first
    judge's RMSE [N m] of the model without (A) and with (B) the payload, and the noise margin; ``route``: the judges.
    """

    named: bool = False
    tried: bool = False
    kept: bool = False
    reason: str = ""
    mass: float | None = None
    com: tuple = ()
    weight: PayloadWeight | None = None
    replaced: tuple = ()
    rmse_without: tuple = ()
    rmse_with: tuple = ()
    margin: tuple = ()
    route: str = ""
    fit: object = field(default=None, repr=False)
    document: dict | None = field(default=None, repr=False)
    counterbalance: CounterbalanceChoice | None = field(default=None, repr=False)

    @property
    def line(self) -> str:
        """The report's line (empty where nothing was named)."""
        return f"payload: {self.reason}" if self.reason else ""

    def to_dict(self) -> dict:
        return {"named": self.named, "tried": self.tried, "kept": self.kept, "reason": self.reason, "mass": self.mass,
                "com": list(self.com), **(self.weight.to_dict() if self.weight else {}),
                "replaced": list(self.replaced), "rmse_without": list(self.rmse_without),
                "rmse_with": list(self.rmse_with), "margin": list(self.margin), "route": self.route}  # fmt: skip


def payload_named(fit) -> bool:
    """Whether the fit's report names a payload: a pressed envelope finding or a held-back parameter whose likeliest
    effect, or an alternative, is a payload."""
    entries = [f for f in fit.envelope if f.pressed] + list(stored_held_back(getattr(fit, "envelope_bounds", ())))
    return any(e.absorbs == "payload" or "payload" in (getattr(e, "alternatives", ()) or ()) for e in entries)


def estimate_payload(robot, model, fit, prepared, springs=(), options=None) -> PayloadWeight | None:
    """The point mass at the flange that best explains the torque the robot file's rigid body leaves on the
    ``prepared`` recordings, the drive columns of ``fit`` and the counterbalance route's kept ``springs``
    (``findings.FindingTerm``) fitted beside it (module docstring): its mass [kg] and centre of mass [m] in the flange
    frame with their standard deviations (``payload_weight.PayloadWeight``: the recording's noise and the file's links
    as ``options``' pull towards the file states them; default ``TrajectoryOptions()``), or None where it is no body
    (mass not positive, centre of mass out of reach).

    Every torque the model already names has its own columns beside the body, so the body takes only what it explains:
    a balancer the fit took as a spring (not as an offset) is otherwise left to the body at the flange, which has no
    column for one joint's torque alone (the heavy virtual arm at seed 1 without an offset: a mass not positive)."""
    from identification.calibration.trajectory_fit import TrajectoryOptions
    from identification.physical_bounds import MAX_PAYLOAD_REACH

    prior = robot.nominal_dynamic_parameters()
    theta = model.base_parameters(prior)
    regressor = LinkRegressor(robot)
    shape = fit_shape(fit)  # Stribeck velocities and viscous exponents
    named = FindingColumns(tuple(springs))
    rows, targets, inertia, cross = [], [], [], 0.0
    for rec in prepared:
        own = drive_columns(rec.qd, rec.qdd, fit.friction_terms, fit.inertia_joints, fit.coulomb_velocity, *shape)
        beside = named.all_columns(np.asarray(rec.q, dtype=float), rec.qd, rec.qdd)
        links = regressor(rec.q, rec.qd, rec.qdd)
        rows.append(np.concatenate([links[:, :, -(BODY + 1) : -(BODY + 1) + 4], own, beside], axis=2))  # flange m, h
        inertia.append(links[:, :, -(BODY + 1) + 4 : -1])  # the last link's inertia about its origin
        cross = cross + link_cross(rows[-1], links)
        targets.append(np.asarray(rec.tau, dtype=float) - model.inverse_dynamics(rec.q, rec.qd, rec.qdd, theta))
    columns, residual = np.concatenate(rows), np.concatenate(targets)
    residual, weights = _point_mass_fit(columns, residual, np.concatenate(inertia))
    found = weigh_payload(columns, residual, weights, cross, prior, options or TrajectoryOptions(), fit.inertia_joints)
    if not found.mass > 0.0:
        return None
    return found if np.linalg.norm(found.com) <= MAX_PAYLOAD_REACH else None


def _point_mass_fit(columns, residual, inertia) -> tuple:
    """``(residual without the point mass's own inertia, per-joint weights)`` of the least squares whose first four
    ``columns`` are a body's mass and first moment: the body is a point mass at its centre of mass, so its inertia about
    the flange (``inertia``: the last link's six inertia columns) is ``m (|c|^2 1 - c c^T)``, taken with the estimate
    (a fixed point, a few rounds). Without it the body had no inertia about the flange however far its centre of mass
    (no body has that), and the first moment and mass took its accelerations' torque (the heavy virtual arm's centre of
    mass came out too far, its mass too low: docs/results/benchmarks.md). The weights are unweighted, then each joint's
    inverse variance of what that fit leaves (``payload_check.new_payload``); NaN joints weigh 0."""
    measured = np.all(np.isfinite(residual), axis=0)
    residual = np.where(measured, residual, 0.0)
    weights, x, own = measured.astype(float), np.zeros(columns.shape[2]), np.zeros(6)
    for round_ in range(4):
        target = residual - inertia @ own
        gram = np.einsum("n,snc,snd->cd", weights, columns, columns)
        x = np.linalg.lstsq(gram, np.einsum("n,snc,sn->c", weights, columns, target), rcond=None)[0]
        if round_ == 0:
            weights = np.where(measured, 1.0 / np.maximum((target - columns @ x).var(axis=0), 1e-300), 0.0)
        own = point_mass_inertia(x[0], x[1:4])
    return residual - inertia @ own, weights


def payload_entry(mass: float, com) -> dict:
    """The model file's ``findings`` entry of a payload identify took (kind ``rigid_body``: in the rigid body)."""
    parameters = {"mass": float(mass), "com_x": float(com[0]), "com_y": float(com[1]), "com_z": float(com[2])}
    return {"effect": "payload", "label": "payload", "kind": "rigid_body", "joints": [], "source": PAYLOAD_SOURCE,
            "parameters": parameters, "diagnosis": {"parameters": dict(parameters)},
            "applied": "taken up by the rigid body (the robot file's links carrying it)",
            "cause": "payload named by identify's report, preferred to a spring taking the same torque"}  # fmt: skip


def _springs(document) -> list:
    return [f for f in document.get("findings") or [] if f.get("source") == COUNTERBALANCE_SOURCE
            and f.get("effect") == "spring"]  # fmt: skip


def _carried_model(robot, model, options, build, entries, data, fit, beside=()) -> tuple | None:
    """``(CalibratedModel, PayloadWeight, carried robot, fit or None)`` of ``data``: the payload estimated on them
    (``fit``'s drive columns and the springs of the entries ``beside`` beside it), the arm identified carrying it with
    the springs ``entries`` (the fit itself where there are none); None where no body is estimated."""
    from identification.calibration.column_candidates import prepare_training

    terms = [FindingTerm.from_dict(entry["term"]) for entry in beside]
    found = estimate_payload(robot, model, fit, prepare_training(robot, list(data), options).prepared, terms, options)
    if found is None:
        return None
    entry = payload_entry(found.mass, found.com)
    carried = carrying_payloads(robot, model, [entry])
    plain = None
    if entries:
        calibrated = spring_model(carried, model, options, build, entries, data)
    else:
        plain = trial_fit(carried, model, list(data), options)
        calibrated = build(plain)
    calibrated.document["findings"] = [*(calibrated.document.get("findings") or []), entry]
    return calibrated, found, carried, plain


def _opinions(robot, model, options, build, a_doc, b_doc, problem, fit) -> list:
    """``[(route, JointComparison A -> B)]`` of every judge (module docstring)."""
    from identification.calibration.calibrated_model import CalibratedModel
    from identification.calibration.counterbalance_folds import ROUTE

    recordings, validation, configurations, kt = problem
    a_springs, b_springs = _springs(a_doc), _springs(b_doc)
    out = []
    if validation:
        each = compare_each(CalibratedModel(a_doc), CalibratedModel(b_doc), model, list(validation), kt)
        out.append(("held-out recordings", pooled_comparison(each)))
    if len(validation) < 2:
        cutoffs = [c for c in fit.cutoff_hz if c]
        folds = block_folds(recordings, configurations, min(cutoffs) if cutoffs else None)
        if isinstance(folds, str):
            if not validation:
                raise PSDMError(folds)
            return out

        def with_payload(pieces):
            found = _carried_model(robot, model, options, build, b_springs, pieces, fit, a_springs)
            if found is None:
                raise PSDMError("no payload is estimated on the training blocks")
            return found[0]

        together, _ = folds.compare(lambda pieces: spring_model(robot, model, options, build, a_springs, pieces),
                                    with_payload, model, kt)  # fmt: skip
        out.append((f"{ROUTE} ({len(folds.training)} blocks)", together))
    return out


def take_payload(problem, start, taken: CounterbalanceChoice, calibrated, validation, saved, skip=False) -> tuple:
    """``(fit, CalibratedModel, CounterbalanceChoice, PayloadChoice)`` of ``psdm identify`` after its counterbalance
    route (module docstring): ``problem`` = (robot, model, recordings, options, configurations), ``start`` the fit
    before the counterbalance, ``taken`` and ``calibrated`` the counterbalance route's choice and model file (A),
    ``saved`` as for ``counterbalance_column.take_counterbalance``. The returned fit, model and choice are B's where
    the payload is kept; the model file's ``identification.payload`` (and ``counterbalance``) state the choice."""
    fit, calibrated, taken, payload = _take(problem, start, taken, calibrated, validation, saved, skip)
    calibrated.document["identification"]["counterbalance"] = taken.to_dict()
    calibrated.document["identification"]["payload"] = payload.to_dict()
    if payload.reason:
        logger.info("identify: payload: %s", payload.reason)
    return fit, calibrated, taken, payload


def _builder(robot, model, recordings, saved):
    """``build(fit) -> CalibratedModel`` as ``take_counterbalance`` builds its model files."""
    from identification.calibration.calibrated_model import CalibratedModel
    from identification.calibration.recording_provenance import recording_provenance

    keywords, paths = saved
    provenance = [recording_provenance(r, p) for r, p in zip(recordings, paths)]
    return lambda result: CalibratedModel.from_fit(robot, model, result, recordings=provenance, **keywords)


def _take(problem, start, taken, calibrated, validation, saved, skip) -> tuple:
    robot, model, recordings, options, configurations = problem
    fit = taken.fit if taken.kept else start
    unchanged = (fit, calibrated, taken)
    if skip or not start.checked or robot.links is None or not payload_named(start):
        return (*unchanged, PayloadChoice())
    if not taken.joints:  # named, its route suggested; no spring tried: nothing a payload competes with
        return (*unchanged, PayloadChoice(True))
    build = _builder(robot, model, recordings, saved)
    if configurations is not None and any(c.kind != "none" for c in configurations):
        return (*unchanged, PayloadChoice(True, reason="not tried: the recordings state their payloads"))
    kt = recording_kt(robot, *validation, *recordings)
    logger.info("identify: trying the payload the report names (a body at the flange) ...")
    try:
        found = _carried_model(robot, model, options, build, [], recordings, start, _springs(calibrated.document))
    except PSDMError as error:
        return (*unchanged, PayloadChoice(True, reason=f"not tried: {str(error).splitlines()[0]}"))
    if found is None:
        return (*unchanged, PayloadChoice(True, reason="not tried: the torque the robot file leaves gives no body at "
                                          "the flange (a mass that is not positive, or out of reach)"))  # fmt: skip
    plain, weight, carried, carried_fit = found
    mass, com = weight.mass, weight.com

    def build_carried(result):
        out = build(result)
        out.document["findings"] = [*(out.document.get("findings") or []), payload_entry(mass, com)]
        return out

    choice = try_counterbalance(carried, model, recordings, options, carried_fit, plain, validation, build_carried,
                                configurations, kt)  # fmt: skip
    b_doc = copy.deepcopy(choice.document if choice.kept else plain.document)
    a_doc = calibrated.document
    b_joints = {j for f in _springs(b_doc) for j in f["joints"]}
    replaced = tuple(f["label"] for f in _springs(a_doc) if not set(f["joints"]) & b_joints)
    try:
        opinions = _opinions(robot, model, options, build, a_doc, b_doc, (recordings, validation, configurations, kt),
                             start)  # fmt: skip
    except (PSDMError, FoldFailure) as error:
        return (*unchanged, PayloadChoice(True, True, reason=f"not judged: {str(error).splitlines()[0]}; "
                                          f"{weight.sentence()}", mass=mass, com=com, weight=weight))  # fmt: skip
    return _decide(opinions, weight, replaced, (carried_fit, choice, b_doc), unchanged, robot.n_dof)


def payload_wins(comparisons, replaces_springs: bool) -> bool:
    """The module docstring's rule on each judge's ``JointComparison`` of the model without (``before``: A) and with
    the payload (``after``: B): where B needs fewer springs (``replaces_springs``), B unless A is better beyond the
    noise margin on some joint for some judge; otherwise B only if it lowers some joint beyond the margin for every
    judge and makes none worse."""
    worse = any(c.worse for c in comparisons)
    if replaces_springs:
        return not worse
    return bool(comparisons) and not worse and all(np.any(c.after < c.before - c.margin) for c in comparisons)


def _decide(opinions, body, replaced, chosen, unchanged, n_dof) -> tuple:
    """The module docstring's rule on the judges' ``opinions`` (A -> B), with the report's sentence."""
    from identification.calibration.calibrated_model import CalibratedModel

    mass, com = body.mass, body.com
    carried_fit, choice, b_doc = chosen
    route = " and ".join(name for name, _ in opinions)
    first = opinions[0][1]
    better_a = sorted({j for _, c in opinions for j in c.worse})  # B worse than A beyond the margin
    lower_b = [set(np.flatnonzero(c.after < c.before - c.margin)) for _, c in opinions]
    take = payload_wins([c for _, c in opinions], bool(replaced))
    at = ", ".join(f"{v:.3g}" for v in com)
    what = f"a payload on the flange ({mass:.4g} kg, centre of mass [{at}] m)"
    pair = "; ".join(f"joint {j + 1}: {first.before[j]:.4g} -> {first.after[j]:.4g} N m" for j in range(n_dof))
    numbers = dict(
        mass=mass,
        com=com,
        weight=body,
        replaced=replaced,
        rmse_without=tuple(map(float, first.before)),
        rmse_with=tuple(map(float, first.after)),
        margin=tuple(map(float, first.margin)),
        route=route,
    )
    if take:
        lead = (f"{', '.join(replaced)} not kept: {what} explains the same torque on every joint that carries it "
                "(one body for several joints' gravity), and the spring is not better out of sample on any joint "
                "beyond the noise margin") if replaced else (f"{what} identified with the model: it lowers "
                f"{', '.join(f'joint {j + 1}' for j in sorted(set.intersection(*lower_b)) or sorted(lower_b[0]))} "
                "beyond the noise margin on every judge, no joint worse")  # fmt: skip
        reason = f"{lead} (RMSE on the {route}, without -> with the payload: {pair}); its {body.sentence()}"
        calibrated = CalibratedModel(b_doc)
        fit = choice.fit if choice.kept else carried_fit
        payload = PayloadChoice(True, True, True, reason, **numbers)
        return fit, calibrated, choice, payload
    if replaced:
        worse = ", ".join(f"joint {j + 1}" for j in better_a)
        reason = (f"{what} tried and not kept: {', '.join(replaced)} is clearly better out of sample on {worse} "
                  f"(beyond the noise margin; RMSE on the {route}, spring -> payload: {pair})")  # fmt: skip
    else:
        reason = (f"{what} tried and not kept: it does not lower any joint beyond the noise margin on every judge, or "
                  f"makes one worse (RMSE on the {route}, without -> with: {pair})")  # fmt: skip
    reason = f"{reason}; its {body.sentence()}"
    return (*unchanged, PayloadChoice(True, True, False, reason, **numbers))
