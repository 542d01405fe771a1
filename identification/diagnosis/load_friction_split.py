"""One coefficient on every half: a load-dependent friction is named only where the same ``mu`` explains the friction
on the slow and the fast samples of the training recording, and on the light- and the heavy-load ones.

The candidate's column (``candidates.friction.LoadDependentFrictionTerm``) is ``|tau| sign(qd)`` of the measured
torque. Where friction and drive inertia make most of a joint's torque (a wrist logged by its motor currents), the
torque seldom opposes the motion and that column is the measured torque itself on most samples: ``mu`` then rescales
whatever the nominal friction gets wrong (a Stribeck peak it lacks, a friction that changed between the recordings as
the joints warmed, a rotor the robot file lacks) and passes the selection's gates with a plausible value (the unseen
warming cobot's joint 6), and a true ``mu`` there cannot be told from a rescaled torque either. A gear's tooth
friction holds one ``mu`` at every speed and every load; a patch of one part of the friction does not: refitted on
the slow samples alone it is another number than on the fast ones, or under the light load than under the heavy one.

``split_fits`` cuts the training recording's samples in two halves at the median of the joint's ``|qd|`` and, apart,
at the median of its nominal rigid-body torque ``|tau_rigid|`` (``DiagnosisContext.tau_rigid``: the load, without
the friction), fits the nominal model, the kept terms and the candidate again on each half alone, and reports each
half's ``mu`` with its standard error (the joint's weighted residual, counted with the filter's effective samples as
the selection's BIC counts them). A pair of halves agrees when both ``mu`` are at least ``SIGNIFICANCE`` standard
errors above zero and differ by at most ``AGREEMENT`` times. ``second_opinion.SecondOpinion`` names the candidate only
if both pairs agree; otherwise it is an unstable finding with the four halves' numbers, not missing physics.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from identification.diagnosis.design import WeightedDesign, solve_scaled

logger = logging.getLogger(__name__)

LOAD_KEY = "load_dependent_friction"
AGREEMENT = 1.5  # the two halves' mu may differ by at most this factor
SIGNIFICANCE = 3.0  # each half's mu must be at least this many standard errors above zero
SPLIT_ROUTE = "one mu on the slow and fast, light- and heavy-load halves of the training recording"
#: What to do about a candidate the halves refused: more motion gives the halves the same disagreement.
SPLIT_NEXT_STEP = (
    "its mu changes with speed or load, so more motion will not decide it: the joint's friction shape or a friction "
    "that changed between recordings is the likelier cause (identify names a friction drift between its recordings)"
)


@dataclass(frozen=True)
class HalfFit:
    """The candidate refitted on one half of the training samples: its ``mu`` and standard error, the joint's training
    RMSE [N m] on the half without and with it, and why the half's pair does not agree (None when it does)."""

    name: str
    mu: float
    error: float
    rmse_before: float
    rmse_after: float
    failure: str | None = None


def halves(ctx, joint: int) -> list:
    """``[(name, rows), ...]``: the samples at or below and above the median of ``joint``'s ``|qd|``, then of its
    nominal rigid-body torque ``|tau_rigid|``, each pair in that order."""
    out = []
    for low, high, symbol, values, unit in (
        ("slow", "fast", "qd", np.abs(ctx.qd[:, joint]), "rad/s"),
        ("light-load", "heavy-load", "tau_rigid", np.abs(ctx.tau_rigid[:, joint]), "N m"),
    ):
        median = float(np.median(values))
        out.append((f"{low} half (|{symbol}| <= {median:.3g} {unit})", np.flatnonzero(values <= median)))
        out.append((f"{high} half (|{symbol}| > {median:.3g} {unit})", np.flatnonzero(values > median)))
    return out


def half_fit(design, ct, rows, joint: int, inflation: float) -> tuple:
    """``(mu, standard error, rmse before, rmse after)`` of the candidate columns ``ct`` (one column) fitted with the
    base of ``design`` (the nominal model and the kept terms) on the training ``rows`` alone. The standard error is
    the joint's weighted residual variance times the inverse normal matrix's entry, times ``inflation`` (samples per
    independent sample of the filtered signal)."""
    base, y, sigma = design.base_train.take(rows), design.y_train[rows], design.sigma
    fold = WeightedDesign(base, base, y, y, sigma)
    before = fold.fit(full=True)[2][joint]
    c = ct[rows]
    beta, _, after, _, _, _ = fold.fit(c, c, full=True)
    cross, cc, _ = fold.cross(c / sigma[None, :, None])
    gram = np.block([[fold.G, cross], [cross.T, cc]])
    unit = np.zeros(gram.shape[0])
    unit[-1] = 1.0
    variance = float(solve_scaled(gram, unit)[-1]) * (after[joint] / sigma[joint]) ** 2 * inflation
    return float(beta[-1]), float(np.sqrt(max(variance, 0.0))), float(before), float(after[joint])


def split_fits(design, term, ctx, inflation: float) -> tuple:
    """The four ``HalfFit`` of a load-dependent friction ``term`` on the training recording ``ctx`` (module
    docstring), each pair's failure on its second half; () for any other term."""
    if getattr(term, "key", None) != LOAD_KEY or term.joint is None:
        return ()
    j = int(term.joint)
    ct = term.columns(ctx)
    fits = [(name, *half_fit(design, ct, rows, j, inflation)) for name, rows in halves(ctx, j)]
    out = []
    for first, second in (fits[0:2], fits[2:4]):
        out += [HalfFit(*first), HalfFit(*second, failure=_disagreement(first, second))]
    numbers = "; ".join(f"{f.name}: mu = {f.mu:.3g} +/- {f.error:.2g}" for f in out)
    logger.info(f"diagnose:   {term.label} on the halves of the training recording: {numbers}")
    return tuple(out)


def _disagreement(first, second) -> str | None:
    """Why the two halves' ``mu`` are not one coefficient (module docstring), or None."""
    for name, mu, error, _, _ in (first, second):
        if not (mu > 0.0 and mu >= SIGNIFICANCE * error):
            return (
                f"mu = {mu:.3g} +/- {error:.2g} on the {_half(name)}: not {SIGNIFICANCE:g} standard errors above zero"
            )
    ratio = max(first[1], second[1]) / min(first[1], second[1])
    if ratio > AGREEMENT:
        return (
            f"mu = {first[1]:.3g} on the {_half(first[0])} against {second[1]:.3g} on the {_half(second[0])}: "
            f"{ratio:.2g} times, more than {AGREEMENT:g}"
        )
    return None


def _half(name: str) -> str:
    """A half's name without its threshold ("slow half")."""
    return name.split(" (")[0]
