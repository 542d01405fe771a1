"""The PSDM functions ``y_f = prod_h gamma_h^E[h, f]`` of many samples, evaluated as a prefix tree, in blocks.

A model's functions share factors: the Panda's 29,639 monomials of 35 signals (``q``, ``sin q``, ``cos q``,
``qd``, ``qdd``) have far fewer distinct prefixes than factors. :class:`MonomialTree` multiplies each prefix
once (a node is its parent times one factor), level by level over a block of samples that stays in cache,
instead of sweeping every factor over an array of ``n_samples x n_functions`` (690 MB for 2,900 Panda samples).

The factors of a monomial are multiplied in the order of ``h`` starting from 1, as the plain product
``y = 1; for h: y *= gamma_h ** E[h]`` does (1 times a factor is that factor exactly), so the values are
bit for bit those of the plain product; ``tests/psdm_casadi/test_monomials.py`` checks it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BLOCK_BYTES", "MonomialTree"]

#: Bytes of node values held per block of samples (two levels of the tree): bounds the memory of a block.
BLOCK_BYTES = 32 << 20


@dataclass(frozen=True, eq=False)
class MonomialTree:
    """The prefix tree of a monomial table ``exponents`` (n_signals, n_functions) of powers 0, 1 or 2.

    Level ``d`` holds the products of the first ``d`` factors of the monomials: ``parents[d]`` indexes level
    ``d - 1`` (level 0 is the factor itself) and ``factors[d]`` the factor table ``[gamma ** 1; gamma ** 2]``
    (row ``2 h + power - 1``); ``leaves[d]`` are (functions, nodes) whose last factor is at that level.
    """

    n_signals: int
    n_functions: int
    parents: tuple
    factors: tuple
    leaves: tuple
    constants: np.ndarray
    width: int

    @classmethod
    def of(cls, exponents) -> MonomialTree:
        """The tree of ``exponents`` (n_signals, n_functions)."""
        exponents = np.asarray(exponents)
        n_signals, n_functions = exponents.shape
        if exponents.size and exponents.max() > 2:
            raise ValueError(f"MonomialTree: exponents are 0, 1 or 2; got {int(exponents.max())}.")
        degree = np.count_nonzero(exponents, axis=0)
        depth = int(degree.max(initial=0))
        # row f: the factor indices 2 h + power - 1 of monomial f in the order of h, then -1
        chains = np.full((n_functions, depth), -1, dtype=np.intp)
        signal, function = np.nonzero(exponents)  # sorted by signal, then function
        order = np.lexsort((signal, function))  # by function, then signal
        signal, function = signal[order], function[order]
        position = np.arange(function.size) - np.searchsorted(function, function)
        chains[function, position] = 2 * signal + exponents[signal, function].astype(np.intp) - 1
        parents, factors, leaves = [], [], []
        previous = np.zeros(n_functions, dtype=np.intp)  # each function's node at the previous level
        for level in range(depth):
            alive = np.flatnonzero(degree > level)
            prefixes, first, inverse = np.unique(chains[alive, : level + 1], axis=0, return_index=True,
                                                 return_inverse=True)  # fmt: skip
            node = np.zeros(n_functions, dtype=np.intp)
            node[alive] = inverse.ravel()
            parents.append(previous[alive[first]] if level else np.full(first.size, -1, dtype=np.intp))
            factors.append(prefixes[:, level].astype(np.intp))
            ends = alive[degree[alive] == level + 1]
            leaves.append((ends, node[ends]))
            previous = node
        constants = np.flatnonzero(degree == 0)
        width = max((p.size for p in parents), default=1)
        return cls(n_signals, n_functions, tuple(parents), tuple(factors), tuple(leaves), constants, width)

    def block_samples(self) -> int:
        """Samples per block: two levels of node values within :data:`BLOCK_BYTES`."""
        return int(max(8, BLOCK_BYTES // (16 * max(self.width, 1))))

    def evaluate_transposed(self, gamma: np.ndarray) -> np.ndarray:
        """``y.T`` (n_functions, n_samples) of the signals ``gamma`` (n_samples, n_signals), C-contiguous."""
        n_samples = gamma.shape[0]
        out = np.empty((self.n_functions, n_samples))
        out[self.constants] = 1.0
        step = self.block_samples()
        for start in range(0, n_samples, step):
            block = np.ascontiguousarray(gamma[start : start + step].T)
            table = np.concatenate([block[:, None, :], (block**2)[:, None, :]], axis=1).reshape(-1, block.shape[1])
            level = None
            for parent, factor, (functions, nodes) in zip(self.parents, self.factors, self.leaves):
                level = table[factor] if level is None else level[parent] * table[factor]
                out[functions, start : start + step] = level[nodes]
        return out
