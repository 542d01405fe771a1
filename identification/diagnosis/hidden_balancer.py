"""A counterbalance the free rigid-body recalibration takes into the links is named, against the robot file's gravity.

``rigid_body="auto"`` (``rigid_body_choice``) reports the diagnosis with the rigid body identified when the prior
model with its findings predicts worse than a full rigid-body recalibration: wrong CAD inertia is not missing physics.
A counterbalance on a shoulder (a spring, a gas spring) then goes unreported: its torque is a smooth law of the joint's
own angle, close to the shape of that joint's gravity torque over a recorded range, and the free recalibration takes
it into the links as a lighter (or heavier) link. On the heavy arm with a gas spring on joint 2 and datasheet masses
10-20 % off, recorded for minutes, the prior model needed the spring and a payload and still predicted worse than the
recalibration, which moved joint 2's gravity torque by a third of the robot file's and reported nothing.
``hidden_payload`` names a tool the links absorbed in the same place; this module names an angle law.

The robot file separates the balancer from the links (``angle_law_choice``): its masses and centres of mass are off
by their CAD error, not by the size of a counterbalance. :func:`hidden_balancers` therefore looks, after the rigid
body is recalibrated, at what the links moved: on each joint whose recalibrated gravity torque (the regressor at rest,
on the validation recording) departs from the robot file's by more than ``FILE_GRAVITY_ERROR`` of it, the angle law
(the prior diagnosis's law on that joint, its shape chosen by BIC there, else a linear spring) is fitted beside the
nominal friction and the rigid body with that joint's own link held at the robot file (``held_links``: the link whose
gravity moment the law mimics; the later links stay free, their masses pinned by the other joints and the inertial
torques). The law is named where

- it is a plausible law (``implausibility``: a spring of positive stiffness, a gas spring that pushes);
- it opposes the file's gravity torque on its joint by a share between ``FILE_GRAVITY_ERROR`` and the whole of it (a
  counterbalance holds up part of the arm's weight; a tool or a heavier link adds to it, and a CAD error is smaller);
- what the recalibration moved is its torque: the departure less the law's torque is within ``FILE_GRAVITY_ERROR``;
- with the link held, it lowers its joint's validation RMSE by ``BALANCER_MARGIN`` (the links at the file need it);
- and the recalibrated rigid body refitted with the law's torque held (the links no longer carry the balancer)
  predicts no joint of the validation recording worse than the recalibration by more than ``NOT_WORSE``.

The named law keeps the held fit's coefficients (the file anchors the split between the link and the balancer, which
the recording alone hardly makes), and the rigid body and friction are refitted on the training recording with its
torque taken off (:func:`with_balancer`); the diagnosis reports the refit.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.gravity_departure import FILE_GRAVITY_ERROR
from identification.calibration.merged_rotors import robot_file_theta
from identification.diagnosis.angle_law_choice import gravity_torque
from identification.diagnosis.backed_name import ANGLE_LAWS
from identification.diagnosis.candidates import SpringTerm
from identification.diagnosis.design import joint_weights, left_out, solve_scaled
from identification.diagnosis.held_links import held_links
from identification.diagnosis.selection import SelectionStep
from identification.metrics import rms, rmse

__all__ = ["BALANCER_MARGIN", "NOT_WORSE", "HiddenBalancer", "hidden_balancers", "name_hidden_balancers"]

logger = logging.getLogger(__name__)

BALANCER_MARGIN = 0.2  # with its joint's link held at the robot file, the law lowers that joint's validation RMSE so
NOT_WORSE = 0.02  # the refit with the law may raise a joint's validation RMSE by at most this fraction (noise margin)


@dataclass(frozen=True, eq=False)
class HiddenBalancer:
    """An angle law (``term`` with ``coefficients``) on ``joint`` (0-based) that the recalibrated links carried.

    RMS [N m] over the validation recording: the robot file's gravity torque on the joint (``file_gravity``), the
    recalibration's departure from it (``departure``) and that departure less the law's torque (``remainder``), the
    law's torque (``law``); ``share`` is the fraction of the file's gravity torque it opposes. Per-joint validation
    RMSE [N m]: of the fit with the joint's link held at the file without the law (``held_without``) and with it
    (``held_with``), of the recalibration (``before``) and of its refit with the law (``after``)."""

    term: object
    coefficients: np.ndarray
    joint: int
    file_gravity: float
    departure: float
    remainder: float
    law: float
    share: float
    held_without: np.ndarray
    held_with: np.ndarray
    before: np.ndarray = None
    after: np.ndarray = None

    def stated(self) -> str:
        """The law's size in the report's words: its stiffness (a spring) or lever product (a gas spring)."""
        parameters = self.term.physical_parameters(self.coefficients)
        if "k" in parameters:
            return f"k = {parameters['k']:.4g} N m/rad"
        return f"k a b = {parameters.get('k_ab', float('nan')):.4g} N m"

    def note(self) -> str:
        """The report's sentence on the balancer and why it is named."""
        j = self.joint + 1
        pairs = "; ".join(f"joint {k + 1}: {self.before[k]:.4g} -> {self.after[k]:.4g} N m" for k in self.changed())
        return (
            f"`{self.term.label}` named ({self.stated()}, opposing {self.share:.0%} of joint {j}'s gravity torque) "
            "although the free rigid-body recalibration takes it into the links: that recalibration moves joint "
            f"{j}'s gravity torque by {self.departure:.4g} N m RMS from the robot file's ({self.file_gravity:.4g} N m "
            f"RMS), more than the {FILE_GRAVITY_ERROR:.0%} a CAD error explains, and the law's torque "
            f"({self.law:.4g} N m RMS) is that departure ({self.remainder:.4g} N m RMS left). With link {j} held at "
            f"the robot file the validation RMSE of joint {j} is {self.held_without[self.joint]:.4g} N m without it, "
            f"{self.held_with[self.joint]:.4g} N m with it. The rigid body is recalibrated with the balancer's torque "
            f"taken off (validation RMSE {pairs})."
        )

    def changed(self) -> list:
        """The joints (0-based) whose validation RMSE the refit moved by more than 0.5 %, the law's joint first."""
        moved = [k for k in range(self.before.size) if abs(self.after[k] - self.before[k]) > 0.005 * self.before[k]]
        return [self.joint] + [k for k in moved if k != self.joint]


