"""What identify's counterbalance choice recorded in a calibrated-model file, read back by the commands that use it.

``psdm identify`` stores its ``CounterbalanceChoice`` in the file (``identification.counterbalance``: the joints it
named, by what, and whether the spring it tried was kept). A torque offset the data chose that identify read as no
sensor's (``offset_reading``: a share of the joint's gravity torque and recorded peak no zero error has) is named by
``counterbalance_column.BY_OFFSET``. Where the spring tried in its place was not kept (its shape, fitted over the
training range, did not hold on the held-out motion: the heavy virtual arm at seed 0, whose held-out recording takes
joint 2 to three times the training's swing), the file keeps that offset as identify's stand-in for the
counterbalance. ``diagnose MODEL`` then does not hold it as a sensor's zero (``HeldFriction.without_offsets``): held,
the torque is carried silently and no finding names it; left to the diagnosis, it is judged as any candidate (out of
sample, with its second opinion) and named (``diagnosis.counterbalance_naming``).
"""

from __future__ import annotations

from identification.calibration.counterbalance_column import BY_OFFSET

__all__ = ["counterbalance_offsets"]


def counterbalance_offsets(document: dict) -> tuple:
    """0-based joints whose torque offset a calibrated-model ``document`` holds and identify read as no sensor's
    (named by ``BY_OFFSET``; a kept spring took the offset's place, so the file's offset there is 0). Files without
    the record: none."""
    named = ((document.get("identification") or {}).get("counterbalance") or {}).get("named_by") or {}
    return tuple(sorted(int(joint) - 1 for joint, by in named.items() if by == BY_OFFSET))
