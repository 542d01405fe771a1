"""The friction shapes' scale search is computed once per recording and gives what the straightforward search gives:
the grid columns equal each scale's own columns, the chosen scale equals the one of scoring each scale's freshly built
columns, the rival's cached columns equal uncached ones, and the cached filter design equals scipy's."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from identification.data.preprocessing import lowpass_sections, zero_phase_filter
from identification.diagnosis.candidates.friction import SCALE_GRIDS, FrictionShapeTerm, PreslidingTerm
from identification.diagnosis.context import lugre_parameters, simulate_friction
from identification.diagnosis.friction_rival import shape_column
from tests.identification.diagnosis_data import sine_context

JOINT = 3


@pytest.fixture(scope="module")
def context(denso, denso_model):
    return sine_context(denso, denso_model, seed=5)


def _terms():
    return [FrictionShapeTerm(joint=JOINT, shape="stribeck"), FrictionShapeTerm(joint=JOINT, shape="smooth_coulomb"),
            PreslidingTerm(joint=JOINT)]  # fmt: skip


class _Score:
    """An independent score: the SSE of the joint's measured torque fitted by a constant, the joint's velocity and the
    candidate column (plain least squares on every other row)."""

    def __init__(self, ctx):
        self.ctx, self.rows = ctx, np.arange(0, ctx.n_samples, 2)

    def __call__(self, joint, values):
        a = np.column_stack([np.ones(self.rows.size), self.ctx.qd[self.rows, joint], values])
        y = self.ctx.tau[self.rows, joint]
        return float(np.sum((y - a @ np.linalg.lstsq(a, y, rcond=None)[0]) ** 2))


def _straightforward_scale(term, ctx, score) -> float:
    """The scale search as written before the grid was cached: each grid value's columns built afresh, scored, the
    best three refined by a parabola in log scale."""
    grid = SCALE_GRIDS[term.shape]
    sse = np.array([score(JOINT, term._scaled(s).columns(ctx)[score.rows, JOINT, 0]) for s in grid])
    i = int(np.clip(np.argmin(sse), 1, grid.size - 2))
    x, y = np.log(grid[i - 1 : i + 2]), sse[i - 1 : i + 2]
    curvature = y[0] - 2 * y[1] + y[2]
    best = grid[int(np.argmin(sse))]
    if curvature > 0:
        best = float(np.exp(x[1] + np.clip(0.5 * (y[0] - y[2]) / curvature, -1, 1) * (x[2] - x[1])))
    return float(best)


@pytest.mark.parametrize("index", [0, 1, 2])
def test_the_cached_grid_gives_each_scales_columns_and_the_same_chosen_scale(context, index):
    term = _terms()[index]
    grid = term.grid_columns(context)
    assert term.grid_columns(context) is grid  # once per recording
    for k, scale in enumerate(SCALE_GRIDS[term.shape]):
        np.testing.assert_array_equal(grid[:, k], term._scaled(scale).columns(context)[:, JOINT, 0])
    score = _Score(context)
    (chosen,) = term.shape_variants(context, score)
    assert chosen.scale == _straightforward_scale(term, context, score)


@pytest.mark.parametrize("shape, scale", [("stribeck", 0.05), ("smooth_coulomb", 0.2), ("presliding", 1e-3)])
def test_the_rivals_cached_column_equals_an_uncached_one(context, shape, scale):
    column = shape_column(context, JOINT, shape, scale)
    assert shape_column(context, JOINT, shape, scale) is column
    fields = ("full_qd", "full_t", "keep", "filtered_friction", "lowpass", "n_samples", "n_dof")
    plain = SimpleNamespace(**{name: getattr(context, name) for name in fields})  # not cached
    np.testing.assert_array_equal(column, shape_column(plain, JOINT, shape, scale))


@pytest.mark.parametrize("order", [8, 5, 2])
def test_the_cached_filter_design_and_zero_phase_filter_are_scipys(rng, order):
    x = rng.standard_normal((500, 2))
    sos = butter(order, 15.0, btype="low", fs=1000.0, output="sos")
    np.testing.assert_array_equal(lowpass_sections(order, 15.0, 1000.0), sos)
    expected = np.column_stack([sosfiltfilt(sos, x[:, c]) for c in range(2)])
    np.testing.assert_array_equal(zero_phase_filter(x, 1000.0, 15.0, order), expected)
    np.testing.assert_array_equal(zero_phase_filter(x, 1000.0, 15.0, order), expected)  # from the cache
    np.testing.assert_array_equal(zero_phase_filter(x[:, 1], 1000.0, 15.0, order), expected[:, 1])


def test_the_friction_shift_with_the_recorded_friction_cached_is_the_two_simulations(context):
    # the deflection terms' friction change: the recorded velocity's LuGre friction (simulated once per recording)
    # minus the shifted velocity's, both simulated here afresh
    p = lugre_parameters(context.drives[JOINT])
    qd = context.full_qd[:, JOINT]
    for rate in (0.01 * np.sin(context.full_t), 0.02 * np.cos(3 * context.full_t)):
        direct = simulate_friction(p, context.full_t, qd) - simulate_friction(p, context.full_t, qd - rate)
        np.testing.assert_array_equal(context.friction_shift(JOINT, rate), context.lowpass(direct))
