"""The counterbalance's odd law about its neutral angle, chosen by BIC (``candidates.counterbalance_law``, issue 25).

References: known synthetic torques over a shoulder's recorded range (-0.25 to 0.75 rad, a sine motion): an odd
quintic about a neutral angle, the virtual cam counterbalance (``CamCounterbalance``, odd about its ``q0``), a linear
spring and pure noise. The law must come back with the truth's neutral angle and coefficients where the data hold
it, and not be chosen where a linear spring or nothing is there.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.diagnosis.candidates import SpringTerm, counterbalance_law
from identification.diagnosis.candidates.neutral_angle import fit_neutral_angle, odd_columns
from identification.virtual import effects as xp

N_EFF = 160.0  # 8 s filtered at 10 Hz: 2 x cut-off x duration independent samples
LO, HI = -0.25, 0.75


def _angles(n=1600):
    t = np.linspace(0.0, 8.0, n)
    return 0.5 * (LO + HI) + 0.5 * (HI - LO) * np.sin(2 * np.pi * 0.35 * t + 0.3 * np.sin(2 * np.pi * 0.9 * t))


def _noise(q, std, seed=0):
    return np.random.default_rng(seed).normal(0.0, std, q.size)


def test_a_fifth_order_odd_torque_is_recovered_with_its_neutral_angle_and_coefficients():
    q = _angles()
    q0, k1, k3, k5, offset = 0.12, 14.0, -9.0, 6.0, 0.4
    x = q - q0
    torque = k1 * x + k3 * x**3 + k5 * x**5 + offset + _noise(q, 0.01)
    law = counterbalance_law(1, q, torque, N_EFF)
    assert law is not None and law.odd and law.order == 5 and law.label == "spring[j2,order=5,odd]"
    assert law.centre == pytest.approx(q0, abs=0.01)
    coefficients = np.linalg.lstsq(odd_columns(q, law.centre, 5), torque, rcond=None)[0]
    assert coefficients == pytest.approx([k1, k3, k5, offset], rel=0.05, abs=0.05)
    parameters = law.physical_parameters(coefficients)
    assert parameters["neutral_angle"] == law.centre and parameters["order"] == 5.0


def test_the_cam_counterbalance_is_taken_as_an_odd_law_about_its_rest_angle():
    """``12 sin(x) (1 + 0.3 cos 2x)``, ``x = q - 0.1``: the cubic leaves 0.02 N m of it, the odd quintic 0.0004."""
    q = _angles()
    cam = xp.CamCounterbalance(joint=0, amplitude=12.0, q0=0.1, lobe=0.3)
    truth = np.array([cam.torque(0.0, np.array([a]), None, None)[0] for a in q])
    torque = truth + _noise(q, 0.005, seed=1)
    law = counterbalance_law(0, q, torque, N_EFF)
    assert law is not None and law.order == 5 and law.centre == pytest.approx(0.1, abs=0.01)
    coefficients = np.linalg.lstsq(odd_columns(q, law.centre, 5), torque, rcond=None)[0]
    wide = np.linspace(LO - 0.25, HI, 200)  # beyond the recorded range by a quarter of it
    truth_wide = np.array([cam.torque(0.0, np.array([a]), None, None)[0] for a in wide])
    assert np.sqrt(np.mean((law.torque_of_angle(wide, coefficients) - truth_wide) ** 2)) < 0.05
    cubic = SpringTerm(joint=0, order=3, centre=0.5 * (LO + HI), q_range=(LO, HI))
    columns = np.column_stack([*(np.asarray(q) - cubic.centre) ** np.arange(1, 4)[:, None], np.ones_like(q)])
    residual = torque - columns @ np.linalg.lstsq(columns, torque, rcond=None)[0]
    assert np.sqrt(np.mean(residual**2)) > 0.01  # the cubic cannot hold it to the noise


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pure_noise_or_a_linear_spring_does_not_choose_the_higher_order(seed):
    q = _angles()
    assert counterbalance_law(1, q, _noise(q, 0.05, seed), N_EFF) is None
    assert counterbalance_law(1, q, 20.0 * (q - 0.3) + _noise(q, 0.05, seed), N_EFF) is None
    x = q - 0.25
    assert counterbalance_law(1, q, 3.0 * x - 2.0 * x**2 + 4.0 * x**3 + _noise(q, 0.05, seed), N_EFF) is None


def test_the_neutral_angle_search_finds_the_lowest_sse_within_reach():
    q = _angles()
    torque = 5.0 * (q - 0.6) ** 5 + 2.0 * (q - 0.6)
    angle, sse = fit_neutral_angle(q, lambda c: float(np.sum((torque - c @ np.linalg.lstsq(c, torque)[0]) ** 2)), 5)
    assert angle == pytest.approx(0.6, abs=1e-3) and sse < 1e-8
