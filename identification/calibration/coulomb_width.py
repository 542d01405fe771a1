"""The Coulomb column's smoothing width per joint: ``v_j`` of ``fc_j tanh(qd_j / v_j)``, as a model file states it.

A joint's Coulomb friction is a sign smoothed over a velocity ``v`` (``trajectory_data.friction_term``). Joints differ
in how sharply their friction reverses, so ``v`` is one value per joint: a model file's ``drive.coulomb_velocity`` is a
number (every joint; the files written so far) or one positive number per joint. :func:`file_coulomb_widths` is the one
reader every command uses; :func:`coulomb_widths` checks any other source (options, the command line) the same way,
:func:`joint_width` picks one joint's, and :func:`widths_text` states them in a sentence (one value when they agree).
"""

from __future__ import annotations

import math

import numpy as np

from psdm_casadi.errors import ModelFileError, ParameterError

__all__ = ["DEFAULT_WIDTH", "approximated_widths", "coulomb_widths", "file_coulomb_widths", "file_width", "joint_width",
           "positive_widths", "tanh_text", "width_value", "widths_text"]  # fmt: skip

#: [rad/s] the width a file without ``drive.coulomb_velocity`` was predicted with (``TrajectoryOptions``' default).
DEFAULT_WIDTH = 0.05


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _problem(value, n_dof: int) -> str | None:
    """What is wrong with ``value`` as the widths of ``n_dof`` joints, or None."""
    if _is_number(value):
        return None if math.isfinite(value) and value > 0 else f"{value!r} is not a positive finite number"
    if not isinstance(value, (list, tuple, np.ndarray)) or not all(_is_number(v) for v in np.ravel(value)):
        return f"{value!r} is neither a number nor a list of numbers"
    values = [float(v) for v in np.ravel(value)]
    if len(values) != n_dof:
        return f"{values} holds {len(values)} values for {n_dof} joints"
    bad = [j + 1 for j, v in enumerate(values) if not (math.isfinite(v) and v > 0)]
    return f"{values} is not positive and finite on joint(s) {bad}" if bad else None


def coulomb_widths(value, n_dof: int, owner: str = "coulomb_velocity", fix: str = "") -> np.ndarray:
    """The widths [rad/s], shape (n_dof,), of ``value``: one positive finite number (every joint's) or ``n_dof``.

    Raises
    ------
    ParameterError
        Naming ``owner`` and the fix (``fix``, else one number or one per joint) for a non-positive, non-finite or
        wrong-length value.
    """
    problem = _problem(value, n_dof)
    if problem is not None:
        raise ParameterError(f"{owner} must be one positive number [rad/s] or {n_dof}, one per joint; got {problem}. "
                             + (fix or f"Give one width or {n_dof} widths > 0."))  # fmt: skip
    return np.broadcast_to(np.asarray(value, dtype=float), (n_dof,)).astype(float)


def positive_widths(value, owner: str) -> float | tuple:
    """``value`` (one width [rad/s], or one per joint, before the joints are known) as :func:`width_value` holds it.

    Raises
    ------
    ParameterError
        Naming ``owner`` for a value that is not one or more positive finite numbers.
    """
    values = np.ravel(value) if isinstance(value, (list, tuple, np.ndarray)) else [value]
    if not (len(values) and all(_is_number(v) and math.isfinite(v) and v > 0 for v in values)):
        raise ParameterError(f"{owner} must be a positive width [rad/s], or one per joint; got {value!r}. Give "
                             "widths > 0.")  # fmt: skip
    return width_value(values)


def file_coulomb_widths(drive: dict, n_dof: int, file: str = "calibrated model") -> np.ndarray:
    """The widths [rad/s], shape (n_dof,), of a model file's ``drive`` block: its ``coulomb_velocity`` (a number for
    every joint, or one per joint); a file without it (no ``fc`` term) is read at :data:`DEFAULT_WIDTH`.

    Raises
    ------
    ModelFileError
        Naming ``file`` (its name), the field ``drive.coulomb_velocity`` and the fix.
    """
    value = drive.get("coulomb_velocity")
    if value is None:
        return np.full(n_dof, DEFAULT_WIDTH)
    problem = _problem(value, n_dof)
    if problem is not None:
        raise ModelFileError(
            f"{file}: drive.coulomb_velocity must be one positive number [rad/s] or {n_dof}, one per joint; got "
            f"{problem}. Correct the field (a positive width per joint) or re-run 'psdm identify' (it writes it)."
        )
    return np.broadcast_to(np.asarray(value, dtype=float), (n_dof,)).astype(float)


def file_width(widths) -> float | list:
    """``widths`` as a model file writes ``drive.coulomb_velocity``: one number when every joint's is the same (the
    files older readers read), else a list per joint (``calibrated_model.WIDTH_VERSION``)."""
    value = width_value(widths)
    return list(value) if isinstance(value, tuple) else value


def joint_width(widths, joint: int) -> float:
    """[rad/s] one joint's (0-based) width of ``widths``: a number (every joint's) or one per joint."""
    return float(widths) if np.ndim(widths) == 0 else float(np.asarray(widths, dtype=float)[joint])


def width_value(widths) -> float | tuple:
    """``widths`` as options hold them: one number when every joint's is the same, else a tuple per joint."""
    values = np.ravel(np.asarray(widths, dtype=float))
    return float(values[0]) if np.all(values == values[0]) else tuple(float(v) for v in values)


def approximated_widths(widths, why: str) -> str:
    """What an export that cannot hold a width per joint adds after :func:`tanh_text`: nothing for one width, else
    ``" (<why>: the per-joint widths are approximated)"``."""
    return "" if isinstance(width_value(widths), float) else f" ({why}: the per-joint widths are approximated)"


def tanh_text(widths) -> str:
    """The Coulomb term in words: ``"fc tanh(qd / 0.05 rad/s)"``, or with a width per joint ``"fc tanh(qd / v) with v
    0.02, 0.085 rad/s (joints 1 to 2)"`` (the exported files' notes)."""
    text = widths_text(widths, 6)
    return f"fc tanh(qd / {text})" if text.endswith(" rad/s") else f"fc tanh(qd / v) with v {text}"


def widths_text(widths, digits: int = 3) -> str:
    """``"0.05 rad/s"`` when every joint's width is the same, else each joint's: ``"0.02, 0.05, 0.085 rad/s (joints
    1 to 3)"``."""
    values = np.ravel(np.asarray(widths, dtype=float))
    if values.size == 1 or np.all(values == values[0]):
        return f"{values[0]:.{digits}g} rad/s"
    listed = ", ".join(f"{v:.{digits}g}" for v in values)
    return f"{listed} rad/s (joints 1 to {values.size})"
