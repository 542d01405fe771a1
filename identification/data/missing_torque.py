"""Joints whose torque a recording does not measure: a dead sensor channel must not poison the fit.

A controller log may hold a torque column that carries nothing: all zero (the Kinova Gen3's RunTrajectory1 has
``TorqueSm1`` zero throughout while joints 2-7 are measured), constant, or NaN. Fitted as a measurement, such a
column says "no torque on this joint", which the model then tries to explain. :func:`find_missing_torque` marks
those joints (``Recording.missing_torque``: their columns become NaN), and the fit and the validation leave only
those joints' rows of that recording out (``trajectory_data.NormalEquations``: a NaN torque row adds nothing);
the other joints' rows of the same samples still count.

Detected by default: a ``tau`` (or, for recordings of currents, ``current``) column that is NaN in every sample
or the same number in every sample. A column that varies but is known to be wrong is stated by the user:
``Recording(..., missing_torque=((0, "why"),))`` in Python, ``--missing-torque FILE:JOINTS`` on the command line
(:func:`stated_missing_torque`).
"""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import numpy as np

from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, RecordingError

__all__ = ["find_missing_torque", "measured_torque", "missing_torque_messages", "parse_missing_torque",
           "require_torque", "stated_missing_torque"]  # fmt: skip

logger = logging.getLogger(__name__)

OPTION_EXAMPLE = "--missing-torque RunTrajectory1.csv:1 (joints by number or name, e.g. FILE:1,3 or FILE:joint_1)"


def find_missing_torque(recording: Recording) -> Recording:
    """``recording`` with every torque column that carries no measurement marked missing (module docstring).

    The signal judged is ``tau`` when recorded, else ``current``. Raises RecordingError when no joint is measured.
    """
    signal = recording.tau if recording.tau is not None else recording.current
    found = dict(recording.missing_torque)
    for joint in range(recording.n_dof):
        column = signal[:, joint]
        if joint in found or not np.all(np.isfinite(column)) or np.ptp(column) > 0:
            continue
        value = float(column[0])
        found[joint] = "zero in every sample" if value == 0.0 else f"the same value ({value:g}) in every sample"
    if len(found) == recording.n_dof:
        raise RecordingError(
            f"{recording.name or 'recording'}: no joint's torque is measured (every column is "
            f"{'; '.join(sorted(set(found.values())))}). Check the torque columns (--columns), or leave the "
            "recording out."
        )
    if len(found) == len(recording.missing_torque):
        return recording
    return replace(recording, missing_torque=tuple(sorted(found.items())))


def missing_torque_messages(recordings, joint_names, purpose: str) -> list:
    """One sentence per missing joint of each of ``recordings``: the recording, the joint, why, what is left out."""
    return [
        f"{Path(r.name).name if r.name else 'a recording'}: joint {joint + 1} ({joint_names[joint]}) has no torque "
        f"measurement ({why}); that joint's rows of this recording are left out of the {purpose}, the other joints' "
        "rows count"
        for r in recordings
        for joint, why in r.missing_torque
    ]


def parse_missing_torque(values, joint_names) -> dict:
    """``{file name: 0-based joints}`` of ``--missing-torque FILE:JOINTS`` values (joints by 1-based number or name)."""
    out = {}
    for value in values or ():
        path, _, joints = str(value).rpartition(":")
        if not path or not joints:
            raise ParameterError(f"--missing-torque takes FILE:JOINTS; got {value!r}. Write {OPTION_EXAMPLE}.")
        out.setdefault(Path(path).name, set()).update(_joint(j.strip(), joint_names, value) for j in joints.split(","))
    return out


def _joint(text: str, joint_names, value) -> int:
    if text in joint_names:
        return list(joint_names).index(text)
    if text.isdigit() and 1 <= int(text) <= len(joint_names):
        return int(text) - 1
    raise ParameterError(
        f"--missing-torque {value!r}: {text!r} is not a joint; give 1..{len(joint_names)} or a name of "
        f"{list(joint_names)}. Write {OPTION_EXAMPLE}."
    )


def stated_missing_torque(recording: Recording, path, stated: dict) -> Recording:
    """``recording`` with the joints ``stated`` for its file (``parse_missing_torque``) marked missing."""
    joints = stated.get(Path(path).name, ())
    if not joints:
        return recording
    found = dict(recording.missing_torque)
    for joint in sorted(joints):
        found.setdefault(joint, "stated by --missing-torque")
    return replace(recording, missing_torque=tuple(sorted(found.items())))


def require_torque(recording: Recording, joint_names, command: str) -> Recording:
    """``recording`` if every joint's torque is measured; else RecordingError naming the joint, why and the route.

    For the commands that judge every joint of a recording together (``psdm diagnose``).
    """
    recording = find_missing_torque(recording)
    if recording.missing_torque:
        joint, why = recording.missing_torque[0]
        raise RecordingError(
            f"{recording.name or 'recording'}: joint {joint + 1} ({joint_names[joint]}) has no torque measurement "
            f"({why}); psdm {command} needs every joint's torque. Leave the recording out here; psdm identify fits "
            "it with only that joint's rows left out."
        )
    return recording


def measured_torque(recordings, joint_names, purpose: str = "diagnosis") -> tuple:
    """``(recordings, missing joints, messages)`` for a fit that judges every recording's joints together (the
    diagnosis): each recording with its missing columns (``find_missing_torque``) set to zero so that filters and
    derivatives stay finite, the sorted 0-based joints missing in any of them (the caller leaves those joints' rows
    out of every recording, so that a joint is fitted and judged on the same footing), and one sentence per missing
    joint and recording (logged as a warning too)."""
    found = [find_missing_torque(r) for r in recordings]
    messages = [
        f"{Path(r.name).name if r.name else 'a recording'}: joint {joint + 1} ({joint_names[joint]}) has no torque "
        f"measurement ({why}); that joint's rows of every recording are left out of the {purpose} (it is not "
        "diagnosed), the other joints are"
        for r in found
        for joint, why in r.missing_torque
    ]
    for message in messages:
        logger.warning(message)
    missing = sorted({joint for r in found for joint, _ in r.missing_torque})
    out = []
    for r in found:
        if not r.missing_torque:
            out.append(r)
            continue
        key = "tau" if r.tau is not None else "current"
        values = np.array(getattr(r, key), dtype=float)
        values[:, [joint for joint, _ in r.missing_torque]] = 0.0
        out.append(replace(r, **{key: values}, missing_torque=()))
    return out, missing, tuple(messages)
