"""A tool the free rigid-body recalibration takes into the links is named a payload, judged inside the envelope.

``rigid_body="auto"`` (``rigid_body_choice``) reports the diagnosis with the rigid body identified when the robot
file's inertia is off. A body fixed to the flange is a change of the last links' inertial parameters (``PayloadTerm``:
its columns are the regressor's of a body at the flange), so the free recalibration takes any tool into the links and
that diagnosis can never name it: on the heavy virtual arm a 100-200 kg tool went unreported, carried by wrist links
several times their robot file's mass. A physical arm cannot carry it there: inside the envelope
(``envelope_check.EnvelopedRecalibration``: identify's consistent fit, each link in its bounding ellipsoid, masses
within 0.5-2 x the file's, pulled towards the file) the links keep their size.

:func:`hidden_payload` therefore fits the enveloped rigid body with the identified diagnosis's findings, without and
with a body at the flange (its ten columns free beside the links: the data leave the split between the links and the
body to the pull towards the robot file, so the body takes what the links cannot). The tool is named where the body
lowers the validation RMSE by ``PAYLOAD_MARGIN`` on at least ``MIN_JOINTS`` joints (a load at the flange loads every
joint that carries it; one joint's drop is another effect's) and on more joints than it raises by that margin, lowers
the squared RMSE relative to the fit without it by ``PAYLOAD_MARGIN`` over all joints alike (the links inside their
envelope may trade a joint for the others: on the heavy arm with a gas spring, whose torque only a constant took in
the identified diagnosis, joint 1 rose beside the drops of joints 2-5), and weighs a positive mass with its centre of
mass within reach of the flange (``PayloadTerm.implausibility``).

Its size is not the enveloped body's: the links inside their envelope keep a share of the tool, and a counterbalance
the identified diagnosis holds only in part (a constant for a gas spring) moves the rest. :func:`carried_estimate`
fits it beside the free rigid body with the links that could carry a body at the flange held at the robot file
(``flange_carriers``: the mass of a body at a spherical wrist's centre is fixed in the frame of the link before the
wrist), off by their CAD error only. It is stated as a point mass, the body's mass and first moments (its own inertia
is what the data fix least), on the last joint's axis where the model holds no last link (the links before the flange
mimic no part that turns with that joint).
:func:`with_payload` puts it in the identified diagnosis: the payload's base-parameter change
(``PayloadTerm.theta_change``, through the map the augmented model folds it with) is taken out of the identified rigid
body and given to the payload term, so that the links no longer carry the tool and the model predicts as before (its
prediction recomputed: exactly as before where the links mimic the load).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.carried_payload import flange_carrier, flange_parameter_map
from identification.diagnosis.candidates import PayloadTerm
from identification.diagnosis.design import joint_weights, left_out
from identification.diagnosis.held_links import held_links
from identification.diagnosis.nominal import friction_feature_names
from identification.diagnosis.selection import SelectionStep
from psdm_casadi.errors import SolverError

__all__ = [
    "MIN_JOINTS",
    "PAYLOAD_MARGIN",
    "HiddenPayload",
    "carried_estimate",
    "flange_carriers",
    "hidden_payload",
    "name_hidden_payload",
    "with_payload",
]

logger = logging.getLogger(__name__)

PAYLOAD_MARGIN = 0.2  # the body must lower a joint's validation RMSE by this fraction (and raise none by it)
MIN_JOINTS = 2  # on at least this many joints: a load at the flange loads every joint that carries it
SEPARATE = 0.5  # a direction of the flange's point mass told apart from the free links keeps this share of its norm
SPAN_TOLERANCE = 1e-6  # a payload's base-parameter change outside the free links' span (held links) by more: not moved


@dataclass(frozen=True, eq=False)
class HiddenPayload:
    """A tool the enveloped rigid body needs at the flange: ``coefficients`` (m, m r: a point mass in the last link
    frame), the ``joints`` (0-based) it lowers by ``PAYLOAD_MARGIN``, largest drop first, and the enveloped fits
    (``envelope_check.EnvelopedFit``) ``without`` it and ``with_body`` (the body at the flange beside the links)."""

    coefficients: np.ndarray
    joints: tuple
    without: object
    with_body: object

    @property
    def mass(self) -> float:
        return float(self.coefficients[0])

    @property
    def com(self) -> np.ndarray:
        return np.asarray(self.coefficients[1:4], dtype=float) / self.mass

    def note(self) -> str:
        """The report's sentence on the payload and why it is named."""
        com = ", ".join(f"{v:.3g}" for v in self.com)
        pairs = "; ".join(
            f"joint {j + 1}: {self.without.rmse_validation[j]:.4g} -> {self.with_body.rmse_validation[j]:.4g} N m"
            for j in self.joints
        )
        return (
            f"`payload` named ({self.mass:.4g} kg, centre of mass ({com}) m in the last link frame) although the free "
            "rigid-body recalibration takes it into the links: a rigid body recalibrated as 'psdm identify' does "
            "(each link inside its envelope, masses within 0.5-2 x the robot file's) cannot carry it, and with a body "
            f"at the flange its validation RMSE falls ({pairs}). The identified links are stated without it."
        )


