"""Compile a batch export (``codegen.batch``) and call it on numpy arrays of states (ctypes): the path
by which identification or reinforcement-learning code evaluates N states in one call.
"""

from __future__ import annotations

import ctypes
import shlex
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from codegen.batch import BatchExport
from codegen.build import compile_shared
from psdm_casadi.errors import ParameterError, ShapeError, SolverError

BATCH_FLAGS = ("-O3", "-march=native", "-fopenmp")


@dataclass(frozen=True)
class BatchLibrary:
    """A compiled batch export, loaded with ctypes.

    Attributes
    ----------
    path : Path
        The shared library (single-call and batch functions).
    export : BatchExport
    cdll : ctypes.CDLL
    """

    path: Path
    export: BatchExport
    cdll: ctypes.CDLL

    @property
    def default_threads(self) -> int:
        """Threads used when ``n_threads`` is None (OpenMP's default: all cores unless OMP_NUM_THREADS)."""
        return int(getattr(self.cdll, f"{self.export.library}_batch_threads")())

    def _index(self, name: str) -> int:
        for k, names in enumerate(zip(self.export.function_names, self.export.single_names, self.export.base_names)):
            if name in names:
                return k
        raise ParameterError(
            f"BatchLibrary function must be one of {list(self.export.function_names)} (or their single-call or "
            f"bare names); got {name!r}."
        )

    def evaluate(self, name: str, *inputs, n_threads: int | None = None) -> tuple:
        """Evaluate one batched function on arrays of states.

        Parameters
        ----------
        name : str
            The batch symbol, its single-call name, or the bare name (``"inverse_dynamics"``).
        *inputs : array, shape (n_states, n_entries)
            One row per state for each input, in the function's input order.
        n_threads : int, optional
            Threads; all cores by default.

        Returns
        -------
        tuple of ndarray
            Per output, shape (n_states, rows) for a vector and (n_states, rows, columns) for a matrix (a
            view of the C function's column-major rows).

        Raises
        ------
        ShapeError
            When an input is not 2-D with the function's width, or the inputs differ in n_states.
        ParameterError
            For an unknown name or a bad ``n_threads``.
        """
        k = self._index(name)
        batch, in_names, in_sizes = self.export.function_names[k], self.export.in_names[k], self.export.in_sizes[k]
        if len(inputs) != len(in_names):
            raise ParameterError(f"{batch} takes {len(in_names)} inputs {list(in_names)}; got {len(inputs)}.")
        arrays = [np.ascontiguousarray(x, dtype=float) for x in inputs]
        n_states = arrays[0].shape[0] if arrays[0].ndim == 2 else -1
        for input_name, size, array in zip(in_names, in_sizes, arrays):
            if array.ndim != 2 or array.shape[1] != size or array.shape[0] != n_states:
                raise ShapeError(
                    f"{batch} input {input_name} must have shape (n_states, {size}) with the same n_states as "
                    f"{in_names[0]} ({n_states if n_states >= 0 else 'not 2-D'}); got {array.shape}. Pass one row per "
                    "state (x[None, :] for a single state)."
                )
        if n_threads is None:
            n_threads = 0
        elif isinstance(n_threads, bool) or not isinstance(n_threads, (int, np.integer)) or n_threads < 1:
            raise ParameterError(f"{batch} n_threads must be a positive integer or None; got {n_threads!r}.")
        shapes = self.export.out_shapes[k]
        outputs = [np.empty((n_states, s[1], s[0]), dtype=float) for s in shapes]  # column-major per state
        function = getattr(self.cdll, batch)
        pointers = [a.ctypes.data_as(ctypes.c_void_p) for a in arrays + outputs]
        status = function(*pointers, ctypes.c_long(n_states), ctypes.c_int(int(n_threads)))
        if status != 0:
            raise SolverError(f"{batch} returned {status} for {n_states} states; rebuild the library.", status=status)
        return tuple(o[:, 0, :] if s[1] == 1 else o.transpose(0, 2, 1) for o, s in zip(outputs, shapes))

    def inverse_dynamics(self, q, qd, qdd, n_threads: int | None = None) -> np.ndarray:
        """tau, shape (n_states, n_dof), of each row of q, qd, qdd (each (n_states, n_dof))."""
        return self.evaluate("inverse_dynamics", q, qd, qdd, n_threads=n_threads)[0]

    def forward_dynamics(self, q, qd, tau, n_threads: int | None = None) -> np.ndarray:
        """qdd, shape (n_states, n_dof), of each row of q, qd, tau (each (n_states, n_dof))."""
        return self.evaluate("forward_dynamics", q, qd, tau, n_threads=n_threads)[0]

    def regressor(self, q, qd, qdd, n_threads: int | None = None) -> np.ndarray:
        """Y, shape (n_states, n_dof, n_base), of each row of q, qd, qdd (each (n_states, n_dof))."""
        return self.evaluate("regressor", q, qd, qdd, n_threads=n_threads)[0]


def build_batch(export: BatchExport, *, build_dir=None, compiler=None, flags=BATCH_FLAGS) -> BatchLibrary:
    """Compile the single-call and batch sources of ``export`` into one shared library and load it.

    Parameters
    ----------
    export : BatchExport
        The result of ``export_batch``.
    build_dir : str or Path, optional
        Where to put ``lib<library>.so``; a fresh temporary folder by default.
    compiler : str, optional
        See ``codegen.build.find_compiler``.
    flags : sequence of str or str
        Compiler flags; without ``-fopenmp`` the batch functions run on one thread.

    Returns
    -------
    BatchLibrary

    Raises
    ------
    ParameterError
        When ``export`` is not a BatchExport.
    SolverError
        When compilation fails.
    """
    if not isinstance(export, BatchExport):
        raise ParameterError(
            f"build_batch export must be a BatchExport; got {type(export).__name__}. Pass export_batch(...)."
        )
    if isinstance(flags, str):
        flags = tuple(shlex.split(flags))
    folder = Path(build_dir) if build_dir is not None else Path(tempfile.mkdtemp(prefix="psdm_batch_"))
    folder.mkdir(parents=True, exist_ok=True)
    path = compile_shared(
        [export.single.source, export.source], folder / f"lib{export.library}.so", compiler=compiler, flags=flags
    )
    cdll = ctypes.CDLL(str(path.resolve()))
    for name in export.function_names:
        function = getattr(cdll, name)
        function.restype = ctypes.c_int
    return BatchLibrary(path=path, export=export, cdll=cdll)
