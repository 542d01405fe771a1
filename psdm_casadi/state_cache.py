"""A bounded memory of a model's regressor on series of states it has already evaluated.

Identification evaluates the regressor of one prepared recording several times: the column choice, the
Stribeck-velocity fit, the normal equations, the residual's correlation time, the validation and its report.
:class:`StateCache` keeps the latest results keyed by a digest of the states (BLAKE2b of their bytes and
shape), up to a byte budget (least recently used first out), and hands out copies, so a caller that changes its
array changes nothing here. Series shorter than ``min_samples`` are not kept: hashing them costs more than it
saves.

:class:`BlockMemory` keeps a costlier result the same way, by a key its caller makes (identify's LuGre trial fits the
training recordings once where its route runs twice, or a caller runs identify several times on them), and with
``BlockMemory.get_with`` beside the input the key does not hold (the derived model a fit was made with).

The memory is on only inside :func:`remembering` (``psdm identify`` and ``identify_trajectories`` / ``choose_columns``
open it) and is emptied when the outermost such block ends: a long-running process that streams recordings through
the regressor once each (the fleet's workers) holds nothing, and a command holds its recordings' regressors only
while it runs.
"""

from __future__ import annotations

import contextlib
import contextvars
import hashlib
import threading
import weakref
from collections import OrderedDict

import numpy as np

__all__ = ["CACHE_BYTES", "MIN_SAMPLES", "BlockMemory", "StateCache", "remembering"]

#: Bytes of results a cache holds at most (about 18 Panda recordings of 2,900 prepared samples, 5 of the 12-joint arm).
CACHE_BYTES = 128 << 20
#: Shortest series kept.
MIN_SAMPLES = 64


#: How many :func:`remembering` blocks are open in this context, and the caches that stored something in them.
_DEPTH = contextvars.ContextVar("psdm_state_cache_depth", default=0)
_USED = weakref.WeakSet()
_USED_LOCK = threading.Lock()


@contextlib.contextmanager
def remembering():
    """A block inside which regressors of series evaluated before come from memory; the memory is emptied when the
    outermost block ends."""
    token = _DEPTH.set(_DEPTH.get() + 1)
    try:
        yield
    finally:
        _DEPTH.reset(token)
        if _DEPTH.get() == 0:
            with _USED_LOCK:
                caches = list(_USED)
                _USED.clear()
            for cache in caches:
                cache.clear()


class StateCache:
    """Results of a function of ``(q, qd, qdd)`` series, by the digest of the states."""

    def __init__(self, max_bytes: int = CACHE_BYTES, min_samples: int = MIN_SAMPLES):
        self.max_bytes = max_bytes
        self.min_samples = min_samples
        self._entries = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    @staticmethod
    def key(*arrays) -> bytes:
        """The digest of the arrays' shapes and bytes."""
        digest = hashlib.blake2b(digest_size=20)
        for array in arrays:
            digest.update(repr(array.shape).encode())
            digest.update(np.ascontiguousarray(array, dtype=float).data)
        return digest.digest()

    def get(self, compute, *arrays) -> np.ndarray:
        """``compute(*arrays)``, from memory when the same states were evaluated before (a copy either way)."""
        if arrays[0].shape[0] < self.min_samples or _DEPTH.get() == 0:
            return compute(*arrays)
        key = self.key(*arrays)
        with self._lock:
            found = self._entries.get(key)
            if found is not None:
                self._entries.move_to_end(key)
                return found.copy()
        value = compute(*arrays)
        if value.nbytes <= self.max_bytes:
            with self._lock:
                if key not in self._entries:
                    self._entries[key] = value.copy()
                    self._bytes += value.nbytes
                    with _USED_LOCK:
                        _USED.add(self)
                while self._bytes > self.max_bytes:
                    _, dropped = self._entries.popitem(last=False)
                    self._bytes -= dropped.nbytes
        return value

    def __getstate__(self) -> dict:
        """Pickled (a model sent to a worker) without its results or lock: the copy starts empty."""
        return {"max_bytes": self.max_bytes, "min_samples": self.min_samples}

    def __setstate__(self, state) -> None:
        self.__init__(**state)

    def clear(self) -> None:
        """Forget every result."""
        with self._lock:
            self._entries.clear()
            self._bytes = 0


class BlockMemory:
    """Results of a costly computation by a hashable key, kept while a :func:`remembering` block is open (emptied with
    the regressors when the outermost block ends), at most ``max_entries`` (the least recently used first out).
    Results are handed out as they are: they must be immutable (frozen dataclasses, tuples)."""

    def __init__(self, max_entries: int = 4):
        self.max_entries = max_entries
        self._entries = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key, compute):
        """``compute()``, from memory when it was computed for ``key`` before in the open block."""
        if _DEPTH.get() == 0:
            return compute()
        with self._lock:
            if key in self._entries:
                self._entries.move_to_end(key)
                return self._entries[key]
        value = compute()
        with self._lock:
            self._entries[key] = value
            self._entries.move_to_end(key)
            with _USED_LOCK:
                _USED.add(self)
            while len(self._entries) > self.max_entries:
                self._entries.popitem(last=False)
        return value

    def get_with(self, key, made_with, compute):
        """``compute()`` made with ``made_with``, an input the key does not hold (a derived model: unhashable, costly
        to digest), from memory when the key's result was made with an equal one in the open block (the same object,
        or ``==``: an equal copy computes the same); computed anew, the remembered result left in place, when it was
        made with another (identify's trial fits with another derivation of the robot)."""
        found_with, found = self.get(key, lambda: (made_with, compute()))
        if found_with is not made_with and found_with != made_with:
            return compute()
        return found

    def clear(self) -> None:
        """Forget every result."""
        with self._lock:
            self._entries.clear()
