"""Naming a torque of the angle: a ripple (periodic in the angle) is named only when the recording can show it.

Over a joint travel that covers a small part of a ripple's period, a low-harmonic ripple, a spring's polynomial and a
gas spring's lever law fit the same smooth torque; the selection then names the family whose claim the data support
(``CandidateTerm.name_unsupported``, ``selection._backed_name``). Synthetic one-joint problems with a known truth:
the torque is a gas-spring lever law over 0.46 rad (as on a heavy arm's shoulder), or a true ripple over two of its
periods."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.diagnosis.candidates import SpringTerm, TorqueRippleTerm
from identification.diagnosis.candidates.gas_spring import lever_columns
from identification.diagnosis.candidates.torque import MIN_PERIODS
from identification.diagnosis.selection import forward_select

NOISE = 0.5  # [N m]


def _context(seed: int, travel: float, centre: float = 0.3, n: int = 2000):
    """One joint moving as a sum of three sines over exactly ``travel`` [rad] about ``centre`` for 10 s (what the
    spring and ripple terms read: the angle; the torque is set by ``_problem``)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 10.0, n)
    x = np.sin(np.outer(t, 2.0 * np.pi * rng.uniform(0.1, 0.6, 3)) + rng.uniform(0.0, 2.0 * np.pi, 3)).sum(axis=1)
    q = centre + travel * (x - x.min()) / (x.max() - x.min()) - 0.5 * travel
    return SimpleNamespace(t=t, q=q[:, None], qd=np.gradient(q, t)[:, None], n_samples=n, n_dof=1)


def _select(truth, travel: float, seed: int = 0):
    """Forward selection among springs and ripples on a training and a validation recording whose residual is
    ``truth(q)`` plus noise, over a nominal model of viscous and Coulomb friction."""
    data = []
    for k in range(2):
        ctx = _context(10 * seed + k, travel)
        q = ctx.q[:, 0]
        y = truth(q) + NOISE * np.random.default_rng(seed + 5 + k).standard_normal(q.size)
        ctx.tau = (y + 20.0 * np.std(truth(q)) * np.sin(ctx.t))[:, None]  # the joint's torque, 20 x the effect
        data.append((ctx, np.stack([ctx.qd, np.sign(ctx.qd)], axis=2), y[:, None]))
    (ct, bt, yt), (cv, bv, yv) = data
    return forward_select((SpringTerm() + TorqueRippleTerm()).expand(1), ct, cv, bt, bv, yt, yv, max_effects=2)


def test_periods_covered_is_the_travel_over_the_period():
    ctx = _context(0, travel=0.5)
    assert TorqueRippleTerm(joint=0, harmonic=4).periods_covered(ctx) == pytest.approx(0.5 * 4 / (2 * np.pi))
    assert "covers 0.16 of the ripple's period" in TorqueRippleTerm(joint=0, harmonic=2).name_unsupported(ctx)
    assert TorqueRippleTerm(joint=0, harmonic=16).name_unsupported(ctx) is None  # 1.27 periods
    assert MIN_PERIODS == 1.0 and SpringTerm(joint=0).name_unsupported(ctx) is None


def test_a_gas_spring_over_a_short_travel_is_named_a_spring_not_a_ripple():
    """A ripple of harmonic 2 fits this lever law over 0.15 of its period with fewer coefficients than the spring
    family; the spring family fits it at least as well, and only it makes no claim the travel cannot back."""

    def gas(q):
        return lever_columns(q, 0.45, 0.3 - 0.23 - 0.15) @ np.array([300.0, 50.0])

    result = _select(gas, travel=0.46)
    assert [s.term.interpret(c)[0] for s, c in zip(result.steps, result.coefficients)] == ["spring"]
    assert "named rather than torque_ripple[j1,h=2]" in result.steps[0].shape_note
    assert "too little to show a periodic torque" in result.steps[0].shape_note
    assert result.steps[0].rmse_after[0] < 1.1 * NOISE  # the lever law's torque captured down to the noise


def test_a_ripple_over_two_of_its_periods_is_still_named():
    result = _select(lambda q: 30.0 * np.sin(8.0 * q + 1.0), travel=1.5)  # 1.9 periods of harmonic 8
    assert [s.term.label for s in result.steps] == ["torque_ripple[j1,h=8]"]
    assert result.steps[0].shape_note == ""
    amplitude = np.hypot(*result.coefficients[0])
    assert amplitude == pytest.approx(30.0, rel=0.02)