def hidden_payload(enveloped, terms) -> HiddenPayload | None:
    """The ``HiddenPayload`` the enveloped recalibration ``enveloped`` (``EnvelopedRecalibration``) needs beside the
    findings ``terms`` (module docstring), or None (not needed, not a body, a payload already among ``terms``, or the
    fit did not converge)."""
    terms = list(terms)
    if enveloped.robot.links is None or any(getattr(t, "key", "") == "payload" for t in terms):
        return None
    logger.info("diagnose: judging a body at the flange against a rigid body recalibrated inside its envelope ...")
    try:
        without = enveloped.fit(terms)
        body = enveloped.fit([*terms, PayloadTerm(inertia=True)])
    except SolverError as error:
        logger.info(f"diagnose: the enveloped recalibration did not converge ({error}); no payload judged")
        return None
    before, after = without.rmse_validation, body.rmse_validation
    drop = 1.0 - after / np.maximum(before, 1e-300)
    lower = [int(j) for j in np.argsort(-drop) if drop[j] >= PAYLOAD_MARGIN]
    worse = [j for j in range(before.size) if after[j] > (1.0 + PAYLOAD_MARGIN) * before[j]]
    ratio = float(np.nanmean((after / np.maximum(before, 1e-300)) ** 2))  # every joint alike
    point = np.asarray(body.coefficients[-1][:4], dtype=float)
    logger.info(f"diagnose:   a body of {point[0]:.4g} kg at the flange: validation RMSE "
                + ", ".join(f"{a:.4g} -> {b:.4g}" for a, b in zip(before, after)) + " N m")  # fmt: skip
    if len(lower) < max(MIN_JOINTS, len(worse) + 1) or ratio > 1.0 - PAYLOAD_MARGIN:
        return None
    return HiddenPayload(point, tuple(lower), without, body)


def flange_carriers(robot, model, held=()) -> tuple | None:
    """The links (0-based, with the ``held`` ones) that a free rigid-body fit must hold at the robot file for a body
    at the flange to be told apart from them: the last links, from the flange back, until each of the point mass's
    base-parameter directions keeps ``SEPARATE`` of its norm outside what the free links reach (``held_links``); None
    where none does."""
    n = robot.n_dof
    directions = flange_parameter_map(robot, model)[:, 11 * (n - 1) : 11 * (n - 1) + 4]
    norms = np.linalg.norm(directions, axis=0)
    used = norms > 1e-12 * max(float(norms.max()), 1e-300)
    for first in range(n - 1, -1, -1):
        links = tuple(sorted(set(range(first, n)) | set(held)))
        fixed = held_links(model, robot, links)
        if fixed is None:
            return None
        outside = directions - fixed.basis @ (fixed.basis.T @ directions)
        if np.all(np.linalg.norm(outside, axis=0)[used] >= SEPARATE * norms[used]):
            return links
    return None


def carried_estimate(robot, model, problem, friction, terms, held=()) -> np.ndarray | None:
    """The point mass (m, m r) of a body at the flange fitted beside the free rigid body with the links that would
    carry it held at the robot file (``flange_carriers``), the friction columns ``friction`` (``BlockColumns`` of
    ``problem.ctx_t``) and the findings ``terms``: least squares on the training recording of ``problem`` (contexts
    with their regressor), each joint weighted by its torque RMS; None without such links. The links held are off by
    their CAD error only, far less than the tool the links inside their envelope share with the body."""
    links = flange_carriers(robot, model, held)
    if links is None:
        return None
    fixed, ctx = held_links(model, robot, links), problem.ctx_t
    parts = [friction.dense(), fixed.columns(ctx.regressor), *(np.asarray(t.columns(ctx), float) for t in terms),
             PayloadTerm(inertia=True).columns(ctx)]  # fmt: skip
    columns, y = np.concatenate(parts, axis=2), ctx.tau_fit - fixed.torque(ctx.regressor)
    sigma = joint_weights(ctx.tau, left_out(ctx))
    measured = [j for j in range(y.shape[1]) if j not in left_out(ctx)]
    a = (columns[:, measured] / sigma[measured, None]).reshape(-1, columns.shape[2])
    x = np.linalg.lstsq(a, (y[:, measured] / sigma[measured]).reshape(-1), rcond=None)[0]
    return x[-10:-6]


