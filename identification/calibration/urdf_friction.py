"""What of a calibrated model's friction a URDF cannot hold (``urdf_export``): the Stribeck hump, the LuGre bristles.

URDF ``<dynamics>`` has Coulomb friction and viscous damping only; ``urdf_export`` writes ``fc`` and ``fv`` (the
sliding level and the viscous slope), and these functions name what is left out, for the per-joint comments and
the warning ``psdm export-urdf`` prints.
"""

from __future__ import annotations

from psdm_casadi.values import exact_text

__all__ = ["friction_left_out", "friction_not_representable"]


def friction_left_out(calibrated) -> list | None:
    """Per joint, the friction values URDF cannot hold (``"fs = .., vs = .."``, LuGre: also sigma0, sigma1)."""
    lugre = calibrated.lugre_parameters
    if lugre is not None:
        names = ("fs", "vs", "sigma0", "sigma1")
        return [", ".join(f"{name} = {exact_text(getattr(p, name))}" for name in names) for p in lugre]
    drive = calibrated.document["drive"]
    if "fs" not in drive["friction_terms"]:
        return None
    values = dict(zip(drive["names"], calibrated.drive))
    return [
        f"fs = {exact_text(values[f'fs{j + 1}'])}, vs = {exact_text(v)}"
        for j, v in enumerate(drive["stribeck_velocity"])
    ]


def friction_not_representable(calibrated) -> str | None:
    """The warning for a model whose friction URDF cannot hold (module docstring), or None (Coulomb + viscous)."""
    if friction_left_out(calibrated) is None:
        return None
    shape = "LuGre" if calibrated.lugre_parameters is not None else "Stribeck"
    dynamics = " and the bristle dynamics (sigma0, sigma1)" if shape == "LuGre" else ""
    return (
        f"the model's friction is {shape}; URDF <dynamics> holds only Coulomb friction and viscous damping, so "
        f"friction = fc (the sliding level) and damping = fv are written, and the static hump (fs, vs){dynamics} "
        "are NOT in the URDF (their values are in a comment on each joint)"
    )
