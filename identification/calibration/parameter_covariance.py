"""The covariance of a calibrated model's base and drive parameters in its file: written by identify, read by the
checks that allow for the model's own error (the flange payload check, ``payload_check.model_columns``).

It is the covariance of the parameters as written (``TrajectoryFit.covariance``): of a least-squares fit, whose
``base.std`` and ``drive.std`` are its diagonal, or of a consistent fit, the least squares' with the pull towards the
robot file's precision added (``consistent_covariance``; narrower than those standard deviations, which stay the least
squares'). The parameters of one fit are correlated (a link's mass
and its first moments share the gravity torque; a drive inertia and the link it turns), and the error of the model's
torque prediction is the sum of their errors along each sample's columns, in which correlated errors partly cancel:
propagated as if independent, the standard deviations alone state the flange check's spread too wide (virtual Denso,
30 calibrations x recordings with a 0.8 kg load: RMS z 0.72, and 1.03 from the covariance). The block ``covariance``
holds the whole matrix:

- ``parameters``: ``"base then drive"`` (the order of ``base.names`` then ``drive.names``);
- ``size``: their number, n;
- ``lower``: its lower triangle row by row (n (n + 1) / 2 numbers; ``null`` for a parameter without one).

The block is optional in any version: a file without it (written before it, or by hand) reads as before, and the
checks fall back to the standard deviations as independent (:func:`stated_covariance`).
"""

from __future__ import annotations

import numpy as np

from psdm_casadi.errors import ModelFileError

__all__ = ["check_covariance_block", "covariance_block", "stated_covariance"]

PARAMETERS = "base then drive"


def covariance_block(fit) -> dict:
    """``{"covariance": block}`` of a ``TrajectoryFit`` (its ``covariance``), or {} when the fit has none."""
    covariance = getattr(fit, "covariance", None)
    if covariance is None:
        return {}
    covariance = np.asarray(covariance, dtype=float)
    lower = covariance[np.tril_indices(covariance.shape[0])]
    values = [None if not np.isfinite(v) else float(v) for v in lower]
    return {"covariance": {"parameters": PARAMETERS, "size": int(covariance.shape[0]), "lower": values}}


def stated_covariance(document: dict, size: int) -> np.ndarray | None:
    """The covariance (size, size) of the base then drive parameters the file states, None when it states none or one
    of another size (the parameters' standard deviations are then all there is). A missing entry (``null``) reads
    as 0."""
    block = document.get("covariance")
    if block is None or block.get("size") != size:
        return None
    out = np.zeros((size, size))
    out[np.tril_indices(size)] = [0.0 if v is None else float(v) for v in block["lower"]]
    return out + np.tril(out, -1).T


def check_covariance_block(name: str, document: dict) -> None:
    """Refuse a ``covariance`` block that is not one this module writes (``model_file_check``).

    Raises
    ------
    ModelFileError
        Naming the file, the field and the fix.
    """
    block = document.get("covariance")
    if block is None:
        return
    size = len(document["base"].get("names", [])) + len(document["drive"].get("names", []))
    fix = "Remove the block (the checks then use the standard deviations) or re-run 'psdm identify'."
    if not isinstance(block, dict) or block.get("parameters") != PARAMETERS or block.get("size") != size:
        raise ModelFileError(f"{name}: covariance must be an object with parameters {PARAMETERS!r} and size {size} "
                             f"(the base then drive parameters); got {repr(block)[:80]}. {fix}")  # fmt: skip
    lower = block.get("lower")
    if not isinstance(lower, list) or len(lower) != size * (size + 1) // 2:
        got = type(lower).__name__ if not isinstance(lower, list) else f"{len(lower)} entries"
        raise ModelFileError(f"{name}: covariance.lower must be a list of {size * (size + 1) // 2} numbers (the lower "
                             f"triangle row by row); got {got}. {fix}")  # fmt: skip
    bad = [v for v in lower if not (v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)))]
    if bad:
        raise ModelFileError(f"{name}: covariance.lower must hold numbers or null; got {repr(bad[0])[:40]}. {fix}")