def _law_term(joint: int, prior_terms, ctx_t):
    """The angle law tried on ``joint``: the prior diagnosis's (its shape chosen there), else a linear spring over
    the training range."""
    for term in prior_terms:
        if term.key in ANGLE_LAWS and tuple(term.joints) == (joint,):
            return term
    q = ctx_t.q[:, joint]
    return SpringTerm(joint=joint, q_range=(float(np.min(q)), float(np.max(q))))


def _solve(columns, y, sigma, measured) -> np.ndarray:
    """Least squares of ``columns`` (n_samples, n_dof, k) to ``y`` over the ``measured`` joints, each weighted by
    ``1 / sigma`` (normal equations with the columns scaled, as the selection solves them)."""
    a = (columns[:, measured] / sigma[measured, None]).reshape(-1, columns.shape[2])
    return solve_scaled(a.T @ a, a.T @ (y[:, measured] / sigma[measured]).reshape(-1))


class _Fits:
    """The fits of one identified diagnosis (``problem``, a ``DiagnosisProblem`` with the rigid body identified, its
    final fit ``final`` and the nominal friction's columns ``friction`` of training and validation): the torque its
    kept terms add, held in every refit here."""

    def __init__(self, problem, final, friction):
        self.problem, self.friction = problem, friction
        ctx_t = problem.ctx_t
        self.sigma = joint_weights(ctx_t.tau, left_out(ctx_t))
        self.measured = [j for j in range(ctx_t.tau.shape[1]) if j not in left_out(ctx_t)]
        fc = np.asarray(final.friction_coefficients, dtype=float)
        self.others = tuple(prediction - base.dense() @ fc for prediction, base in
                            ((final.prediction_t, problem.base_t), (final.prediction_v, problem.base_v)))  # fmt: skip

    def held(self, model, robot, links, term=None) -> tuple:
        """``(coefficients of term or None, validation RMSE)`` of the friction, the rigid body with ``links`` held at
        the robot file, the kept terms' torque and ``term``, fitted on the training recording."""
        held = held_links(model, robot, links)
        parts = []
        for ctx, friction, others in zip((self.problem.ctx_t, self.problem.ctx_v), self.friction, self.others):
            columns = [friction.dense(), held.columns(ctx.regressor)]
            columns += [] if term is None else [np.asarray(term.columns(ctx), dtype=float)]
            parts.append((np.concatenate(columns, axis=2), ctx.tau_fit - held.torque(ctx.regressor) - others))
        (a_t, y_t), (a_v, y_v) = parts
        x = _solve(a_t, y_t, self.sigma, self.measured)
        law = None if term is None else x[-len(term.feature_names()) :]
        return law, rmse(y_v, a_v @ x)

    def refit(self, torques) -> tuple:
        """``(friction_coefficients, prediction_t, prediction_v)``: the friction and the recalibrated rigid body
        refitted on the training recording with the law's ``torques`` (training, validation) held."""
        problem = self.problem
        y_t = problem.y_t - self.others[0] - torques[0]
        x = _solve(problem.base_t.dense(), y_t, self.sigma, self.measured)
        predictions = (base.dense() @ x + others + torque for base, others, torque in
                       zip((problem.base_t, problem.base_v), self.others, torques))  # fmt: skip
        return (x, *predictions)


