"""The checks every file export of a calibrated model makes (URDF, MJCF), and its atomic write.

A target file holds the model's standard parameters, so a model identified without them (``--no-consistency``)
cannot be written; a model whose standard parameters are not physically consistent is written only when asked
(``allow_inconsistent``; the file then says so). The file is written atomically and never replaces an existing one
without ``overwrite``.
"""

from __future__ import annotations

import numpy as np

from psdm_casadi.errors import ModelFileError
from psdm_casadi.fileio import atomic_write

__all__ = ["require_standard", "write_model"]


def require_standard(calibrated, what: str):
    """``calibrated.standard``, refused (``ModelFileError``) when not finite; ``what`` names the format (``MJCF``)."""
    standard = calibrated.standard
    if not np.all(np.isfinite(standard)):
        raise ModelFileError(
            f"CalibratedModel.standard must hold finite standard parameters to write {what}; got none (the model "
            "was identified with --no-consistency: base parameters only). Re-run 'psdm identify' without it."
        )
    return standard


def write_model(calibrated, path, render, what: str, overwrite: bool, allow_inconsistent: bool):
    """Write ``render(calibrated)`` to ``path`` atomically and return ``path``; an inconsistent model without
    ``allow_inconsistent`` is refused (``ModelFileError`` naming the smallest pseudo-inertia eigenvalue)."""
    if not calibrated.consistent and not allow_inconsistent:
        raise ModelFileError(
            f"the calibrated model is not physically consistent (smallest pseudo-inertia eigenvalue "
            f"{calibrated.document['standard']['min_pseudo_inertia_eigenvalue']}); no {what} was written to "
            f"{str(path)!r}. Pass --allow-inconsistent to write it marked as such."
        )
    text = render(calibrated)
    return atomic_write(path, lambda handle: handle.write(text), overwrite)
