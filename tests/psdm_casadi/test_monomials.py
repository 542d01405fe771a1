"""The regressor's fast evaluation (``monomials.MonomialTree`` in blocks, ``state_cache.StateCache``) against the
plain product it replaces, bit for bit; the cache's copies, budget and pickling."""

import pickle
from dataclasses import replace

import numpy as np
import pytest

from psdm_casadi import model as model_module
from psdm_casadi import monomials
from psdm_casadi.monomials import MonomialTree
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.state_cache import BlockMemory, StateCache, remembering


def plain_functions(exponents, gamma):
    """The straightforward product ``y = 1; for h: y *= gamma_h ** E[h]`` over every sample at once."""
    y = np.ones((gamma.shape[0], exponents.shape[1]))
    for h in range(gamma.shape[1]):
        for power in (1, 2):
            cols = exponents[h] == power
            if cols.any():
                y[:, cols] *= gamma[:, h : h + 1] ** power
    return y


def plain_regressor(model, q, qd, qdd):
    gamma = np.concatenate([q, np.sin(q), np.cos(q), qd, qdd], axis=1)
    y = plain_functions(model.exponents, gamma)
    y[:, model.gravity_functions] *= model.gravity_magnitude
    return np.asarray(model._reduction_sparse.T @ y.T).T.reshape(y.shape[0], model.n_dof, model.n_base)


def test_the_tree_gives_the_plain_product_bit_for_bit_on_a_random_table(monkeypatch):
    rng = np.random.default_rng(3)
    exponents = rng.choice([0, 0, 0, 1, 2], size=(15, 400)).astype(np.uint8)
    exponents[:, 7] = 0  # a constant function
    gamma = rng.normal(size=(301, 15))
    monkeypatch.setattr(monomials, "BLOCK_BYTES", 16 * 64 * 30)  # several blocks, the last one short
    tree = MonomialTree.of(exponents)
    assert tree.block_samples() < gamma.shape[0]
    assert np.array_equal(tree.evaluate_transposed(gamma), plain_functions(exponents, gamma).T)
    assert sum(p.size for p in tree.parents) < np.count_nonzero(exponents)  # shared prefixes multiplied once


def test_the_regressor_is_the_plain_products_bit_for_bit_and_the_robots_torque(denso, denso_model, monkeypatch):
    monkeypatch.setattr(model_module, "REGRESSOR_BLOCK", 37)  # blocks not dividing the series
    rng = np.random.default_rng(0)
    q = rng.uniform(denso.q_min, denso.q_max, size=(200, 6))
    qd, qdd = rng.normal(size=(2, 200, 6))
    fast = denso_model.regressor(q, qd, qdd)
    assert np.array_equal(fast, plain_regressor(denso_model, q, qd, qdd))
    plain = plain_functions(denso_model.exponents, np.concatenate([q, np.sin(q), np.cos(q), qd, qdd], axis=1))
    plain[:, denso_model.gravity_functions] *= denso_model.gravity_magnitude
    assert np.array_equal(denso_model.functions(q, qd, qdd), plain)
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    assert np.allclose(fast @ theta, PinocchioOracle(denso).rnea(q, qd, qdd), atol=1e-9)
    assert np.array_equal(denso_model.regressor(q[5], qd[5], qdd[5]), fast[5])  # one state


def test_a_series_evaluated_again_comes_from_memory_as_a_copy(denso_model):
    rng = np.random.default_rng(1)
    q, qd, qdd = rng.normal(size=(3, 100, 6))
    calls = []

    def compute(*arrays):
        calls.append(1)
        return denso_model._evaluate_regressor(*arrays)

    cache = StateCache()
    cache.get(compute, q, qd, qdd)
    cache.get(compute, q, qd, qdd)  # outside a remembering block nothing is kept
    assert len(calls) == 2 and not cache._entries
    with remembering():
        first = cache.get(compute, q, qd, qdd)
        first[:] = 0.0  # the caller's copy: the memory keeps the result
        with remembering():
            again = cache.get(compute, q, qd, qdd)
        assert len(calls) == 3 and np.array_equal(again, denso_model._evaluate_regressor(q, qd, qdd))
        q2 = q.copy()
        q2[50, 3] += 1e-12  # other states: evaluated
        cache.get(compute, q2, qd, qdd)
        assert len(calls) == 4
        cache.get(compute, q[:10], qd[:10], qdd[:10])  # short series are not kept
        cache.get(compute, q[:10], qd[:10], qdd[:10])
        assert len(calls) == 6 and len(cache._entries) == 2
    assert not cache._entries and cache._bytes == 0  # emptied when the outermost block ends