def hidden_balancers(robot, model, problem, final, friction, theta, prior_terms=(), held=()) -> list:
    """The ``HiddenBalancer`` laws (module docstring) of the identified diagnosis ``problem`` with its ``final`` fit
    (``diagnose.FinalFit``), the nominal friction's columns ``friction`` (training, validation), its recalibrated base
    parameters ``theta`` and the prior diagnosis's kept terms ``prior_terms``; ``held`` are the links a model file
    holds (held here too). Each with ``before`` and ``after`` left unset; empty without the robot file's links."""
    if robot.links is None:
        return []
    ctx_t, ctx_v = problem.ctx_t, problem.ctx_v
    file_gravity = gravity_torque(model, ctx_v.q, robot_file_theta(robot, model, ctx_v.torque_constants))
    departure = gravity_torque(model, ctx_v.q, theta) - file_gravity
    fits, kept = _Fits(problem, final, friction), {j for t in final.terms if t.key in ANGLE_LAWS for j in t.joints}
    found = []
    for j in fits.measured:
        size, moved = float(rms(file_gravity[:, j])), float(rms(departure[:, j]))
        if j in kept or j in held or size <= 0.0 or moved <= FILE_GRAVITY_ERROR * size:
            continue
        term = _law_term(j, prior_terms, ctx_t)
        links = tuple(sorted({*held, j}))
        _, without = fits.held(model, robot, links)
        c, with_law = fits.held(model, robot, links, term)
        law = np.asarray(term.columns(ctx_v), dtype=float)[:, j, :] @ c
        share = float(-np.dot(law, file_gravity[:, j]) / np.dot(file_gravity[:, j], file_gravity[:, j]))
        left = float(rms(departure[:, j] - law))
        logger.info(
            f"diagnose:   joint {j + 1}'s gravity torque moved {moved:.4g} N m RMS from the robot file's ({size:.4g}); "
            f"{term.label} with link {j + 1} held there: opposes {share:.0%} of it, leaves {left:.4g} N m of the "
            f"departure, validation RMSE {without[j]:.4g} -> {with_law[j]:.4g} N m"
        )
        reason = term.implausibility(c, ctx_t)
        if (reason is None and FILE_GRAVITY_ERROR <= share <= 1.0 and left <= FILE_GRAVITY_ERROR * size
                and with_law[j] <= (1.0 - BALANCER_MARGIN) * without[j]):  # fmt: skip
            found.append(HiddenBalancer(term, c, j, size, moved, left, float(rms(law)), share, without, with_law))
    return found


