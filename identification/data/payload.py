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
from psdm_casadi.text_file import read_text_file
from psdm_casadi.values import float_array, format_value, inertia_violation, is_real_number

__all__ = ["Payload", "payload_from_mapping", "payload_json", "read_payload"]


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
        """Raise :class:`ParameterError` for a negative or non-finite mass or a malformed centre of mass or inertia.

        The inertia (about the centre of mass) must be symmetric, positive semi-definite and within
        the triangle inequality of its principal moments. ``n_dof`` is the robot's joint count
        (unused: a payload fits any robot); the signature is the one of the virtual robot's effects.
        """
        if not (is_real_number(self.mass) and np.isfinite(self.mass) and self.mass >= 0):
            raise ParameterError(
                f"Payload.mass must be a finite number >= 0 [kg]; got {format_value(self.mass)}. Give the mass in kg."
            )
        com = float_array(self.com, "Payload.com", "3 coordinates [m]", error=ParameterError)
        if com.shape != (3,) or not np.all(np.isfinite(com)):
            raise ParameterError(
                f"Payload.com must be 3 finite coordinates [m]; got {format_value(self.com)}. Write [x, y, z]."
            )
        if self.inertia is None:
            return
        inertia = float_array(self.inertia, "Payload.inertia", "a 3x3 matrix [kg m^2]", error=ParameterError)
        if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)):
            raise ParameterError(
                f"Payload.inertia must be a 3x3 matrix of finite numbers [kg m^2] or None; "
                f"got {format_value(self.inertia)}. Give three rows of three numbers."
            )
        if not np.allclose(inertia, inertia.T, rtol=1e-9, atol=1e-12):
            raise ParameterError(
                f"Payload.inertia must be symmetric; got {format_value(inertia)}. Make Ixy, Ixz, Iyz match across the "
                "diagonal."
            )
        problem = inertia_violation(inertia)
        if problem:
            raise ParameterError(f"Payload.inertia {problem}. Give the inertia about the centre of mass in kg m^2.")

    def dynamic_parameters(self) -> np.ndarray:
        """The 10 dynamic parameters of the payload about the last link frame origin."""
        inertia = np.zeros((3, 3)) if self.inertia is None else np.asarray(self.inertia, dtype=float)
        return physical_to_dynamic(float(self.mass), np.asarray(self.com, dtype=float), inertia)


def read_payload(path) -> Payload:
    """Read ``{"mass": .., "com": [..], "inertia": [[..]]}`` (a payload.json or tool.json) into a Payload.

    ``com`` is required for a load (``{"mass": 0}`` is none): read as the flange origin, a virtual cobot's 3 kg tool
    7 cm out went into its links (joints 2, 4, 6 validated 5-15x worse, no warning). ``inertia`` (about the centre
    of mass) defaults to none, a point mass.

    Raises
    ------
    ParameterError
        Naming the file, the field and the fix, when the file is not readable JSON text, is not
        an object, lacks the mass, has an unknown key, or holds a value of the wrong shape or
        outside its range (:meth:`Payload.validate`).
    """
    path = Path(path)
    text = read_text_file(path, what="payload file", error=ParameterError)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParameterError(f"{path.name} must be JSON such as {_EXAMPLE}; got {exc}. Fix the syntax there.") from None
    except RecursionError:
        raise ParameterError(f"{path.name} must be JSON such as {_EXAMPLE}; got nesting too deep. Fix it.") from None
    if not isinstance(data, dict):
        raise ParameterError(f"{path.name} must hold a JSON object such as {_EXAMPLE}; got {format_value(data)}.")
    return payload_from_mapping(data, path.name)


def payload_from_mapping(data: dict, name: str) -> Payload:
    """A Payload from the keys ``mass``, ``com`` and ``inertia`` of a parsed JSON or TOML table named ``name``.

    Raises
    ------
    ParameterError
        Naming ``name``, the field and the fix (as :func:`read_payload`).
    """
    unknown = sorted(set(data) - {"mass", "com", "inertia"})
    if unknown:
        raise ParameterError(
            f"{name} has unknown key(s) {unknown}; allowed keys are ['com', 'inertia', 'mass']. Check the spelling."
        )
    if "mass" not in data:
        raise ParameterError(f"{name}: Payload.mass is missing. Add the mass in kg, e.g. {_EXAMPLE}.")
    mass = _json_numbers(data["mass"], (), name, "mass", '"mass": 2.0 [kg]')
    if "com" not in data and mass > 0:  # read as the flange origin, a 3 kg tool 7 cm out cost a cobot 5-15x its RMSE
        raise ParameterError(
            f"{name}: Payload.com is missing. Add the load's centre of mass in the flange frame [m], "
            f'e.g. {_EXAMPLE} ("com": [0, 0, 0] for a load centred on the flange origin).'
        )
    com = _json_numbers(data.get("com", [0.0, 0.0, 0.0]), (3,), name, "com", '"com": [x, y, z] [m]')
    inertia = data.get("inertia")
    if inertia is not None:
        example = '"inertia": [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]] [kg m^2] or null'
        inertia = tuple(map(tuple, _json_numbers(inertia, (3, 3), name, "inertia", example)))
    payload = Payload(mass=mass, com=tuple(com), inertia=inertia)
    try:
        payload.validate(0)
    except ParameterError as exc:
        raise ParameterError(f"{name}: {exc}") from None
    return payload


_EXAMPLE = '{"mass": 2.0, "com": [0.05, 0.0, 0.05]}'


def _json_numbers(value, shape: tuple, name: str, field: str, example: str):
    """A float (shape ``()``) or nested lists of floats of ``shape`` from JSON, or ParameterError naming the field."""

    def conforms(item, dims) -> bool:
        if not dims:
            return is_real_number(item)
        return isinstance(item, list) and len(item) == dims[0] and all(conforms(x, dims[1:]) for x in item)

    if not conforms(value, shape):
        wanted = "a number" if not shape else "x".join(map(str, shape)) + " numbers (every row complete)"
        raise ParameterError(f"{name}: Payload.{field} must be {wanted}; got {format_value(value)}. Write {example}.")
    try:
        return float(value) if not shape else np.asarray(value, dtype=float).tolist()
    except OverflowError:
        raise ParameterError(
            f"{name}: Payload.{field} must be finite; got a number beyond 1e308. Write {example}."
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
