"""Reading a recording's MATLAB ``.mat`` file into a ColumnTable, in either of two layouts.

**One variable per column**: ``t``, ``q1..qn``, ``tau1..taun`` and/or ``i1..in``, optional
``qd1..qdn``, ``qdd1..qddn``; each a vector of ``n_samples`` numbers (row or column), e.g.
``save('rec.mat', 't', 'q1', 'q2', 'tau1', 'tau2')``.

**Matrices**: ``t`` (a vector of ``n_samples``), ``q`` ``(n_samples, n_dof)``, ``tau`` and/or
``current`` (or ``i``) ``(n_samples, n_dof)``, optional ``qd`` and ``qdd`` of the same shape, e.g.
``save('rec.mat', 't', 'q', 'tau')``; a matrix holding one joint per row, ``(n_dof, n_samples)``, is
refused with the fix (save its transpose). The two layouts may not be mixed in one file.

Files of MATLAB v4 to v7 are read by ``scipy.io.loadmat``. A v7.3 file is HDF5: it is read with
``h5py`` when that package is installed (MATLAB stores its arrays transposed there; they are read
back in MATLAB's orientation) and refused with the fix otherwise. Units are SI as in every recording:
``t`` [s], ``q`` [rad or m], ``tau`` [N m], currents [A].
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from identification.data.csvfile import read_head
from identification.data.table import ColumnTable
from psdm_casadi.errors import RecordingError

#: Matrix variable -> column prefix of its columns (``q`` -> ``q1..qn``).
MATRIX_PREFIXES = {"q": "q", "qd": "qd", "qdd": "qdd", "tau": "tau", "current": "i", "i": "i"}
_SAVE = "Save plain numeric arrays, e.g. save('rec.mat', 't', 'q', 'tau') with t (n x 1), q and tau (n x n_dof)."
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_V73_STAND_INS = {  # MATLAB classes of a v7.3 file that are not numbers, as arrays of the kind scipy reads them as
    "struct": np.zeros((1, 1), dtype=[("field", "O")]),
    "cell": np.empty((1, 1), dtype=object),
    "char": np.array(["text"]),
    "logical": np.zeros((1, 1), dtype=bool),
}


def _is_v73(head: bytes) -> bool:
    """Whether the file is MATLAB v7.3 (header version 2, as ``scipy.io.matlab.matfile_version`` reads it) or HDF5."""
    endian = head[126:128]
    major = head[125] if endian == b"IM" else head[124] if endian == b"MI" else None
    return major == 2 or head.startswith(_HDF5_SIGNATURE) or head[512:520] == _HDF5_SIGNATURE


def _load_classic(path: Path) -> dict:
    """name -> array of a v4-v7 file (scipy), refusing what scipy cannot read."""
    from scipy.io import loadmat

    try:
        content = loadmat(path, squeeze_me=False, mat_dtype=False, struct_as_record=True)
    except (ValueError, TypeError, OSError, NotImplementedError, EOFError, MemoryError) as exc:
        raise RecordingError(f"{path.name}: not a readable MATLAB file ({exc}). {_SAVE}") from None
    return {name: value for name, value in content.items() if not name.startswith("__")}


def _load_v73(path: Path) -> dict:
    """name -> array of a v7.3 (HDF5) file through h5py, transposed back to MATLAB's orientation."""
    try:
        import h5py
    except ImportError:
        raise RecordingError(
            f"{path.name} is a MATLAB v7.3 file (HDF5), which needs the h5py package. Install it "
            "(pip install h5py), or save the file in the v7 format: save('rec.mat', 't', 'q', 'tau', '-v7')."
        ) from None
    variables = {}
    try:
        with h5py.File(path, "r") as handle:
            for name, item in handle.items():
                if name.startswith("#"):  # MATLAB's #refs# / #subsystem# groups
                    continue
                kind = item.attrs.get("MATLAB_class", b"double") if isinstance(item, h5py.Dataset) else b"struct"
                kind = kind.decode() if isinstance(kind, bytes) else str(kind)
                # what is not numeric is refused below by its kind: a struct (a group), cell, text or logical
                variables[name] = _V73_STAND_INS[kind] if kind in _V73_STAND_INS else np.asarray(item[()]).T
    except OSError as exc:
        raise RecordingError(f"{path.name}: not a readable MATLAB v7.3 (HDF5) file ({exc}). {_SAVE}") from None
    return variables


def _numbers(source: str, name: str, value) -> np.ndarray:
    """A variable as a 2-D float array, refusing structs, cells, text, sparse and complex data."""
    if not isinstance(value, np.ndarray):
        raise RecordingError(
            f"{source}: variable {name!r} is a {type(value).__name__} (a sparse matrix?), not a numeric array. "
            f"Save it as full(...). {_SAVE}"
        )
    kinds = {"V": "a struct", "O": "a cell array", "U": "text", "S": "text", "c": "complex", "b": "logical"}
    if value.dtype.kind not in "iuf":
        raise RecordingError(
            f"{source}: variable {name!r} is {kinds.get(value.dtype.kind, str(value.dtype))}, not real numbers. {_SAVE}"
        )
    array = np.asarray(value, dtype=float)
    if array.ndim > 2:
        raise RecordingError(f"{source}: variable {name!r} has shape {array.shape}; it must be 1-D or 2-D. {_SAVE}")
    return array.reshape(1, -1) if array.ndim < 2 else array


