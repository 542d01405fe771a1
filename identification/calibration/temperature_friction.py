"""A calibrated model's friction along the joints' temperature: the law identify fitted, kept in the model file.

Where identify found the friction of a joint drifting between the training recordings and the logged temperatures
explain it (``drift_choice``, ``temperature_law``), the model keeps the friction at one temperature (the held-out
recordings', else the latest recording's): the ``reference`` of that joint. The file's ``drive.temperature`` block
(optional, any file version, with its own ``version``; older readers ignore it and predict the friction at the
reference temperature) records per such joint that reference, the reach of the line (its training temperatures
widened by half their spread each way, as ``temperature_law`` reads it) and the slope [per °C] of each friction
coefficient (``fc``, ``fs``, ``fv``; the offset and drive inertia do not move). At a joint temperature ``T`` the
coefficient is ``value + slope (clip(T, reach) - reference)``; a temperature not logged (NaN) is the reference.

``CalibratedModel.predict`` adds that change of the friction torque after the findings (a load-dependent friction
scales the torque without it), as ``codegen.temperature_friction`` exports it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psdm_casadi.errors import ModelFileError

__all__ = ["TEMPERATURE_BLOCK_VERSION", "JointTemperature", "TemperatureFriction", "temperature_block"]

#: The version of the ``drive.temperature`` block.
TEMPERATURE_BLOCK_VERSION = 1
#: The coefficients whose slopes the block records (the friction; an offset or a drive inertia does not warm up).
SLOPED_TERMS = ("fc", "fs", "fv")


@dataclass(frozen=True)
class JointTemperature:
    """One joint's friction law: its ``reference`` [°C], the ``reach`` (low, high) [°C] the line is read within and
    ``slopes`` ``{drive name: slope per °C}``; ``joint`` is 0-based."""

    joint: int
    reference: float
    reach: tuple
    slopes: dict

    def to_dict(self) -> dict:
        return {"joint": self.joint + 1, "reference_c": self.reference, "range_c": list(self.reach),
                "slopes_per_c": dict(self.slopes)}  # fmt: skip


@dataclass(frozen=True)
class TemperatureFriction:
    """The friction laws in temperature of a model file (module docstring); ``joints`` of ``JointTemperature``."""

    joints: tuple

    @classmethod
    def from_document(cls, document: dict, name: str = "calibrated model") -> TemperatureFriction | None:
        """The laws of a model file's ``drive.temperature`` block; None without one. Raises ``ModelFileError``
        naming the field for a block that does not parse."""
        block = document.get("drive", {}).get("temperature")
        if not block:
            return None
        names, n_dof = list(document["drive"].get("names", ())), len(document["robot"]["joint_names"])
        try:
            if block["version"] != TEMPERATURE_BLOCK_VERSION:
                raise ValueError(f"version {block['version']!r}, this reader knows {TEMPERATURE_BLOCK_VERSION}")
            joints = []
            for entry in block["joints"]:
                joint, reference = int(entry["joint"]) - 1, float(entry["reference_c"])
                low, high = (float(v) for v in entry["range_c"])
                slopes = {str(k): float(v) for k, v in entry["slopes_per_c"].items()}
                if not 0 <= joint < n_dof or not low <= reference <= high or not np.all(np.isfinite([low, high])):
                    raise ValueError(f"joint {joint + 1}: joint 1..{n_dof}, a finite range holding the reference")
                if any(k not in names or not np.isfinite(v) for k, v in slopes.items()):
                    raise ValueError(f"joint {joint + 1}: slopes must be finite, of drive.names {names}")
                joints.append(JointTemperature(joint, reference, (low, high), slopes))
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFileError(f"{name}: drive.temperature must hold version {TEMPERATURE_BLOCK_VERSION} and per "
                                 "joint its joint, reference_c, range_c [low, high] and slopes_per_c {drive name: "
                                 f"slope}}; got an error ({exc}). Re-run 'psdm identify'.") from None  # fmt: skip
        return cls(tuple(joints))

    def slope_vector(self, names) -> np.ndarray:
        """The slopes [per °C] in the order of the drive ``names`` (0 for a coefficient without one)."""
        slopes = {k: v for joint in self.joints for k, v in joint.slopes.items()}
        return np.array([slopes.get(name, 0.0) for name in names])

    def change(self, temperature, n_dof: int) -> np.ndarray:
        """Each joint's temperature minus its reference [°C], shape (n_samples, n_dof): clipped to the reach, 0 for a
        joint without a law and where ``temperature`` (n_samples, n_dof) is NaN (or is None)."""
        if temperature is None:
            return np.zeros((1, n_dof))
        temperature = np.atleast_2d(np.asarray(temperature, dtype=float))
        out = np.zeros(temperature.shape)
        for joint in self.joints:
            column = np.clip(temperature[:, joint.joint], *joint.reach) - joint.reference
            out[:, joint.joint] = np.where(np.isnan(column), 0.0, column)
        return out

    def torque(self, columns, names, temperature) -> np.ndarray:
        """The change of the friction torque [N m] (n_samples, n_dof) at ``temperature`` from the drive ``columns``
        (n_samples, n_dof, len(names)) of ``trajectory_data.drive_columns``."""
        return (columns @ self.slope_vector(names)) * self.change(temperature, columns.shape[1])

    def sentence(self, temperature, joint_names) -> str:
        """What a judged recording's friction was evaluated at: its logged temperatures, or the reference."""
        logged = temperature is not None
        parts = []
        for joint in self.joints:
            column = None if not logged else np.asarray(temperature)[:, joint.joint]
            if column is None or np.all(np.isnan(column)):
                parts.append(f"{joint_names[joint.joint]} at its reference {joint.reference:.1f} °C (none logged)")
            else:
                low, high = np.nanmin(column), np.nanmax(column)
                clipped = " (clipped to the line's reach)" if low < joint.reach[0] or high > joint.reach[1] else ""
                parts.append(f"{joint_names[joint.joint]} at its logged {low:.1f}-{high:.1f} °C{clipped}")
        return "friction along the joints' temperature (the model file's law): " + "; ".join(parts)


def temperature_block(drift, names) -> dict | None:
    """The ``drive.temperature`` block of a model whose friction identify read along the logged temperature on some
    joints (``drift_choice.FrictionDrift``, its ``kept`` of basis ``"temperature"``), with the slopes of the model's
    drive ``names``; None when no kept friction came from a law."""
    joints = []
    for kept in drift.kept if drift.corrected else ():  # fitted at the kept friction only where corrected to it
        if kept.basis != "temperature" or kept.law is None:
            continue
        law = kept.law
        own = next(f.names for f in drift.check.drifting if f.joint == kept.joint)
        slopes = {name: float(slope) for name, slope in zip(own, law.slopes)
                  if name in names and name.rstrip("0123456789") in SLOPED_TERMS}  # fmt: skip
        half = 0.5 * (max(law.temperatures) - min(law.temperatures))
        reach = (min(law.temperatures) - half, max(law.temperatures) + half)
        if slopes:
            joints.append(JointTemperature(kept.joint, float(law.target), reach, slopes).to_dict())
    if not joints:
        return None
    return {"version": TEMPERATURE_BLOCK_VERSION, "joints": joints,
            "from": "identify's friction drift: each joint's friction as a line in its logged temperature"}  # fmt: skip
