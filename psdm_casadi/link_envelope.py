"""The physical envelope of a link: an ellipsoid (in the link frame) that holds all of the link's mass.

A robot file may give it per link (``envelope`` in a ``[[link]]`` table, ``robot_file``); otherwise the
identification derives one from the link's geometry or its kinematic lengths
(``identification.calibration.envelope``). A box is held by the ellipsoid through its corners (semi-axes
``sqrt(3)`` times the box's half extents), the smallest one with the box's axes.

A link the next joint's origin bounds (a link of its own length, not the last) also has a ``CentreReach``: its centre
of mass lies at most ``limit`` along the direction from its joint to the next joint's origin (the mass beyond that
origin is the next joint's housing, centred on it). The identification derives it; a robot file does not give it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from psdm_casadi.errors import RobotFileError
from psdm_casadi.values import float_array, format_value

__all__ = ["CentreReach", "LinkEnvelope", "check_envelopes"]


@dataclass(frozen=True, eq=False)
class CentreReach:
    """The half-space ``{c : direction . (c - origin) <= limit}`` that holds a link's centre of mass ``c``.

    Parameters
    ----------
    origin : array, shape (3,)
        [m] the link's joint origin in the link frame.
    direction : array, shape (3,)
        Unit vector from ``origin`` towards the next joint's origin (link frame).
    limit : float
        [m] > 0, the farthest the centre of mass lies along ``direction`` from ``origin``.
    """

    origin: np.ndarray
    direction: np.ndarray
    limit: float

    def __post_init__(self):
        origin = np.asarray(self.origin, dtype=float).reshape(-1)
        direction = np.asarray(self.direction, dtype=float).reshape(-1)
        if origin.shape != (3,) or direction.shape != (3,) or not np.isclose(np.linalg.norm(direction), 1.0):
            raise RobotFileError(f"CentreReach needs a 3-vector origin and a unit direction; got {format_value(origin)}"
                                 f" and {format_value(direction)}.")  # fmt: skip
        if not (math.isfinite(self.limit) and self.limit > 0):
            raise RobotFileError(f"CentreReach.limit must be finite and > 0 [m]; got {format_value(self.limit)}.")
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "direction", direction)
        object.__setattr__(self, "limit", float(self.limit))

    def along(self, com) -> float:
        """How far ``com`` (3,) [m] lies along ``direction`` from ``origin``, as a share of ``limit`` (1: at it)."""
        return float(self.direction @ (np.asarray(com, dtype=float) - self.origin)) / self.limit

    def to_dict(self) -> dict:
        return {"origin": self.origin.tolist(), "direction": self.direction.tolist(), "limit": self.limit}


@dataclass(frozen=True, eq=False)
class LinkEnvelope:
    """The ellipsoid ``{x : (x - center)^T Q (x - center) <= 1}``, ``Q = R diag(1 / semi_axes^2) R^T``.

    Parameters
    ----------
    center : array, shape (3,)
        [m] in the link frame (the frame of the link's inertial parameters).
    semi_axes : array, shape (3,)
        [m] along the columns of ``rotation``, all > 0.
    rotation : array, shape (3, 3)
        Orthonormal; its columns are the ellipsoid's axes in the link frame (default: the link frame's).
    source : str
        Where it comes from, for reports ("robot file", "URDF collision geometry", "kinematic lengths", ...).
    reach : CentreReach or None
        Where the next joint's origin bounds the link: how far along the link its centre of mass may lie.

    Raises
    ------
    RobotFileError
        For non-finite values, a semi-axis <= 0, or a rotation that is not orthonormal.
    """

    center: np.ndarray
    semi_axes: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    source: str = "robot file"
    reach: CentreReach | None = None

    def __post_init__(self):
        center = float_array(self.center, "LinkEnvelope.center", "3 numbers [m]").reshape(-1)
        axes = float_array(self.semi_axes, "LinkEnvelope.semi_axes", "3 numbers [m]").reshape(-1)
        rotation = float_array(self.rotation, "LinkEnvelope.rotation", "a 3x3 rotation matrix")
        if center.shape != (3,) or not np.all(np.isfinite(center)):
            raise RobotFileError(f"LinkEnvelope.center must be 3 finite numbers [m]; got {format_value(center)}.")
        if axes.shape != (3,) or not np.all(np.isfinite(axes)) or np.any(axes <= 0):
            raise RobotFileError(
                f"LinkEnvelope.semi_axes must be 3 finite numbers > 0 [m]; got {format_value(axes)}. "
                "Give the half-lengths of the link's bounding ellipsoid (or half_extents of its bounding box)."
            )
        if rotation.shape != (3, 3) or not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6):
            raise RobotFileError(f"LinkEnvelope.rotation must be a 3x3 rotation matrix; got {format_value(rotation)}.")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "semi_axes", axes)
        object.__setattr__(self, "rotation", rotation)

    @classmethod
    def from_box(cls, center, half_extents, rotation=None, source: str = "robot file") -> LinkEnvelope:
        """The ellipsoid through the corners of a box (semi-axes ``sqrt(3)`` times its half extents)."""
        half = float_array(half_extents, "LinkEnvelope.half_extents", "3 numbers [m]").reshape(-1)
        rotation = np.eye(3) if rotation is None else rotation
        return cls(center, math.sqrt(3.0) * half, rotation, source)

    @property
    def shape_matrix(self) -> np.ndarray:
        """``Q`` of the module docstring, shape (3, 3) [1/m^2]."""
        return (self.rotation / self.semi_axes**2) @ self.rotation.T

    def contains(self, points) -> np.ndarray:
        """Whether each point (shape (n, 3) or (3,), link frame [m]) lies in the ellipsoid."""
        d = np.atleast_2d(np.asarray(points, dtype=float)) - self.center
        return np.einsum("ni,ij,nj->n", d, self.shape_matrix, d) <= 1.0 + 1e-12

    def holds_centre(self, com) -> bool:
        """Whether a centre of mass ``com`` (3,) [m] lies in the ellipsoid and within the ``reach``."""
        return bool(self.contains(com)[0]) and (self.reach is None or self.reach.along(com) <= 1.0 + 1e-12)

    def to_dict(self) -> dict:
        out = {"center": self.center.tolist(), "semi_axes": self.semi_axes.tolist(),
               "rotation": self.rotation.tolist(), "source": self.source}  # fmt: skip
        return out if self.reach is None else {**out, "reach": self.reach.to_dict()}


def check_envelopes(envelopes, n: int) -> tuple | None:
    """``RobotDescription.envelopes`` checked: None, or ``n`` entries each a LinkEnvelope or None."""
    if envelopes is None:
        return None
    envelopes = tuple(envelopes)
    if len(envelopes) != n or not all(e is None or isinstance(e, LinkEnvelope) for e in envelopes):
        raise RobotFileError(
            f"RobotDescription.envelopes must hold {n} entries (one per link), each a LinkEnvelope or None; got "
            f"{format_value(envelopes)}."
        )
    return envelopes
