"""The viscous power law of the column choice: the paper's ``fv |qd|^dv sign(qd)`` (eq. 14) where the data show it.

A harmonic drive or a heavy gearbox loses less than linearly with speed (``dv`` 0.6-0.75); a linear viscous column
fitted to such a drive on slow training motion misses badly on faster motion. The exponent is the one nonlinear
parameter: as the Stribeck velocity (``stribeck``), it is found first, per joint, by a 1-D fit on the training data, and
the column ``viscous_column`` (linear in ``fv`` once ``dv`` is fixed) is then a candidate the column choice judges like
any other (``column_choice``: the training BIC with one more parameter and the held-out verdict).

The 1-D fit holds the full model's base parameters and every other joint's columns at their least-squares values (every
joint's viscous column at its exponent so far: the two in turn, ``MAX_PASSES``; held at the linear model's, the base
parameters absorb part of the power law and bias the exponent towards 1) and refits only the joint's own drive columns
(Coulomb, static, offset, drive inertia, loss, and the viscous column at each trial ``dv``) to the torque they and the
residual leave: per joint a small least squares on a grid of exponents in ``EXPONENT_RANGE``, refined by a parabola
through the best three. The standard deviation of ``dv`` is that of the profile likelihood's curvature, with the joint's
effective sample count (samples over the residual's correlation time).

The column (``trajectory_data.viscous_column``) is smoothed below the Coulomb smoothing velocity, with a finite slope
at rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.column_verdict import Evidence, verdict
from identification.calibration.coulomb_width import joint_width
from identification.calibration.trajectory_data import drive_column_joint, viscous_column

__all__ = ["EXPONENT_RANGE", "EXPONENT_Z", "LINEAR", "ViscousExponents", "fit_viscous_exponents",
           "viscous_evidence", "viscous_exponents", "viscous_lines"]  # fmt: skip

#: The exponents tried [-]: from a strongly sublinear drive to linear viscous friction.
EXPONENT_RANGE = (0.3, 1.0)
GRID_POINTS = 71
#: An exponent this close to 1 is linear viscous friction: no candidate.
LINEAR = 0.99
#: The held-out RMS gain a kept power law must bring on its joint: on linear truth the low-pass filter's smearing of
#: the Coulomb step makes a slightly sublinear law (0.90-0.94) fit a little better, its standard deviation too small
#: for that systematic error (the Denso, Coulomb-viscous: BIC +52, held-out 3 % lower; a true 0.7: 18 %).
MIN_GAIN = 0.05
#: Standard deviations by which a kept exponent must lie below 1 (as a Stribeck hump above the Coulomb level).
EXPONENT_Z = 2.0
#: Passes of the exponents and the full model's other parameters in turn, until no exponent moves by the tolerance.
MAX_PASSES, PASS_TOLERANCE = 5, 0.005
#: The 1-D fit's samples: those faster than this share of the joint's top training speed. Near rest the Coulomb step
#: and the low-pass filter's smearing of it dominate, and a sublinear law there trades against the Coulomb and Stribeck
#: columns (the Denso's joint 3 with a true 0.7: 0.85 +- 0.014 on every sample, 0.73 +- 0.017 above 40 %).
FAST_SHARE = 0.4
#: Drive columns of a joint the 1-D fit refits with its viscous column (payload columns are the arm's, held).
OWN_TERMS = ("fc", "fs", "fv", "offset", "Ia", "loss")


@dataclass(frozen=True)
class ViscousExponents:
    """The exponent ``dv`` per joint found on the training data and its standard deviation (1 and 0: linear)."""

    value: tuple
    std: tuple

    def candidates(self) -> tuple:
        """The joints (0-based) whose exponent departs from linear inside the range tried: a power-law column is a
        candidate there (an exponent at the range's lower end is no minimum the data show: the viscous column then
        takes a Coulomb-like step, the TX40's joint 6 at 0.3 +- 0.29, validated 6 % worse)."""
        return tuple(j for j, dv in enumerate(self.value) if EXPONENT_RANGE[0] < dv < LINEAR)


def fit_viscous_exponents(fitted, names, n_base: int, coulomb_velocity, weights, effective) -> ViscousExponents:
    """The viscous exponent of each joint (module docstring).

    Parameters
    ----------
    fitted : sequence of (columns, tau)
        Per prepared training recording its full candidate columns (n_samples, n_dof, n_columns) and torque.
    names : sequence of str
        The columns' names after the ``n_base`` base parameters (``column_candidates``).
    coulomb_velocity : float
        The Coulomb smoothing velocity [rad/s] (the power column's smoothing).
    weights, effective : array
        Per joint, the weight ``1 / sigma^2`` of the full model and the effective sample count (samples over the
        residual's correlation time).
    """
    n_dof = fitted[0][1].shape[1]
    viscous = [n_base + list(names).index(f"fv{j + 1}") for j in range(n_dof)]
    exponents = ViscousExponents((1.0,) * n_dof, (0.0,) * n_dof)
    for _ in range(MAX_PASSES):  # the joint exponents and the full model's other parameters in turn
        x = _full_estimate(fitted, viscous, exponents.value, coulomb_velocity, weights)
        found = [_joint_exponent(fitted, names, n_base, j, x, coulomb_velocity, effective[j]) for j in range(n_dof)]
        change = max(abs(a[0] - b) for a, b in zip(found, exponents.value))
        exponents = ViscousExponents(tuple(f[0] for f in found), tuple(f[1] for f in found))
        if change < PASS_TOLERANCE:
            break
    return exponents


def _full_estimate(fitted, viscous, exponent, coulomb_velocity, weights) -> np.ndarray:
    """The weighted least squares of every candidate column with each joint's viscous column at its ``exponent``."""
    gram, moment = 0.0, 0.0
    for columns, tau in fitted:
        columns = columns.copy()
        for j, k in enumerate(viscous):
            columns[:, j, k] = viscous_column(columns[:, j, k], exponent[j], joint_width(coulomb_velocity, j))
        measured = np.isfinite(tau)
        tau = np.where(measured, tau, 0.0)
        columns = columns * (measured * np.sqrt(weights))[:, :, None]
        gram = gram + np.einsum("snc,snd->cd", columns, columns)
        moment = moment + np.einsum("snc,sn->c", columns, tau * np.sqrt(weights))
    scale = np.sqrt(np.clip(np.diag(gram), 1e-300, None))
    inverse = np.linalg.pinv(gram / np.outer(scale, scale), rcond=1e-12, hermitian=True) / np.outer(scale, scale)
    return inverse @ moment


def _joint_exponent(fitted, names, n_base: int, j: int, x, coulomb_velocity, effective: float) -> tuple:
    """(exponent, standard deviation) of joint ``j`` with the others' parameters held at ``x`` (module docstring)."""
    own = [n_base + k for k, name in enumerate(names) if name.startswith(OWN_TERMS) and drive_column_joint(name) == j]
    viscous = n_base + list(names).index(f"fv{j + 1}")
    columns = np.concatenate([c[:, j, :] for c, _ in fitted])
    target = np.concatenate([t[:, j] for _, t in fitted])
    measured = np.isfinite(target)
    columns, target = columns[measured], target[measured]
    others = [k for k in range(columns.shape[1]) if k not in own]
    target = target - columns[:, others] @ x[others]
    qd, rest = columns[:, viscous], columns[:, [k for k in own if k != viscous]]  # the linear column is the velocity
    fast = np.abs(qd) > FAST_SHARE * np.abs(qd).max()  # where the viscous law, not the Coulomb step, shows
    qd, rest, target, effective = qd[fast], rest[fast], target[fast], effective * fast.mean()

    def rss(dv):
        design = np.column_stack([rest, viscous_column(qd, dv, joint_width(coulomb_velocity, j))])
        estimate = np.linalg.lstsq(design, target, rcond=None)[0]
        return float(np.sum((target - design @ estimate) ** 2))

    grid = np.linspace(*EXPONENT_RANGE, GRID_POINTS)
    curve = np.array([rss(dv) for dv in grid])
    best = int(np.argmin(curve))
    if best == grid.size - 1 or not np.isfinite(curve[best]) or curve[best] <= 0:
        return 1.0, 0.0
    step, dv = grid[1] - grid[0], float(grid[best])
    if best > 0:  # the parabola's vertex through the best three points
        a, b, c = curve[best - 1 : best + 2]
        bend = a - 2 * b + c
        dv = dv + (0.5 * (a - c) / bend * step if bend > 0 else 0.0)
    profile = [effective * np.log(rss(v)) for v in (dv - step, dv, dv + step)]
    curvature = (profile[0] - 2 * profile[1] + profile[2]) / step**2
    spread = float(np.sqrt(2.0 / curvature)) if curvature > 0 else EXPONENT_RANGE[1] - EXPONENT_RANGE[0]
    return float(min(dv, 1.0)), spread


def viscous_evidence(found, stribeck) -> list:
    """Per joint, its power-law viscous column (``Candidates`` column ``fp<j>``) against the linear one, every other
    joint linear and every other candidate column in: one ``Evidence`` (``term`` ``"viscous"``, ``estimate`` the
    exponent) each, kept by the verdict every column gets (``column_verdict.verdict``) and only where the exponent is
    below 1 by ``EXPONENT_Z`` standard deviations (a linear drive's exponent scatters about 1)."""
    exponents = found.exponents
    if exponents is None:
        return []
    train, held, _, _ = found.evaluate(stribeck)
    out = []
    for j, (dv, std) in enumerate(zip(exponents.value, exponents.std)):
        if j not in exponents.candidates():  # the training data's best exponent is 1: linear, no candidate
            continue
        full, sub = (stribeck, (f"fv{j + 1}",)), (stribeck, ())
        train_p, held_p, _, _ = found.evaluate(*full)
        n = found.effective[j]
        delta = float(n * np.log(train[j] / train_p[j]) - np.log(n))  # one more parameter: the exponent
        ratio = float(held_p[j] / held[j])
        kept, reason = verdict(found, full, sub, j, delta, ratio)
        below = bool(dv + EXPONENT_Z * std < 1.0)
        if kept and not below:
            kept, reason = False, (f"the exponent {dv:.3g} +- {std:.2g} is not below 1 by {EXPONENT_Z:g} standard "
                                   "deviations: linear viscous friction within the data's scatter")  # fmt: skip
        elif kept and 1.0 - np.sqrt(ratio) < MIN_GAIN:
            below, kept, reason = False, False, (
                f"the exponent {dv:.3g} lowers the held-out RMS error by {1.0 - np.sqrt(ratio):.0%}, less than the "
                f"{MIN_GAIN:.0%} asked of a power law: a slightly sublinear fit of linear friction")  # fmt: skip
        departs = kept != (delta > 0 and ratio < 1 and below)  # the plain rule's verdict
        out.append(Evidence("viscous", j, delta, ratio, kept, reason, dv, std, departs))
    return out


def viscous_exponents(evidence, n_dof: int) -> tuple:
    """Per joint the exponent of a kept ``"viscous"`` ``evidence`` and 1 elsewhere; empty when every joint is linear."""
    kept = {e.joint: e.estimate for e in evidence if e.term == "viscous" and e.kept}
    return tuple(float(kept.get(j, 1.0)) for j in range(n_dof)) if kept else ()


def viscous_lines(exponent, evidence) -> list:
    """The choice's sentence for each joint whose viscous friction is the power law (``ColumnChoice.describe``)."""
    std = {e.joint: e.std for e in evidence if e.term == "viscous"}
    return [f"joint {j + 1}: viscous friction ~ |qd|^{dv:.2f} (dv = {dv:.3g} +- {std.get(j, 0.0):.2g}), chosen from "
            "the data" for j, dv in enumerate(exponent) if dv != 1.0]  # fmt: skip