def _is_vector(array: np.ndarray) -> bool:
    return min(array.shape) == 1 or array.size == 0


def _matrix_columns(source: str, name: str, array: np.ndarray, n_samples: int) -> np.ndarray:
    """The ``(n_samples, n_dof)`` matrix of a signal variable, refusing a transposed or mis-sized one."""
    if _is_vector(array):
        array = array.reshape(-1, 1)
    if array.shape[0] == n_samples:
        return array
    if array.shape[1] == n_samples:
        raise RecordingError(
            f"{source}: variable {name!r} has shape {array.shape}: one joint per row; it must be (n_samples, n_dof) = "
            f"({n_samples}, {array.shape[0]}) to match t. Save its transpose ({name} = {name}.') and load again."
        )
    raise RecordingError(
        f"{source}: variable {name!r} has {array.shape[0]} rows but t has {n_samples} samples. "
        "Save every signal with one row per sample of t."
    )


def _table_from_variables(source: str, variables: dict) -> ColumnTable:
    """The columns of either layout (module docstring) as a ColumnTable."""
    arrays = {name: _numbers(source, name, value) for name, value in variables.items()}
    if "t" not in arrays:
        raise RecordingError(
            f"{source}: variable t is missing (variables: {', '.join(arrays) or 'none'}). Save the time stamps [s] "
            "as t."
        )
    if not _is_vector(arrays["t"]):
        raise RecordingError(
            f"{source}: variable 't' has shape {arrays['t'].shape}; it must be a vector of time stamps [s]. Save t(:)."
        )
    t = arrays.pop("t").ravel()
    matrices = [name for name in arrays if name in MATRIX_PREFIXES]
    others = [name for name in arrays if name not in MATRIX_PREFIXES]
    if matrices and others:
        raise RecordingError(
            f"{source}: holds both matrix variables ({', '.join(matrices)}) and others ({', '.join(others)}); "
            "use one layout: matrices t, q, tau (and qd, qdd, current), or one vector per column t, q1, tau1, ..."
        )
    names, columns = ["t"], [t]
    if matrices:
        for name in sorted(matrices, key=list(MATRIX_PREFIXES).index):
            matrix = _matrix_columns(source, name, arrays[name], t.size)
            prefix = MATRIX_PREFIXES[name]
            if name == "i" and "current" in matrices:
                raise RecordingError(f"{source}: holds both 'current' and 'i'. Keep one of them.")
            names += [f"{prefix}{j + 1}" for j in range(matrix.shape[1])]
            columns += list(matrix.T)
    else:
        for name in others:
            array = arrays[name]
            if not _is_vector(array):
                raise RecordingError(
                    f"{source}: variable {name!r} has shape {array.shape}; in the one-variable-per-column layout "
                    "each must be a vector. Save matrices as t, q, tau (n_samples x n_dof) instead."
                )
            if array.size != t.size:
                raise RecordingError(
                    f"{source}: variable {name!r} has {array.size} samples but t has {t.size}. "
                    "Make all columns equal length."
                )
            names.append(name)
            columns.append(array.ravel())
    data = np.column_stack(columns) if t.size else np.empty((0, len(names)))
    data.setflags(write=False)  # handed over to the table without a copy
    return ColumnTable(source=source, names=tuple(names), data=data)


def read_mat_table(path) -> ColumnTable:
    """Read a MATLAB ``.mat`` recording (either layout of the module docstring) into a :class:`ColumnTable`.

    Parameters
    ----------
    path : str or Path
        An existing regular file.

    Returns
    -------
    ColumnTable
        Columns ``t``, ``q1..qn``, ... (matrices split per joint), rows located as ``row k`` (0-based).

    Raises
    ------
    RecordingError
        Naming the file, the variable and the fix: not a MATLAB file, a v7.3 file without h5py,
        structs, cells, text, sparse or complex variables, mixed layouts, a transposed matrix,
        signals of another length than ``t``, NaN, infinite or implausibly large values.

    Examples
    --------
    >>> from scipy.io import savemat                                   # doctest: +SKIP
    >>> savemat("rec.mat", {"t": t, "q": q, "tau": tau})
    >>> read_mat_table("rec.mat").names[:3]
    ('t', 'q1', 'q2')
    """
    path = Path(path)
    head = read_head(path)
    if not head:
        raise RecordingError(f"{path.name} is empty. {_SAVE}")
    variables = _load_v73(path) if _is_v73(head) else _load_classic(path)
    return _table_from_variables(path.name, variables)
