"""A spring finding's rest angle in a model file: where its torque, with the torque offset that holds its constant, is
zero.

A spring's columns end in a constant (``c_N``), and a torque offset on the same joint (the drive's ``offsetN``) is the
same column: a fit keeps one and reports the other absorbed (``findings.filled_entries``: an absorbed feature counts
0). The rest angle a user compares with a datasheet is the root of the whole torque, so it is computed with whichever
of the two holds the constant: the spring's own, or the joint's offset where ``c_N`` is absorbed. That offset also
holds any sensor offset of the joint; the two cannot be told apart, and the note says which constant was used.
"""

from __future__ import annotations

import numpy as np

from identification.calibration.findings import FindingTerm
from identification.calibration.trajectory_data import drive_offset

__all__ = ["rest_angle_text", "with_rest_angles"]


def with_rest_angles(entries, drive: dict | None) -> list:
    """``entries`` (a model file's findings) with each spring's ``parameters.rest_angle`` [rad] and
    ``parameters.rest_angle_offset`` (the joint's torque offset counted, N m; 0 when the constant is the spring's)."""
    out, block = [], drive or {}
    for entry in entries:
        if entry.get("kind") == "torque" and entry.get("effect") == "spring" and entry.get("coefficients"):
            term = FindingTerm.from_dict(entry["term"])
            candidate = term.candidate
            c = [0.0 if v is None else float(v) for v in entry["coefficients"]]
            absorbed = f"c_{term.joint + 1}" in (entry.get("absorbed") or ())
            offset = drive_offset(block.get("values") or [], block.get("names") or [], term.joint) if absorbed else 0.0
            if candidate is None:  # a linear spring stored without a spec: k q + c
                rest = -(c[1] + offset) / c[0] if c[0] else None
            elif hasattr(candidate, "rest_angle"):  # a polynomial law; a gas spring's lever law states its own q0
                rest = candidate.rest_angle(c, offset)
            else:
                rest = None
            if rest is not None and np.isfinite(rest):
                entry = {**entry, "parameters": {**entry.get("parameters", {}), "rest_angle": float(rest),
                                                 "rest_angle_offset": offset}}  # fmt: skip
        out.append(entry)
    return out


def rest_angle_text(entry: dict) -> str:
    """``", zero torque at q = 0.401 rad (with joint 4's torque offset -2.986 N m, which holds its constant)"`` of a
    spring entry with a rest angle; empty without one."""
    parameters = entry.get("parameters") or {}
    if "rest_angle" not in parameters:
        return ""
    offset = float(parameters.get("rest_angle_offset", 0.0))
    joint = (entry.get("joints") or ["?"])[0]
    held = f" (with joint {joint}'s torque offset {offset:.4g} N m, which holds its constant)" if offset else ""
    return f", zero torque at q = {parameters['rest_angle']:.4g} rad{held}"
