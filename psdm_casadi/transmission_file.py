"""The ``[transmission]`` and ``[recording]`` tables of a robot file: gears, couplings, offsets, recording side.

Read by ``robot_file`` into the robot's ``Transmission`` and ``RecordingLayout``::

    [transmission]
    gear_ratios = [32, 32, 45, -48, 45, 32]          # motor turns per turn of its joint (sign: direction)
    coupling = [{ motor = 6, joint = 5, ratio = 32 }] # motor 6 also turns 32 times per turn of joint 5
    # matrix = [[...], ...]                           # or the whole N_q instead: theta_m = N_q q + offsets
    joint_offsets = [0, "-pi/2", "pi/2", 0, 0, 0]     # q at which the motor encoders read 0 [rad]
    # motor_offsets = [...]                           # or the encoders' readings at q = 0 [rad]
    # motor_kt = [...]                                # motor torque constants [N m/A], for motor currents
    # rated_current = [...]                           # rated currents [A], for currents logged in % of them

    [recording]
    side = "motor"              # or per signal: { q = "motor", qd = "motor", tau = "joint", current = "motor" }
    sample_rate = 5000.0        # [Hz] for files without a t column
    files = { q = "pos_read_data.csv", tau = "curr_data.csv" }   # one file per signal, columns in joint order

Every malformed entry is refused with a RobotFileError naming the file, the field and the fix.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from psdm_casadi.description import DriveParameters
from psdm_casadi.errors import RobotFileError
from psdm_casadi.file_values import file_number, file_vector
from psdm_casadi.recording_layout import SIDES, SIGNALS, RecordingLayout
from psdm_casadi.transmission import Transmission
from psdm_casadi.values import format_value

__all__ = ["drives_with_motor_kt", "layout_from_table", "transmission_from_table"]

_TRANSMISSION_KEYS = {"gear_ratios", "coupling", "matrix", "joint_offsets", "motor_offsets", "motor_kt",
                      "rated_current"}  # fmt: skip
_COUPLING_KEYS = {"motor", "joint", "ratio"}
_RECORDING_KEYS = {"side", "sample_rate", "files"}


def _check_keys(table, allowed, where) -> None:
    if not isinstance(table, dict):
        raise RobotFileError(f"{where} must be a table; got {format_value(table)}. Write it as a TOML table.")
    unknown = sorted(str(key) for key in set(table) - allowed)
    if unknown:
        raise RobotFileError(
            f"{where} has unknown key(s) {unknown}; allowed keys are {sorted(allowed)}. Check the spelling."
        )


def transmission_from_table(table, n: int, where: str) -> Transmission:
    """The Transmission of a ``[transmission]`` table of a robot with ``n`` joints (module docstring).

    Raises
    ------
    RobotFileError
        Naming ``where [transmission].<field>`` and the fix: a list of the wrong length, a gear ratio of 0,
        a coupling of an unknown motor or joint, a singular matrix, both kinds of offsets.
    """
    where = f"{where} [transmission]"
    _check_keys(table, _TRANSMISSION_KEYS, where)
    matrix = _coupling_matrix(table, n, where)
    if "joint_offsets" in table and "motor_offsets" in table:
        raise RobotFileError(
            f"{where} states both joint_offsets and motor_offsets; they say the same thing "
            "(motor_offsets = -N_q joint_offsets). Keep one."
        )
    offsets = None
    if "joint_offsets" in table:
        offsets = file_vector(table["joint_offsets"], n, f"{where}.joint_offsets")
    kt = file_vector(table["motor_kt"], n, f"{where}.motor_kt") if "motor_kt" in table else None
    rated = file_vector(table["rated_current"], n, f"{where}.rated_current") if "rated_current" in table else None
    if rated is not None and np.any(rated <= 0):
        raise RobotFileError(f"{where}.rated_current must be > 0 [A] for every motor; got {format_value(rated)}. "
                             "Give the motors' rated (continuous) currents from their datasheet.")  # fmt: skip
    try:
        transmission = Transmission(coupling=matrix, joint_offsets=offsets, motor_kt=kt, rated_current=rated)
        if "motor_offsets" in table:  # theta_0 = -N_q q_0
            theta_0 = file_vector(table["motor_offsets"], n, f"{where}.motor_offsets")
            transmission = Transmission(matrix, -transmission.joint_rates(theta_0), kt, rated)
        return transmission
    except RobotFileError as exc:
        field = "matrix" if "matrix" in table else "gear_ratios and coupling"
        raise RobotFileError(f"{where}.{field}: {exc}") from None


def _coupling_matrix(table, n, where) -> np.ndarray:
    """``N_q`` from ``matrix``, or from ``gear_ratios`` with the ``coupling`` entries."""
    if "matrix" in table:
        if "gear_ratios" in table or "coupling" in table:
            raise RobotFileError(
                f"{where} states matrix together with gear_ratios or coupling; the matrix holds them all. "
                "Keep either matrix, or gear_ratios (with coupling)."
            )
        rows = table["matrix"]
        if not isinstance(rows, list) or len(rows) != n:
            raise RobotFileError(
                f"{where}.matrix must be {n} rows (one per motor) of {n} numbers; got {format_value(rows)}. "
                "Fix the matrix."
            )
        return np.array([file_vector(row, n, f"{where}.matrix[{i}]") for i, row in enumerate(rows)])
    if "gear_ratios" not in table:
        raise RobotFileError(
            f"{where}.gear_ratios is missing. Add gear_ratios = [...] ({n} numbers, motor turns per joint turn), "
            "or the whole matrix = [[...], ...]."
        )
    ratios = file_vector(table["gear_ratios"], n, f"{where}.gear_ratios")
    if np.any(ratios == 0):
        k = int(np.flatnonzero(ratios == 0)[0])
        raise RobotFileError(
            f"{where}.gear_ratios[{k}] must not be 0 (joint {k + 1} would not move its motor); got 0. "
            "Give the motor turns per joint turn (negative if the motor turns the other way)."
        )
    matrix = np.diag(ratios)
    entries = table.get("coupling", [])
    if not isinstance(entries, list):
        raise RobotFileError(
            f"{where}.coupling must be a list of tables; got {format_value(entries)}. "
            "Write coupling = [{ motor = 6, joint = 5, ratio = 32 }]."
        )
    for k, entry in enumerate(entries):
        ewhere = f"{where}.coupling[{k}]"
        _check_keys(entry, _COUPLING_KEYS, ewhere)
        motor, joint = (_index(entry.get(key), n, f"{ewhere}.{key}") for key in ("motor", "joint"))
        if motor == joint:
            raise RobotFileError(
                f"{ewhere} couples motor {motor + 1} with its own joint; that is its gear ratio. "
                "Set it in gear_ratios, or name another joint."
            )
        if "ratio" not in entry:
            raise RobotFileError(f"{ewhere}.ratio is missing. Add ratio = <motor turns per turn of the joint>.")
        matrix[motor, joint] = file_number(entry["ratio"], f"{ewhere}.ratio")
    return matrix


def _index(value, n, where) -> int:
    if not (isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= n):
        raise RobotFileError(f"{where} must be a number 1..{n} (1-based); got {format_value(value)}. Fix it.")
    return value - 1


def layout_from_table(table, n: int, where: str, transmission: Transmission | None) -> RecordingLayout:
    """The RecordingLayout of a ``[recording]`` table; motor-side signals need a ``[transmission]``.

    Raises
    ------
    RobotFileError
        Naming ``where [recording].<field>`` and the fix.
    """
    where = f"{where} [recording]"
    _check_keys(table, _RECORDING_KEYS, where)
    side = table.get("side", "joint")
    if isinstance(side, str):
        sides = dict.fromkeys(SIGNALS, side)
    elif isinstance(side, dict):
        sides = dict(side)
    else:
        sides = {"": side}
    if any(s not in SIGNALS or v not in SIDES for s, v in sides.items()):
        raise RobotFileError(
            f'{where}.side must be "joint", "motor", or a table of signals {list(SIGNALS)} with those values; got '
            f'{format_value(side)}. Write side = "motor" or side = {{ q = "motor", tau = "joint" }}.'
        )
    if "motor" in sides.values() and transmission is None:
        raise RobotFileError(
            f"{where}.side says signals are recorded on the motor side, but the robot file has no [transmission] "
            "table to map them to the joints. Add [transmission] with gear_ratios = [...]."
        )
    rate = None
    if "sample_rate" in table:
        rate = file_number(table["sample_rate"], f"{where}.sample_rate", "Give the samples per second [Hz].")
        if rate <= 0:
            raise RobotFileError(f"{where}.sample_rate must be > 0 [Hz]; got {format_value(rate)}. Fix the value.")
    files = table.get("files", {})
    if not isinstance(files, dict) or not all(isinstance(v, str) and v.strip() for v in files.values()):
        raise RobotFileError(
            f"{where}.files must be a table of file names per signal; got {format_value(files)}. Write files = "
            '{ q = "positions.csv", tau = "torques.csv" }.'
        )
    try:
        return RecordingLayout(sides=sides, sample_rate=rate, files=tuple(files.items()))
    except RobotFileError as exc:
        raise RobotFileError(f"{where}: {exc}") from None


def drives_with_motor_kt(drives, tables, transmission: Transmission | None, layout: RecordingLayout | None, where: str):
    """The robot's drives holding the joint-side torque constants of motor currents (``Transmission.joint_kt``).

    Currents logged on the motor side (``[recording] side``) of an uncoupled transmission with ``motor_kt`` stay
    currents, signed like their joint (``motor_side.to_joint_side``), so every command treats them as currents: their
    torque holds the rotors' inertia and the gears' loss. Mapped to joint torques instead, they were read as a torque
    sensor's and a rotor inertia the data want small was dropped (a virtual 7-joint cobot: joint 7's validation RMSE
    0.058 N m against 0.033 N m with the same constants stated as [[drive]] kt). The drives take ``|N_ii| kt_m`` as
    their ``kt`` (drives with no friction where the file has no [[drive]] tables); a [[drive]] kt the file states
    must agree.

    Raises
    ------
    RobotFileError
        A [[drive]] table's ``kt`` that is not the joint-side constant ``|gear ratio| x motor_kt``, naming both.
    """
    kt = None if transmission is None else transmission.joint_kt
    if kt is None or layout is None or layout.side("current") != "motor":
        return drives
    if drives is None:
        return tuple(DriveParameters(kt=float(k)) for k in kt)
    out = []
    for i, (drive, table) in enumerate(zip(drives, tables)):
        if "kt" in table and not math.isclose(drive.kt, kt[i], rel_tol=1e-9):
            ratio, motor = abs(float(transmission.gear_ratios[i])), float(transmission.motor_kt[i])
            raise RobotFileError(
                f"{where} drive[{i + 1}].kt = {drive.kt:g} N m/A disagrees with the [transmission] of joint {i + 1}: "
                f"motor currents on the motor side give the joint |gear ratio| x motor_kt = {ratio:g} x {motor:g} = "
                f"{kt[i]:g} N m/A (a [[drive]] kt is the joint's constant, joint torque per motor ampere). Remove kt "
                f"from the [[drive]] tables, or set it to {kt[i]:g}."
            )
        out.append(replace(drive, kt=float(kt[i])))
    return tuple(out)