def name_hidden_balancers(robot, model, problem, fits, friction, theta, prior_terms=(), held=()) -> tuple | None:
    """``(selection, final, notes)`` of the identified diagnosis (``problem``, ``fits`` its ``(selection, final)``)
    with the balancers its links carried named (``hidden_balancers``; arguments as there), each refitted with the
    recalibrated rigid body and kept where that refit makes no joint worse than ``NOT_WORSE``; None when none is."""
    selection, final = fits
    notes = []
    for balancer in hidden_balancers(robot, model, problem, final, friction, theta, prior_terms, held):
        named = with_balancer(problem, selection, final, friction, balancer)
        if named is None:
            continue
        selection, final, balancer = named
        notes.append(balancer.note())
    return (selection, final, tuple(notes)) if notes else None


def with_balancer(problem, selection, final, friction, balancer: HiddenBalancer) -> tuple | None:
    """``(selection, final, balancer)`` with ``balancer`` as the last kept term of the identified diagnosis, the
    friction and rigid body refitted with its torque held (``before``/``after`` set), or None where that refit makes
    a joint's validation RMSE worse by more than ``NOT_WORSE``."""
    term, c, j = balancer.term, np.asarray(balancer.coefficients, dtype=float), balancer.joint
    fits = _Fits(problem, final, friction)
    torques = tuple(np.asarray(term.columns(ctx), dtype=float) @ c for ctx in (problem.ctx_t, problem.ctx_v))
    x, prediction_t, prediction_v = fits.refit(torques)
    before, after = rmse(problem.y_v, final.prediction_v), rmse(problem.y_v, prediction_v)
    train_before, train_after = rmse(problem.y_t, final.prediction_t), rmse(problem.y_t, prediction_t)
    worse = [k for k in fits.measured if after[k] > (1.0 + NOT_WORSE) * before[k]]
    logger.info(f"diagnose:   recalibrated with {term.label} held: validation RMSE "
                + ", ".join(f"{a:.4g} -> {b:.4g}" for a, b in zip(before, after)) + " N m")  # fmt: skip
    if worse:
        return None
    sigma, n = fits.sigma[fits.measured], len(fits.measured)
    wval0, wval1 = (float(np.sum((r[fits.measured] / sigma) ** 2)) for r in (before, after))
    samples = problem.ctx_t.n_samples * n
    sse0, sse1 = (float(np.sum(r[fits.measured] ** 2)) * problem.ctx_t.n_samples for r in (train_before, train_after))
    delta_bic = samples * np.log(max(sse1, 1e-300) / max(sse0, 1e-300)) + c.size * np.log(samples)
    step = SelectionStep(term=term, joints=(j,), rmse_before=before, rmse_after=after, rmse_train_before=train_before,
                         rmse_train_after=train_after, delta_bic=float(delta_bic),
                         validation_gain=(wval0 - wval1) / max(wval0, 1e-300),
                         shape_note=f"a counterbalance the free rigid-body recalibration takes into the links: fitted "
                         f"with link {j + 1} held at the robot file")  # fmt: skip
    selection = replace(selection, steps=selection.steps + (step,), coefficients=selection.coefficients + (c,))
    final = replace(final, terms=final.terms + (term,), coefficients=final.coefficients + (c,),
                    friction_coefficients=x, prediction_t=prediction_t, prediction_v=prediction_v)  # fmt: skip
    return selection, final, replace(balancer, before=before, after=after)
