"""Payload: a known load fixed to the flange (the calibration mass of payload.json, a tool of tool.json).

The user supplies it with the recordings (``identification.data.dataset``); the calibration steps
subtract its torques (``identification.calibration.payload``) and the virtual robot carries it as
an effect (``identification.virtual.effects.Payload`` extends this class).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from psdm_casadi.errors import ParameterError
from psdm_casadi.robot import physical_to_dynamic

__all__ = ["Payload", "read_payload", "payload_json"]


@dataclass(frozen=True)
class Payload:
    """A body fixed to the flange (last link frame): point mass by default (paper eqs. 16-17).

    Parameters
    ----------
    mass : float
        [kg]
    com : array, shape (3,)
        Centre of mass in the last link frame [m].
    inertia : array, shape (3, 3), optional
        Inertia about the centre of mass [kg m^2]; zero (a point mass) by default.

    Examples
    --------
    >>> float(Payload(mass=2.0, com=(0.05, 0.0, 0.05)).dynamic_parameters()[0])   # the mass comes first
    2.0
    """

    mass: float
    com: tuple = (0.0, 0.0, 0.0)
    inertia: tuple | None = None

    def validate(self, n_dof: int) -> None:
        """Raise :class:`ParameterError` for a negative mass or a malformed centre of mass or inertia.

        ``n_dof`` is the robot's joint count (unused: a payload fits any robot); the signature is
        the one of the virtual robot's effects.
        """
        if not (np.isfinite(self.mass) and self.mass >= 0):
            raise ParameterError(f"Payload.mass must be >= 0 [kg]; got {self.mass!r}.")
        if np.asarray(self.com, dtype=float).shape != (3,):
            raise ParameterError(f"Payload.com must have 3 coordinates [m]; got {self.com!r}.")
        if self.inertia is not None and np.asarray(self.inertia, dtype=float).shape != (3, 3):
            raise ParameterError(f"Payload.inertia must be a 3x3 matrix [kg m^2] or None; got {self.inertia!r}.")

    def dynamic_parameters(self) -> np.ndarray:
        """The 10 dynamic parameters of the payload about the last link frame origin."""
        inertia = np.zeros((3, 3)) if self.inertia is None else np.asarray(self.inertia, dtype=float)
        return physical_to_dynamic(float(self.mass), np.asarray(self.com, dtype=float), inertia)


def read_payload(path) -> Payload:
    """Read ``{"mass": .., "com": [..], "inertia": [[..]]}`` (a payload.json or tool.json) into a Payload.

    Raises
    ------
    ParameterError
        When the file lacks the mass or holds malformed values.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
        return Payload(
            mass=float(data["mass"]),
            com=tuple(float(c) for c in data.get("com", (0.0, 0.0, 0.0))),
            inertia=None if data.get("inertia") is None else tuple(map(tuple, data["inertia"])),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ParameterError(
            f"{path.name}: must hold {{'mass': kg, 'com': [x, y, z]}}; got an invalid file ({exc}). Fix the file."
        ) from None


def payload_json(payload: Payload) -> str:
    """The JSON text :func:`read_payload` reads back."""
    return json.dumps(
        {
            "mass": payload.mass,
            "com": list(payload.com),
            "inertia": None if payload.inertia is None else np.asarray(payload.inertia).tolist(),
        }
    )
