"""Long recordings in the diagnosis (issue 17): chunked least squares, per-joint columns, bounded grid, chunked LuGre.

Each path that a long recording takes is checked against the one a short recording takes (one chunk, one
LuGre call, the whole dense array): the same numbers to rounding.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from identification.data.preprocessing import PreprocessOptions, central_difference, preprocess, zero_phase_filter
from identification.diagnosis import DiagnosisOptions, SpringTerm, TorqueOffsetTerm, diagnose
from identification.diagnosis import columns as columns_module
from identification.diagnosis.columns import BlockColumns, row_chunks
from identification.diagnosis.context import build_context, lugre_parameters, simulate_friction
from identification.diagnosis.nominal import friction_blocks, friction_columns, friction_shapes
from identification.diagnosis.selection import forward_select
from identification.friction import simulation as simulation_module
from identification.virtual import effects as xp
from psdm_casadi.errors import ParameterError, ShapeError
from tests.identification.diagnosis_data import recording_pair


@pytest.fixture(scope="module")
def pair(request):
    denso = request.getfixturevalue("denso")
    return recording_pair(denso, [xp.Spring(joint=1, stiffness=35.0, q0=0.15)], seed=1, train_s=8.0, val_s=4.0)


@pytest.fixture(scope="module")
def contexts(request, pair):
    denso, model = request.getfixturevalue("denso"), request.getfixturevalue("denso_model")
    pre = PreprocessOptions(cutoff_hz=15.0)
    return tuple(build_context(denso, model, preprocess(r, pre), raw=r) for r in pair)


def test_block_columns_round_trip_and_products(rng):
    dense = np.zeros((50, 3, 5))
    dense[:, 0, [0, 3]] = rng.normal(size=(50, 2))
    dense[:, 1, :] = rng.normal(size=(50, 5))
    dense[:, 2, 4] = rng.normal(size=50)
    blocks = BlockColumns.from_dense(dense)
    assert [i.tolist() for i in blocks.index] == [[0, 3], [0, 1, 2, 3, 4], [4]]
    assert blocks.shape == (50, 3, 5)
    np.testing.assert_array_equal(blocks.dense(), dense)
    np.testing.assert_array_equal(blocks.dense(slice(10, 20)), dense[10:20])
    np.testing.assert_array_equal(blocks.joint(1, slice(5, 9), 2.0), dense[5:9, 1, :] / 2.0)
    beta = rng.normal(size=5)
    np.testing.assert_allclose(blocks.predict(beta), dense @ beta, rtol=1e-14, atol=1e-14)
    both = blocks.concatenate(BlockColumns.from_dense(dense[:, :, :2]))
    np.testing.assert_array_equal(both.dense(), np.concatenate([dense, dense[:, :, :2]], axis=2))
    scale = np.array([0.5, 2.0, 3.0])
    weighted = (dense / scale[None, :, None]).reshape(-1, 5)
    r = blocks.weighted_r(scale)
    np.testing.assert_allclose(r.T @ r, weighted.T @ weighted, rtol=1e-12, atol=1e-12)
    with pytest.raises(ShapeError, match="BlockColumns.values"):
        BlockColumns(5, (np.array([0]),), (np.zeros((4, 2)),))
    with pytest.raises(ShapeError, match="BlockColumns.concatenate"):
        blocks.concatenate(BlockColumns.from_dense(dense[:10]))


def test_row_chunks_cover_the_rows_in_order():
    assert row_chunks(7, 3) == [slice(0, 3), slice(3, 6), slice(6, 7)]
    assert row_chunks(5, 10) == [slice(0, 5)]


def test_filtering_and_differences_one_column_at_a_time_give_the_whole_arrays_values(rng):
    """``zero_phase_filter`` and ``central_difference`` work column by column (a one-column temporary): the values
    are exactly those of the whole array."""
    x = rng.normal(size=(3000, 2, 3)).cumsum(axis=0)
    sos = butter(8, 15.0, btype="low", fs=1000.0, output="sos")
    np.testing.assert_array_equal(zero_phase_filter(x, 1000.0, 15.0), sosfiltfilt(sos, x, axis=0))
    t = np.cumsum(rng.uniform(0.5, 1.5, 3000)) * 1e-3
    first, second = central_difference(t, x)
    np.testing.assert_array_equal(first, np.gradient(x, t, axis=0, edge_order=2))
    for c in range(3):
        one = central_difference(t, x[:, 1, c])
        np.testing.assert_array_equal(first[:, 1, c], one[0])
        np.testing.assert_array_equal(second[:, 1, c], one[1])


def test_chunked_lugre_simulation_matches_one_call(denso, contexts, monkeypatch):
    ctx = contexts[0]
    p = lugre_parameters(denso.drives[2])
    whole = simulate_friction(p, ctx.full_t, ctx.full_qd[:, 2])
    monkeypatch.setattr(simulation_module, "LUGRE_CHUNK", 997)  # the simulator's own pieces (simulate_lugre)
    chunked = simulate_friction(p, ctx.full_t, ctx.full_qd[:, 2])
    assert ctx.full_t.size > 3 * 997
    np.testing.assert_allclose(chunked, whole, rtol=1e-12, atol=1e-12 * np.max(np.abs(whole)))


def test_friction_blocks_are_the_dense_filtered_columns(denso, contexts):
    """Built joint by joint, the friction columns equal the dense full-rate columns filtered and decimated."""
    ctx = contexts[0]
    vs, dv = friction_shapes(denso)
    dense = friction_columns("lugre", ctx.full_qd, vs, dv, sign=np.sign(ctx.full_qd))
    blocks = friction_blocks(denso, "lugre", ctx)
    assert blocks.n_columns == dense.shape[2] + denso.n_dof  # and one bristle-dynamics column per joint
    np.testing.assert_array_equal(blocks.dense()[:, :, : dense.shape[2]], ctx.lowpass(dense))
    assert all(i.size == 4 for i in blocks.index)


def test_chunked_selection_matches_one_chunk(denso, contexts, monkeypatch):
    """The forward selection summed over chunks of rows keeps the same terms with the same coefficients."""
    ctx_t, ctx_v = contexts
    instances = (SpringTerm() + TorqueOffsetTerm()).expand(denso.n_dof)
    base_t, base_v = friction_blocks(denso, "lugre", ctx_t), friction_blocks(denso, "lugre", ctx_v)
    y_t, y_v = ctx_t.tau - ctx_t.tau_rigid, ctx_v.tau - ctx_v.tau_rigid
    whole = forward_select(instances, ctx_t, ctx_v, base_t, base_v, y_t, y_v)
    monkeypatch.setattr(columns_module, "CHUNK_ROWS", 97)
    assert len(row_chunks(ctx_t.n_samples)) > 5
    chunked = forward_select(instances, ctx_t, ctx_v, base_t.dense(), base_v.dense(), y_t, y_v)
    assert [s.term.label for s in chunked.steps] == [s.term.label for s in whole.steps] == ["spring[j2]"]
    for a, b in zip(chunked.coefficients, whole.coefficients):
        np.testing.assert_allclose(a, b, rtol=1e-9)
    np.testing.assert_allclose(chunked.prediction_validation, whole.prediction_validation, rtol=1e-9, atol=1e-9)


def test_max_samples_bounds_the_grid_and_the_finding_stays(denso, denso_model, pair, caplog):
    train, val = pair
    ctx = build_context(denso, denso_model, preprocess(train, PreprocessOptions()), max_samples=1200)
    assert ctx.n_samples <= 1200 and ctx.keep[1] - ctx.keep[0] == 7  # 8000 samples in steps of 7 ms
    lib = SpringTerm() + TorqueOffsetTerm()
    with caplog.at_level("INFO", logger="identification.diagnosis.context"):
        options = DiagnosisOptions(library=lib, max_samples=1200, cutoff_hz=15.0, rate_hz=200.0, samples="diagnosis")
        report = diagnose(denso, train, val, options, model=denso_model)  # 1600 samples on the 200 Hz grid
    assert "on a 143 Hz grid" in caplog.text
    assert report.findings[0].effect == "spring" and report.findings[0].joints == (1,)
    assert report.findings[0].parameters["k"] == pytest.approx(35.0, rel=0.1)
    with caplog.at_level("WARNING", logger="identification.diagnosis.context"):
        build_context(denso, denso_model, preprocess(train, PreprocessOptions()), cutoff_hz=15.0, max_samples=400)
    assert "fewer than 4 samples per period" in caplog.text


def test_max_samples_error_names_the_field(denso, denso_model, pair):
    with pytest.raises(ParameterError, match="DiagnosisOptions.max_samples"):
        DiagnosisOptions(max_samples=10)
    with pytest.raises(ParameterError, match="DiagnosisOptions.max_samples"):
        DiagnosisOptions(max_samples=2.5e5)
    with pytest.raises(ParameterError, match="max_samples"):
        build_context(denso, denso_model, preprocess(pair[0], PreprocessOptions()), max_samples=0)
