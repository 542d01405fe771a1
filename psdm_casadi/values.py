"""Input values as the checks see them: real numbers, physical inertias, and values as error messages show them.

Shared by the robot description (``description``), the robot-file and URDF readers and the payload
reader of ``identification``, so that every message prints ``nan``, ``inf`` and ``0.1`` the same
way and every inertia is held to the same physics.
"""

from __future__ import annotations

import numpy as np

from psdm_casadi.errors import RobotFileError

__all__ = ["exact_text", "float_array", "format_value", "inertia_violation", "is_real_number"]


def is_real_number(value) -> bool:
    """True for an int or float (numpy scalars included) that is not a bool; NaN and inf count as numbers."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def exact_text(value) -> str:
    """A float as the shortest text that reads back to the same double (``0.0`` for ``-0.0``), for files a
    reader must reproduce exactly (URDF out)."""
    return repr(float(value) + 0.0)


def format_value(value, limit: int = 80) -> str:
    """A value as an error message shows it: plain numbers (``nan``, ``inf``, ``0.1``) and lists of them.

    Never ``np.float64(0.1)`` or ``array([...])``; long values are cut at ``limit`` characters.

    Examples
    --------
    >>> format_value(np.array([0.0, np.inf, np.nan]))
    '[0.0, inf, nan]'
    """
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        shown = [format_value(v, limit) for v in value[:16]] + (["..."] if len(value) > 16 else [])
        text = "[" + ", ".join(shown) + "]"
    elif isinstance(value, (bool, np.bool_)):
        text = "true" if value else "false"
    elif isinstance(value, (int, np.integer)):
        text = str(int(value))
    elif isinstance(value, (float, np.floating)):
        text = repr(float(value))
    else:
        text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def float_array(value, owner: str, expected: str, error: type = RobotFileError) -> np.ndarray:
    """``value`` as a float array, or ``error`` saying ``owner must be expected; got value``."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise error(f"{owner} must be {expected}; got {format_value(value)}. Fix the value.") from None


def inertia_violation(inertia, rtol: float = 1e-6, atol: float = 1e-12) -> str | None:
    """Why a 3x3 inertia about the centre of mass is not physical, or None when it is.

    It must be symmetric positive semi-definite and its principal moments must satisfy the
    triangle inequality (each at most the sum of the other two, e.g. Ixx + Iyy >= Izz for a
    diagonal inertia); ``rtol`` of the largest moment plus ``atol`` [kg m^2] is allowed for
    round-off. Zero (a point mass or a massless link) is physical.

    Parameters
    ----------
    inertia : array, shape (3, 3)
        [kg m^2], about the centre of mass.

    Returns
    -------
    str or None
        The violated constraint and the principal moments, phrased to follow ``Owner.inertia``.
    """
    moments = np.linalg.eigvalsh(0.5 * (np.asarray(inertia) + np.asarray(inertia).T))  # ascending
    tolerance = rtol * float(np.abs(moments).max()) + atol
    shown = format_value([float(f"{m:.6g}") for m in moments])
    if moments[0] < -tolerance:
        return f"must be positive semi-definite (principal moments >= 0); got principal moments {shown}"
    if moments[0] + moments[1] < moments[2] - tolerance:
        return (
            "must satisfy the triangle inequality of its principal moments (the largest at most the sum of the "
            f"other two, e.g. Ixx + Iyy >= Izz); got principal moments {shown}"
        )
    return None
