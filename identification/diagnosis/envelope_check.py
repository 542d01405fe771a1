"""Is a finding needed when the recalibrated rigid body must stay physical? The stand-in rule, held to the envelope.

With ``rigid_body="auto"`` (``rigid_body_choice``) a finding of the prior model that a full rigid-body recalibration
makes unnecessary "stands in" for the robot file's wrong inertia and is dropped. That recalibration is the free least
squares one: its base parameters may take any value, so an effect with the shape of a gravity torque is absorbed by a
rigid body no arm has. The first harmonic of a cam counterbalance on a shoulder has the shape of that joint's gravity:
a link 2 twice as heavy, its centre of mass outside the link, fits it. Inertia 10-20 % off (CAD values) is something a
physical link can be; absorbing a counterbalance is not.

``EnvelopedRecalibration.check`` therefore fits the rigid body as ``psdm identify`` does (``consistent_fit``: every
link with a positive-definite pseudo-inertia inside its bounding ellipsoid, masses and drive inertias within 0.5-2 x
the robot file's, ``TrajectoryOptions`` defaults; the drive inertias the base parameters merge held where identify
holds them, ``merged_rotors.with_merged_rotors``, so the links do not absorb the rotors on motor-side torques or
currents) on the training recording, jointly with the nominal friction and
all the prior's findings, and once more without each per-joint finding that would be dropped (leave one out: a
finding is judged by what it adds to the others, not by what fixing another joint does to its own). A finding that
lowers its joint's validation RMSE by ``STAND_IN_MARGIN`` there is needed even by a physical rigid body, so it is not
a stand-in (``EnvelopeCheck``; ``rigid_body_choice.standing_in`` keeps it, and the report says why). The fits cost an
Ipopt solve each (seconds), and are made only for findings the free recalibration would drop.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from identification.calibration.consistent_fit import consistent_fit, residual_sigma
from identification.calibration.merged_rotors import with_merged_rotors
from identification.calibration.residual_correlation import residual_correlation_time
from identification.calibration.trajectory_data import NormalEquations
from identification.calibration.trajectory_fit import TrajectoryOptions
from identification.diagnosis.rigid_body_choice import Claim
from identification.metrics import rmse
from psdm_casadi.errors import SolverError

logger = logging.getLogger(__name__)

STAND_IN_MARGIN = 0.2  # a finding must lower its joint's validation RMSE this much (fraction) to be needed there


@dataclass(frozen=True)
class NeededFinding:
    """A finding a rigid body recalibrated inside its envelope still needs: its ``label`` and ``claim``
    (``rigid_body_choice.Claim``), the ``joints`` (0-based) where it lowers the validation RMSE by ``STAND_IN_MARGIN``,
    and the per-joint validation RMSE [N m] of the enveloped recalibration without it (``rmse_without``) and with it
    (``rmse_with``, all findings)."""

    label: str
    claim: Claim
    joints: tuple
    rmse_without: np.ndarray
    rmse_with: np.ndarray


@dataclass(frozen=True, eq=False)
class EnvelopedFit:
    """One enveloped recalibration: the per-joint RMSE [N m] on the training and the validation recording, and the
    fitted coefficients of each finding's columns (in the order of its terms)."""

    rmse_train: np.ndarray
    rmse_validation: np.ndarray
    coefficients: tuple


@dataclass(frozen=True)
class EnvelopeCheck:
    """The findings (``NeededFinding``) that a rigid body recalibrated inside its envelope still needs (module
    docstring); empty when none."""

    needed: tuple = ()

    @property
    def claims(self) -> tuple:
        """The ``Claim`` of each needed finding."""
        return tuple(finding.claim for finding in self.needed)

    def notes(self) -> tuple:
        """The report's sentences, one per needed finding."""
        return tuple(
            f"`{f.label}` kept although the free rigid-body recalibration fits its joint without it: that "
            "recalibration is not a physical arm. With the rigid body recalibrated as 'psdm identify' does (each link "
            "inside its envelope, masses within 0.5-2 x the robot file's) it is still needed (validation RMSE "
            + "; ".join(
                f"joint {j + 1}: {f.rmse_without[j]:.4g} without it, {f.rmse_with[j]:.4g} N m with it" for j in f.joints
            )
            + ")."
            for f in self.needed
        )


def _columns(ctx, friction, terms, free) -> tuple:
    """The columns ``[regressor, friction, terms...]`` (n_samples, n_dof, k) of a context with its regressor, the
    friction's ``free`` ones (those of a model file's held friction are none of the fit), and the names of those after
    the base parameters: a ``rotor_inertia`` finding's is ``Ia<j>`` (identify's drive-inertia column), the others
    ``extra<k>``."""
    parts = [ctx.regressor, friction.dense()[:, :, free]] + [np.asarray(t.columns(ctx), dtype=float) for t in terms]
    names = [f"extra{k}" for k in range(parts[1].shape[2])]
    for term, part in zip(terms, parts[2:]):
        rotor = getattr(term, "key", "") == "rotor_inertia" and part.shape[2] == 1
        names += [f"Ia{term.joint + 1}"] if rotor else [f"extra{len(names) + k}" for k in range(part.shape[2])]
    return np.concatenate(parts, axis=2), names


