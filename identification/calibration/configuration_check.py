"""Mixed configurations said nowhere: a recording that carries a load the others do not, found by its residual.

When loaded and unloaded recordings are fitted as one arm, the arm's parameters absorb the load and no
residual looks wrong on its own. The test gives each recording in turn a body of its own at the flange
(the columns of ``payload_fit.FlangeRegressor`` on its samples only), refits everything jointly, and
compares: a recording whose weighted residual drops by much more than its noise allows, with a flange
mass many standard deviations from zero, is named with the mass it appears to carry and the fix (say
its payload in a sidecar or a configuration manifest). Residual correlation (filtered data) is allowed
for by the correlation time of the fit (``trajectory_fit``); the thresholds are deliberately strict,
since a body at the flange also soaks up other differences between recordings (friction drift).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from identification.calibration.payload_fit import BODY, Estimable, FlangeRegressor
from identification.calibration.trajectory_data import NormalEquations

__all__ = [
    "LoadedRecording",
    "MIN_DROP",
    "MIN_Z",
    "P_VALUE",
    "accumulate",
    "loaded_recordings",
    "unstated_payload_warnings",
]

P_VALUE = 1e-6  # the residual drop must be this unlikely under the recording's noise (chi-square, correlation-scaled)
MIN_DROP = 0.05  # and at least this fraction of the recording's own weighted residual
MIN_Z = 5.0  # and its flange mass this many standard deviations from zero


@dataclass(frozen=True)
class LoadedRecording:
    """A recording that looks loaded (or lighter) at the flange against the others of its fit."""

    name: str
    mass: float  # [kg] the flange mass it appears to carry beyond the others (negative: lighter)
    mass_std: float
    residual_drop: float  # fraction of its own weighted residual the flange body removes


class _Probe:
    """The extra columns of one recording followed by a flange body's (the probe)."""

    def __init__(self, extra, flange):
        self.extra, self.flange = extra, flange

    def columns(self, q, qd, qdd) -> np.ndarray:
        own = self.flange(q, qd, qdd)
        return own if self.extra is None else np.concatenate([self.extra.columns(q, qd, qdd), own], axis=2)


def _solve(gram, moment):
    scale = np.sqrt(np.clip(np.diag(gram), 1e-300, None))
    inverse = np.linalg.pinv(gram / np.outer(scale, scale), rcond=1e-12, hermitian=True) / np.outer(scale, scale)
    return inverse @ moment, inverse


def accumulate(robot, model, prepared, extras, setup, n_columns: int, probes=None) -> tuple:
    """(summed normal equations of ``n_columns``, per recording its own with a flange probe's 10 columns last, or
    None): the fit's one pass over the recordings. ``probes`` (one entry per recording, None for those to test;
    None: no probe) asks for the per-recording equations; ``setup`` is ``(friction terms, drive-inertia joints,
    coulomb velocity, vs, viscous exponents)`` and ``extras`` the recordings' extra-column objects."""
    terms, inertia_joints, coulomb_velocity, vs, dv = setup
    probes = probes if probes is not None and len(prepared) > 1 and None in probes else None  # one recording: none
    flange = None if probes is None else FlangeRegressor(robot)
    total, own = NormalEquations(robot.n_dof, n_columns), []
    for ready, extra, probe in zip(prepared, extras, probes if probes is not None else [0] * len(prepared)):
        if flange is None or probe is not None:
            total.add_recording(model, ready, terms, inertia_joints, coulomb_velocity, extra, vs, dv)
            continue
        equations = NormalEquations(robot.n_dof, n_columns + BODY)
        equations.add_recording(model, ready, terms, inertia_joints, coulomb_velocity, _Probe(extra, flange), vs, dv)
        own.append((ready.name, equations))
        shared = equations.subset(range(n_columns))
        total.gram += shared.gram
        total.moment += shared.moment
        total.energy += shared.energy
        total.count += shared.count
        total.total += shared.total
    return total, (own if flange is not None else None)


def loaded_recordings(own, n_shared: int, equations, sigma, correlation) -> list:
    """The :class:`LoadedRecording` of every probed recording whose flange body passes the three thresholds.

    ``own`` are the (name, normal equations) of :func:`accumulate` (the probe's columns last); ``equations`` the
    fit's summed normal equations of its first ``n_shared`` columns, ``sigma`` its per-joint residual sigma and
    ``correlation`` the per-joint correlation time.
    """
    weights = 1.0 / np.asarray(sigma, dtype=float) ** 2
    gram, moment, _ = equations.weighted(weights)
    n = gram.shape[0]
    x0, _ = _solve(gram, moment)
    tau = float(np.mean(correlation))
    out = []
    for name, full in own:
        probed = full.subset([*range(n_shared), *range(full.n_columns - BODY, full.n_columns)])
        g, m, _ = probed.weighted(weights)
        augmented = g.copy()  # its own flange rows and columns, everyone's rows of the shared columns
        augmented[:n, :n] = gram
        moment_aug = np.concatenate([moment, m[n:]])
        x1, inverse = _solve(augmented, moment_aug)
        drop = float(moment_aug @ x1 - moment @ x0)  # weighted residual sum before minus after
        residual = float(weights @ probed.residual_sum(np.concatenate([x0, np.zeros(BODY)])))
        df = int(np.linalg.matrix_rank(g[n:, n:] / max(np.abs(g[n:, n:]).max(), 1e-300), tol=1e-9))
        if df == 0 or residual <= 0 or not Estimable(augmented).unit(n):
            continue
        mass, mass_std = float(x1[n]), float(np.sqrt(max(inverse[n, n], 0.0) * tau))
        significant = drop / tau > chi2.isf(P_VALUE, df) and drop > MIN_DROP * residual
        if significant and abs(mass) > MIN_Z * mass_std:
            out.append(LoadedRecording(name, mass, mass_std, drop / residual))
    return out


def unstated_payload_warnings(found) -> list:
    """One warning per recording that looks loaded, with the mass and the fix (lighter ones when none looks
    loaded: then the others carry the load)."""
    heavier = [f for f in found if f.mass > 0]
    out = []
    for f in heavier or found:
        name = f.name or "a recording"
        stem = name.rsplit(".", 1)[0] if "." in name else name
        amount = f"{abs(f.mass):.3g} +- {f.mass_std:.2g} kg"
        how = f"carries {amount} at the flange that the other recordings do not"
        if f.mass < 0:
            how = f"is {amount} lighter at the flange than the other recordings (they may carry a payload)"
        out.append(
            f"{name} looks as if it {how}: with a body of its own at the flange its residual drops "
            f"{100 * f.residual_drop:.0f} %. Loaded and unloaded recordings fitted as one arm bias its parameters. "
            f'If it carries a payload, say so: write {stem}.payload.json beside it ({{"mass": {abs(f.mass):.2g}, '
            f'"com": [x, y, z]}} if known, {{"unknown": "tool"}} if not), or list it in a configurations.toml '
            "(--data configurations.toml)."
        )
    return out