def test_the_memory_stays_within_its_budget_and_is_not_pickled(denso_model):
    rng = np.random.default_rng(2)
    size = denso_model._evaluate_regressor(*rng.normal(size=(3, 100, 6))).nbytes
    cache = StateCache(max_bytes=2 * size)
    series = [rng.normal(size=(3, 100, 6)) for _ in range(3)]
    with remembering():
        for states in series:
            cache.get(denso_model._evaluate_regressor, *states)
        assert cache._bytes <= 2 * size and len(cache._entries) == 2
        assert StateCache.key(*series[0]) not in cache._entries  # the least recently used went first
        denso_model.regressor(*series[1])
        copy = pickle.loads(pickle.dumps(denso_model))
    assert len(copy._regressor_cache._entries) == 0 and np.array_equal(
        copy.regressor(*series[1]), denso_model.regressor(*series[1])
    )


def test_a_block_memory_computes_a_key_once_in_a_block_and_forgets_it_after():
    """``BlockMemory`` (identify's LuGre trial fits): outside a block always computed; inside, once per key, the
    least recently used key first out beyond ``max_entries``; emptied when the outermost block ends."""
    calls = []

    def compute(value):
        calls.append(value)
        return (value,)

    memory = BlockMemory(max_entries=2)
    memory.get("a", lambda: compute(1))
    assert memory.get("a", lambda: compute(1)) == (1,) and len(calls) == 2  # no block: nothing kept
    with remembering():
        first = memory.get("a", lambda: compute(1))
        with remembering():
            assert memory.get("a", lambda: compute(2)) is first and len(calls) == 3  # the value kept, not 2
        memory.get("b", lambda: compute(3))
        memory.get("c", lambda: compute(4))  # over max_entries: "a" goes
        assert memory.get("a", lambda: compute(5)) == (5,) and len(calls) == 6
    with remembering():
        assert memory.get("b", lambda: compute(6)) == (6,)  # the outermost block's end emptied it


def test_a_block_memory_result_made_with_a_model_is_handed_out_for_an_equal_model_only(denso_model):
    """``BlockMemory.get_with`` (identify's trial fits, keyed without their derived model): the result made with a
    model is handed out again for that model and an equal copy of it (a fit of equal E, P and parameter map is the same
    fit); for another model it is computed anew, and the remembered result stays."""
    calls = []

    def compute(value):
        calls.append(value)
        return (value,)

    memory, other = BlockMemory(), replace(denso_model, gravity_magnitude=1.62)
    with remembering():
        first = memory.get_with("fit", denso_model, lambda: compute(1))
        assert memory.get_with("fit", denso_model, lambda: compute(2)) is first
        assert memory.get_with("fit", pickle.loads(pickle.dumps(denso_model)), lambda: compute(3)) is first
        assert memory.get_with("fit", other, lambda: compute(4)) == (4,) and calls == [1, 4]
        assert memory.get_with("fit", denso_model, lambda: compute(5)) is first and calls == [1, 4]


@pytest.mark.parametrize("n_samples", [1, 63, 64])
def test_any_length_gives_the_same_values(denso_model, n_samples):
    rng = np.random.default_rng(n_samples)
    q, qd, qdd = rng.normal(size=(3, n_samples, 6))
    assert np.array_equal(denso_model.regressor(q, qd, qdd), plain_regressor(denso_model, q, qd, qdd))