class EnvelopedRecalibration:
    """The rigid body recalibrated inside identify's envelope on one diagnosis problem, with the nominal friction and
    the linear columns of given findings; each fit is remembered per set of findings.

    Parameters
    ----------
    robot, model
        The robot file (its links give the envelope and the mass bounds) and its PSDM model.
    contexts : tuple (training, validation) of DiagnosisContext
        With their regressor (``rigid_body_choice.with_regressor``).
    friction : tuple (training, validation) of BlockColumns
        The nominal friction's columns.
    held_links : tuple of int
        Links (0-based) held at the robot's inertia (``DiagnosisOptions.held_links``).
    rotors_apart : tuple of int
        Joints (0-based) whose merged rotor is taken apart from the same actuator's (``DiagnosisOptions.rotors_apart``).
    """

    def __init__(self, robot, model, contexts, friction, held_links=(), rotors_apart=()):
        self.robot = robot
        self.held_links = tuple(held_links)  # a model file's held links: held here too (``TrajectoryOptions``)
        self.rotors_apart = tuple(rotors_apart)  # a model file's rotors taken apart: apart here too
        self.model = model  # the derived map; each fit puts identify's merged rotors in it (``_fit``)
        self.contexts = contexts
        self.friction = friction
        self.fits = {}

    def rmse(self, terms) -> np.ndarray:
        """Per joint, the validation RMSE [N m] of the enveloped recalibration with the findings ``terms``.

        Raises
        ------
        SolverError
            When Ipopt fails.
        """
        return self.fit(terms).rmse_validation

    def fit(self, terms) -> EnvelopedFit:
        """The ``EnvelopedFit`` with the findings ``terms`` (made once per set of labels).

        Raises
        ------
        SolverError
            When Ipopt fails.
        """
        key = tuple(term.label for term in terms)
        if key not in self.fits:
            self.fits[key] = self._fit(list(terms))
        return self.fits[key]

    def _fit(self, terms) -> EnvelopedFit:
        """The ``EnvelopedFit`` of identify's consistent fit with ``terms``: in identify's map
        (``merged_rotors.with_merged_rotors``, the one place both routes take it from), so that a drive inertia the
        base parameters merge is held where identify holds it (the robot file's; on currents its siblings'; else what
        the data want beside the file's links) and the links do not absorb it. A ``rotor_inertia`` finding's column is
        the drive-inertia column ``Ia<j>`` of identify (>= 0): it says that the torque holds the rotors, as identify's
        kept ``Ia<j>`` columns do."""
        (ctx_t, ctx_v), robot = self.contexts, self.robot
        free = sorted(set().union(*(set(index.tolist()) for index in self.friction[0].index)))  # held: in no joint's
        train, names = _columns(ctx_t, self.friction[0], terms, free)
        equations = NormalEquations(robot.n_dof, train.shape[2])
        equations.add(train, ctx_t.tau_fit)
        x_ols = np.linalg.lstsq(train.reshape(-1, train.shape[2]), ctx_t.tau_fit.reshape(-1), rcond=None)[0]
        options = TrajectoryOptions(held_links=self.held_links, rotors_apart=self.rotors_apart)
        merged = with_merged_rotors(self.model, robot, options, ctx_t.torque_constants, (equations, names), log=False)
        correlation = residual_correlation_time(ctx_t.tau_fit - train @ x_ols)  # the pull's weight as identify's
        standard, extra, _, _, _ = consistent_fit(
            merged.robot, merged.model, equations, residual_sigma(equations, x_ols), names, options,
            np.full(len(names), -np.inf), bounds=merged.fit_bounds(options), warn=False, correlation=correlation,
        )  # fmt: skip
        x = np.concatenate([merged.model.base_parameters(standard), extra])
        split = np.cumsum([len(free)] + [len(term.feature_names()) for term in terms])
        validation = _columns(ctx_v, self.friction[1], terms, free)[0]
        return EnvelopedFit(rmse(ctx_t.tau_fit, train @ x), rmse(ctx_v.tau_fit, validation @ x),
                            tuple(np.split(extra, split)[1:-1]))  # fmt: skip

    def check(self, selection, joints) -> EnvelopeCheck:
        """The ``EnvelopeCheck`` of the per-joint findings of ``selection`` (a ``SelectionResult``) that act on
        ``joints`` (0-based; those the free recalibration would drop): each left out of the fit of all in turn."""
        steps = list(selection.steps)
        tested = [s for s in steps if Claim.of_step(s).per_joint and set(Claim.of_step(s).joints) & set(joints)]
        if self.robot.links is None or not tested:
            return EnvelopeCheck()
        logger.info("diagnose: judging the findings against a rigid body recalibrated inside its physical envelope ...")
        terms = [s.term for s in steps]
        needed = []
        try:
            with_all = self.rmse(terms)
            for step in tested:
                without = self.rmse([t for t in terms if t is not step.term])
                on = [j for j in Claim.of_step(step).joints if with_all[j] <= (1.0 - STAND_IN_MARGIN) * without[j]]
                if on:
                    needed.append(NeededFinding(step.term.label, Claim.of_step(step), tuple(on), without, with_all))
        except SolverError as error:
            logger.info(f"diagnose: the enveloped recalibration did not converge ({error}); not used")
            return EnvelopeCheck()
        return EnvelopeCheck(tuple(needed))