def name_hidden_payload(robot, model, problems, fits, options, enveloped) -> tuple | None:
    """``(selection, final, note)`` of the identified diagnosis with the tool it hides named (module docstring), or
    None. ``problems`` are the prior's and the identified ``DiagnosisProblem`` (the friction columns, the contexts with
    their regressor), ``fits`` the identified ``(selection, final)``, ``options`` its ``DiagnosisOptions``,
    ``enveloped`` its ``EnvelopedRecalibration``."""
    (prior, identified), (selection, final) = problems, fits
    payload = hidden_payload(enveloped, final.terms)
    if payload is None:
        return None
    point = carried_estimate(robot, model, identified, prior.base_t, final.terms, options.held_links)
    payload = payload if point is None else replace(payload, coefficients=point)
    carrier = flange_carrier(robot, model)
    if carrier is not None and carrier[0] != robot.n_dof - 1:  # a last link the model holds none of: on its axis
        payload = replace(payload, coefficients=payload.coefficients * np.array([1.0, 0.0, 0.0, 1.0]))
    reason = "a negative mass" if payload.mass <= 0.0 else PayloadTerm().implausibility(payload.coefficients)
    if reason is not None:
        logger.info(f"diagnose:   the body at the flange is not named a tool: {reason}")
        return None
    named = with_payload(robot, model, identified, selection, final, options, payload)
    return None if named is None else (*named, payload.note())


def with_payload(robot, model, problem, selection, final, options, payload: HiddenPayload) -> tuple | None:
    """``(selection, final)`` of the identified diagnosis of ``problem`` (a ``DiagnosisProblem`` with the rigid body
    identified, ``options`` its ``DiagnosisOptions``) with ``payload`` as its last kept term (module docstring), or
    None where the payload's base-parameter change is no change of the free links (links held there)."""
    term, p = PayloadTerm(), np.asarray(payload.coefficients, dtype=float)
    delta = term.theta_change(p, flange_parameter_map(robot, model))
    held = held_links(model, robot, options.held_links)
    shift = delta if held is None else np.linalg.lstsq(held.basis, delta, rcond=None)[0]
    if held is not None and np.linalg.norm(held.basis @ shift - delta) > SPAN_TOLERANCE * np.linalg.norm(delta):
        return None
    n = robot.n_dof
    start = len(friction_feature_names(options.friction, n)) + (n if options.friction == "lugre" and robot.drives
                                                                 is not None else 0)  # fmt: skip
    coefficients = np.array(final.friction_coefficients, dtype=float)
    if coefficients.size - start != shift.size:
        return None
    coefficients[start:] -= shift
    prediction_t, prediction_v = (
        prediction - ctx.regressor @ delta + term.columns(ctx) @ p
        for prediction, ctx in ((final.prediction_t, problem.ctx_t), (final.prediction_v, problem.ctx_v))
    )
    before, after = payload.without, payload.with_body
    sigma = joint_weights(problem.ctx_t.tau, left_out(problem.ctx_t))
    counted = np.isfinite(before.rmse_validation) & np.isfinite(after.rmse_validation)
    wval0, wval1 = (float(np.sum((r.rmse_validation[counted] / sigma[counted]) ** 2)) for r in (before, after))
    samples = problem.ctx_t.n_samples * n
    sse0, sse1 = (float(np.sum(r.rmse_train[counted] ** 2)) * problem.ctx_t.n_samples for r in (before, after))
    delta_bic = samples * np.log(max(sse1, 1e-300) / max(sse0, 1e-300)) + p.size * np.log(samples)
    step = SelectionStep(term=term, joints=payload.joints, rmse_before=before.rmse_validation,
                         rmse_after=after.rmse_validation, rmse_train_before=before.rmse_train,
                         rmse_train_after=after.rmse_train, delta_bic=float(delta_bic),
                         validation_gain=(wval0 - wval1) / max(wval0, 1e-300),
                         shape_note="a body at the flange that the free rigid-body recalibration takes into the links: "
                         "judged against a rigid body recalibrated inside its envelope")  # fmt: skip
    selection = replace(selection, steps=selection.steps + (step,), coefficients=selection.coefficients + (p,))
    final = replace(final, terms=final.terms + (term,), coefficients=final.coefficients + (p,),
                    friction_coefficients=coefficients, prediction_t=prediction_t,
                    prediction_v=prediction_v)  # fmt: skip
    return selection, final
