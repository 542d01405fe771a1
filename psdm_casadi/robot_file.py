"""Robot files: the ``psdm-robot/1`` TOML reader (DH rows or a URDF reference) and the built-in robots.

``load_robot`` turns a file, or the name of a robot shipped in ``psdm_casadi/robots``, into a
RobotDescription. Every malformed entry raises a RobotFileError naming the file, the table, the row
and the fix: unreadable or non-text files, a value of the wrong kind, NaN or infinite numbers,
unphysical inertia, duplicate joint names. Numbers may be written as small expressions of ``pi``
(``"-pi/2"``). A robot file with a ``[urdf]`` table takes its joints and inertia from the URDF and
may override the URDF's limits per joint (``[urdf.limits.<joint>]``) and inertials per link (``[[link]]`` tables
naming the URDF link: ``link_overrides``), and add ``[[drive]]`` tables.
"""

from __future__ import annotations

import logging
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np
import tomllib

from psdm_casadi.description import (
    CONVENTIONS,
    GRAVITY_STANDARD,
    JOINT_KINDS,
    DriveParameters,
    Joint,
    LinkInertia,
    RobotDescription,
    locked_positions,
)
from psdm_casadi.errors import RobotFileError
from psdm_casadi.file_values import file_number as _number
from psdm_casadi.file_values import file_vector as _vector
from psdm_casadi.link_envelope import LinkEnvelope
from psdm_casadi.link_overrides import apply_link_overrides
from psdm_casadi.mjcf import MJCF_SUFFIXES
from psdm_casadi.said_once import say
from psdm_casadi.text_file import read_text_file
from psdm_casadi.transmission_file import drives_with_motor_kt, layout_from_table, transmission_from_table
from psdm_casadi.urdf import from_urdf
from psdm_casadi.values import format_value

logger = logging.getLogger(__name__)

ROBOT_FORMAT = "psdm-robot/1"
#: The format of a robot file with link envelopes (``envelope`` in ``[[link]]`` tables); it reads version 1 too.
ROBOT_FORMAT_ENVELOPES = "psdm-robot/2"


def _table(value, where: str, example: str) -> dict:
    if not isinstance(value, dict):
        raise RobotFileError(f"{where} must be a table; got {format_value(value)}. Write it as {example}.")
    return value


def _tables(value, n, where: str, header: str, per: str) -> list:
    """An array of n tables (``[[link]]`` ...), checked for its length and the kind of each entry."""
    if not isinstance(value, list) or len(value) != n:
        got = f"{len(value)} tables" if isinstance(value, list) else format_value(value)
        raise RobotFileError(f"{where}: needs exactly {n} {header} tables ({per}) or none; got {got}.")
    for i, table in enumerate(value):
        _table(table, f"{where} {header[2:-2]}[{i + 1}]", f"a {header} table")
    return value


def _string(value, where: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise RobotFileError(f'{where} must be a non-empty string; got {format_value(value)}. Write it in "quotes".')
    return value


def _strings(value, where: str) -> tuple:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise RobotFileError(f'{where} must be a list of strings; got {format_value(value)}. Write ["a", "b"].')
    return tuple(value)


def _check_keys(table: dict, allowed: set, where: str):
    unknown = sorted(str(key) for key in set(table) - allowed)
    if unknown:
        raise RobotFileError(
            f"{where} has unknown key(s) {unknown}; allowed keys are {sorted(allowed)}. Check the spelling."
        )


@contextmanager
def _within(where: str):
    """Prefix the file and row to the errors of the value classes (Joint, LinkInertia, ...)."""
    try:
        yield
    except RobotFileError as exc:
        raise RobotFileError(f"{where}: {exc}") from None


_LIMIT_KEYS = {"q_min", "q_max", "qd_max", "qdd_max", "tau_max"}
_JOINT_KEYS = {"name", "type", "a", "alpha", "d", "theta"} | _LIMIT_KEYS
_LINK_KEYS = {"mass", "com", "inertia", "rotor_inertia", "envelope"}
_ENVELOPE_KEYS = {"center", "semi_axes", "half_extents", "rpy"}
_ENVELOPE_EXAMPLE = "envelope = { center = [0.1, 0, 0], semi_axes = [0.25, 0.08, 0.08] } (or half_extents = [...])"
_DRIVE_KEYS = {"kt", "fc", "fs", "vs", "fv", "dv", "sigma0", "sigma1"}
_TOP_KEYS = {"format", "name", "convention", "gravity", "joint", "link", "drive", "assumptions", "urdf", "description",
             "transmission", "recording"}  # fmt: skip
_ASSUMPTION_KEYS = {"drive_inertia", "massless_links", "zero_parameters"}
_URDF_KEYS = {"path", "locked_joints", "limits"}
_TAU_MAX_FIX = "Give the limit in N m (N for a prismatic joint), or leave tau_max out for no torque limit."


#: The robot files that ship with the package, found by name (``load_robot("denso_vs6556g")``).
BUILTIN_ROBOTS_DIR = Path(__file__).resolve().parent / "robots"


def builtin_robot_names() -> list[str]:
    """Names of the built-in robot files, for ``load_robot(name)`` and ``psdm ... NAME``."""
    return sorted(p.stem for p in BUILTIN_ROBOTS_DIR.glob("*.toml"))


def resolve_robot_path(path) -> Path:
    """The file a robot argument names: an existing path, or the name of a built-in robot."""
    candidate = Path(path)
    try:
        exists = candidate.exists()
    except (OSError, ValueError):  # a name with a NUL byte, or too long for the file system
        exists = False
    if exists:
        return candidate
    if candidate.parent == Path(".") and candidate.stem in builtin_robot_names() and candidate.suffix in ("", ".toml"):
        return BUILTIN_ROBOTS_DIR / f"{candidate.stem}.toml"
    raise RobotFileError(
        f"robot file {format_value(str(path))} does not exist. Check the path, or name a built-in robot: "
        f"{', '.join(builtin_robot_names())}."
    )


def load_robot(path, locked_joints=()) -> RobotDescription:
    """Read a robot file: ``.toml`` (DH rows or a ``[urdf]`` table), ``.urdf`` or MJCF ``.xml``, or a built-in robot.

    Parameters
    ----------
    path : str or Path
        A file, or the name of a built-in robot (:func:`builtin_robot_names`).
    locked_joints : sequence of str or (str, float), or mapping str -> float
        Further joints to fix at a position [rad or m] (a bare name: 0), for robots read from a URDF
        (``.urdf``, or a ``[urdf]`` table, whose own ``locked_joints`` they join; a value given here
        replaces the file's for the same joint). Robots of DH rows cannot lock joints.

    Returns
    -------
    RobotDescription

    Raises
    ------
    RobotFileError
        Naming the file, the field, the row and the fix, for a file that cannot be read as text,
        for every malformed entry, and for joints locked on a robot of DH rows.
    """
    path = resolve_robot_path(path)
    suffix = path.suffix.lower()
    if suffix in (".urdf", *MJCF_SUFFIXES):
        return from_urdf(path, locked_joints=locked_joints)
    if suffix != ".toml":
        raise RobotFileError(_calibrated_model_text(path) or (
            f"robot file {path.name!r} must end in .toml, .urdf or .xml (MJCF); got {suffix!r}. Rename it or "
            "convert it."
        ))  # fmt: skip
    text = read_text_file(path, what="robot file")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RobotFileError(f"{path.name} must be valid TOML; got {exc}. Fix the syntax at that line.") from None
    except RecursionError:
        raise RobotFileError(
            f"{path.name} must be valid TOML; got arrays or tables nested too deeply. Fix the syntax."
        ) from None
    return robot_from_mapping(data, source=path, locked_joints=locked_joints)


def robot_from_mapping(data: dict, source: Path | None = None, locked_joints=()) -> RobotDescription:
    """Build a RobotDescription from the parsed contents of a robot TOML file (``locked_joints`` as in ``load_robot``).

    Raises
    ------
    RobotFileError
        Naming the file (``source``), the table, the row and the fix, for every malformed entry.
    """
    where = source.name if source is not None else "robot file"
    _table(data, where, "a TOML document")
    _check_keys(data, _TOP_KEYS, where)
    fmt = data.get("format", ROBOT_FORMAT)
    if fmt not in (ROBOT_FORMAT, ROBOT_FORMAT_ENVELOPES):
        raise RobotFileError(
            f"{where}: format must be {ROBOT_FORMAT!r} (or {ROBOT_FORMAT_ENVELOPES!r} with link envelopes); got "
            f"{format_value(fmt)}. Convert the file or fix the line."
        )
    assumptions = _table(data.get("assumptions", {}), f"{where} [assumptions]", "an [assumptions] table")
    _check_keys(assumptions, _ASSUMPTION_KEYS, f"{where} [assumptions]")
    extra_locks = locked_positions(locked_joints)
    if "urdf" in data:
        return _robot_from_urdf_table(data, assumptions, source, where, extra_locks)
    if extra_locks:
        raise RobotFileError(
            f"{where}: joints can be locked only on a robot read from a URDF; this robot has DH rows (got a lock "
            f"of {extra_locks[0][0]!r}). Remove the lock, or describe the robot by a URDF ([urdf] table)."
        )
    joint_tables = data.get("joint")
    if not isinstance(joint_tables, list) or not joint_tables:
        raise RobotFileError(f"{where}: needs at least one [[joint]] table with a DH row (a, alpha, d, theta).")
    joints = _joints_from_tables(joint_tables, where)
    n = len(joints)
    gravity = _vector(data.get("gravity", [0, 0, -GRAVITY_STANDARD]), 3, f"{where} gravity")
    links, rotor = _links_from_tables(data.get("link"), n, where)
    envelopes = _envelopes_from_tables(data.get("link"), n, where, fmt)
    drives = _drives_from_tables(data.get("drive"), n, where)
    name = _string(data["name"], f"{where} name") if "name" in data else (source.stem if source else "robot")
    convention = _convention(data.get("convention", "standard"), where)
    assumed = {**_assumed(assumptions, n, where), **_motor_side(data, n, where)}
    drives = _drives_with_motor_kt(drives, data, assumed, where)
    with _within(where):
        return RobotDescription(
            name=name,
            joints=tuple(joints),
            convention=convention,
            gravity=gravity,
            links=links,
            rotor_inertia=rotor,
            drives=drives,
            source=None if source is None else str(source),
            envelopes=envelopes,
            **assumed,
        )


def _assumed(assumptions: dict, n: int, where: str) -> dict:
    """The RobotDescription fields of the ``[assumptions]`` table."""
    return {
        "drive_inertia": _drive_flags(assumptions.get("drive_inertia", False), n, where),
        "massless_links": _massless(assumptions.get("massless_links", []), n, where),
        "zero_parameters": _strings(assumptions.get("zero_parameters", []), f"{where} [assumptions].zero_parameters"),
    }


def _motor_side(data: dict, n: int, where: str) -> dict:
    """The RobotDescription fields of the ``[transmission]`` and ``[recording]`` tables (``transmission_file``)."""
    transmission = transmission_from_table(data["transmission"], n, where) if "transmission" in data else None
    layout = layout_from_table(data["recording"], n, where, transmission) if "recording" in data else None
    return {"transmission": transmission, "recording_layout": layout}


def _drives_with_motor_kt(drives, data: dict, assumed: dict, where: str):
    """``drives`` with the joint-side torque constants of motor currents (``drives_with_motor_kt``)."""
    tables = data.get("drive") or [{}] * len(drives or ())
    return drives_with_motor_kt(drives, tables, assumed["transmission"], assumed["recording_layout"], where)


def _joints_from_tables(tables, where) -> list:
    joints, rows = [], {}
    for i, table in enumerate(tables):
        jwhere = f"{where} joint[{i + 1}]"
        _check_keys(_table(table, jwhere, "a [[joint]] table"), _JOINT_KEYS, jwhere)
        for key in ("a", "alpha", "d", "theta"):
            if key not in table:
                raise RobotFileError(f"{jwhere}.{key} is missing. Add {key} = <number> to the DH row (0 if absent).")
        kwargs = {
            k: _number(table[k], f"{jwhere}.{k}", _TAU_MAX_FIX if k == "tau_max" else "Give a finite value.")
            for k in sorted(_JOINT_KEYS - {"name", "type"})
            if k in table
        }
        kind = table.get("type", "revolute")
        if kind not in JOINT_KINDS:
            raise RobotFileError(
                f'{jwhere}.type must be "revolute" or "prismatic"; got {format_value(kind)}. Fix the joint type.'
            )
        name = _string(table["name"], f"{jwhere}.name") if "name" in table else f"joint{i + 1}"
        if name in rows:
            raise RobotFileError(
                f"{jwhere}.name must differ from the other joints' names; got {name!r}, the name of "
                f"joint[{rows[name] + 1}] too. Rename one of them."
            )
        rows[name] = i
        with _within(jwhere):
            joints.append(Joint(name=name, kind=kind, **kwargs))
    return joints


def _convention(value, where):
    if value not in CONVENTIONS:
        raise RobotFileError(
            f'{where}: convention must be "standard" or "modified"; got {format_value(value)}. Fix the line.'
        )
    return value


def _drive_flags(value, n, where):
    if isinstance(value, bool):
        return (value,) * n
    if isinstance(value, list) and len(value) == n and all(isinstance(v, bool) for v in value):
        return tuple(value)
    raise RobotFileError(
        f"{where} [assumptions].drive_inertia must be true, false or a list of {n} booleans; "
        f"got {format_value(value)}. Fix the line."
    )


def _massless(value, n, where):
    if not isinstance(value, list) or not all(
        isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= n for v in value
    ):
        raise RobotFileError(
            f"{where} [assumptions].massless_links must be a list of link numbers 1..{n}; "
            f"got {format_value(value)}. Fix the list."
        )
    return tuple(value)


def _links_from_tables(tables, n, where):
    if tables is None:
        return None, None
    links, rotor = [], []
    for i, table in enumerate(_tables(tables, n, where, "[[link]]", "one per joint")):
        lwhere = f"{where} link[{i + 1}]"
        _check_keys(table, _LINK_KEYS, lwhere)
        mass = _number(table.get("mass", 0.0), f"{lwhere}.mass", "Give the mass in kg.")
        if mass < 0:
            raise RobotFileError(f"{lwhere}.mass must be >= 0 [kg]; got {format_value(mass)}. Give the mass in kg.")
        com = _vector(table.get("com", [0, 0, 0]), 3, f"{lwhere}.com")
        inertia = _vector(table.get("inertia", [0] * 6), 6, f"{lwhere}.inertia ([Ixx, Iyy, Izz, Ixy, Ixz, Iyz])")
        with _within(lwhere):
            links.append(LinkInertia(mass=mass, com=com, inertia=inertia))
        rotor.append(_number(table.get("rotor_inertia", 0.0), f"{lwhere}.rotor_inertia", "Give it in kg m^2."))
        if rotor[-1] < 0:
            raise RobotFileError(
                f"{lwhere}.rotor_inertia must be >= 0 [kg m^2]; got {format_value(rotor[-1])}. Fix the sign."
            )
    return tuple(links), np.array(rotor)


def _envelopes_from_tables(tables, n, where, fmt):
    """Per link, the ``envelope`` of its ``[[link]]`` table (an ellipsoid, or a box's half extents), or None."""
    if tables is None or not any(isinstance(t, dict) and "envelope" in t for t in tables):
        return None
    out = []
    for i, table in enumerate(tables):
        ewhere = f"{where} link[{i + 1}].envelope"
        if "envelope" not in table:
            out.append(None)
            continue
        if fmt != ROBOT_FORMAT_ENVELOPES:
            raise RobotFileError(
                f"{ewhere} needs format = {ROBOT_FORMAT_ENVELOPES!r} (a file with link envelopes); got "
                f"{format_value(fmt)}. Write format = {ROBOT_FORMAT_ENVELOPES!r} at the top of the file."
            )
        table = _table(table["envelope"], ewhere, _ENVELOPE_EXAMPLE)
        _check_keys(table, _ENVELOPE_KEYS, ewhere)
        if ("semi_axes" in table) == ("half_extents" in table) or "center" not in table:
            raise RobotFileError(
                f"{ewhere} must give center and one of semi_axes (an ellipsoid) or half_extents (a box) [m], in the "
                f"link frame; got keys {sorted(table)}. For example {_ENVELOPE_EXAMPLE}."
            )
        size = "semi_axes" if "semi_axes" in table else "half_extents"
        center, axes = _vector(table["center"], 3, f"{ewhere}.center"), _vector(table[size], 3, f"{ewhere}.{size}")
        rpy = _vector(table.get("rpy", [0, 0, 0]), 3, f"{ewhere}.rpy")
        with _within(ewhere):
            make = LinkEnvelope if size == "semi_axes" else LinkEnvelope.from_box
            out.append(make(center, axes, _rotation(rpy), "robot file"))
    return tuple(out)


def _rotation(rpy) -> np.ndarray:
    """The rotation of roll, pitch, yaw angles [rad] (URDF's convention: ``Rz(yaw) Ry(pitch) Rx(roll)``)."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])  # fmt: skip


def _drives_from_tables(tables, n, where):
    if tables is None:
        return None
    drives = []
    for i, table in enumerate(_tables(tables, n, where, "[[drive]]", "one per joint")):
        dwhere = f"{where} drive[{i + 1}]"
        _check_keys(table, _DRIVE_KEYS, dwhere)
        values = {k: _number(v, f"{dwhere}.{k}") for k, v in table.items()}
        with _within(dwhere):
            drives.append(DriveParameters(**values))
    return tuple(drives)


def _robot_from_urdf_table(data, assumptions, source, where, extra_locks=()):
    table = _table(data["urdf"], f"{where} [urdf]", '[urdf] with path = "robot.urdf"')
    _check_keys(table, _URDF_KEYS, f"{where} [urdf]")
    for key, text in (("joint", "[[joint]] tables"), ("convention", "a convention")):
        if key in data:
            raise RobotFileError(
                f"{where}: a robot with a [urdf] table must take its joints from the URDF; got {text} as well. "
                "Remove them (override joint limits in [urdf.limits.<joint name>], link inertials in [[link]] "
                "tables with the link's name)."
            )
    if "path" not in table:
        raise RobotFileError(f"{where} [urdf].path is missing. Give the URDF path relative to the robot file.")
    urdf = Path(_string(table["path"], f"{where} [urdf].path"))
    if not urdf.is_absolute() and source is not None:
        urdf = source.parent / urdf
    if not urdf.exists():
        raise RobotFileError(
            f"{where} [urdf].path must name an existing URDF; got {table['path']!r} ({urdf} does not exist). "
            "Check the path (relative to the robot file)."
        )
    locked = _strings(table.get("locked_joints", []), f"{where} [urdf].locked_joints")
    locked = tuple({**dict(locked_positions(locked)), **dict(extra_locks)}.items())
    gravity = _vector(data["gravity"], 3, f"{where} gravity") if "gravity" in data else None
    name = _string(data["name"], f"{where} name") if "name" in data else None
    with _within(f"{where} [urdf].path"):
        robot = from_urdf(urdf, locked_joints=locked, gravity=gravity, name=name, warn=False)
    n = robot.n_dof
    joints = _urdf_limits(robot.joints, table.get("limits", {}), where)
    drives = _drives_from_tables(data.get("drive"), n, where)
    assumed = {**_assumed(assumptions, n, where), **_motor_side(data, n, where)}
    drives = _drives_with_motor_kt(drives, data, assumed, where)
    with _within(where):
        robot = replace(robot, joints=joints, drives=drives, source=None if source is None else str(source), **assumed)
    unusable = robot.replaced_inertias
    robot = apply_link_overrides(robot, data["link"], where) if "link" in data else robot
    for stand_in in robot.replaced_inertias:  # those the [[link]] tables did not replace
        say(logger, stand_in.message(urdf.name))
    for stand_in in (r for r in unusable if r not in robot.replaced_inertias):  # said once, nothing left to do
        logger.info("%s: the URDF's inertia of link %s (joint %d) is unusable (it %s); its kinematics are used and the "
                    "robot file's [[link]] table states the inertia", urdf.name, stand_in.link, stand_in.joint + 1,
                    stand_in.problem)  # fmt: skip
    return robot


def _urdf_limits(joints: tuple, limits, where) -> tuple:
    """The URDF's joints with the limits of ``[urdf.limits.<joint name>]`` tables in place of the file's."""
    names = [joint.name for joint in joints]
    joints = list(joints)
    for name, values in _table(limits, f"{where} [urdf].limits", "[urdf.limits.<joint name>] tables").items():
        lwhere = f"{where} [urdf.limits.{name}]"
        if name not in names:
            raise RobotFileError(
                f"{lwhere} must name a joint of the URDF; got {name!r}. Joints are {names}; check the spelling."
            )
        _check_keys(_table(values, lwhere, f"[urdf.limits.{name}] with qdd_max = ..."), _LIMIT_KEYS, lwhere)
        changes = {
            k: _number(v, f"{lwhere}.{k}", _TAU_MAX_FIX if k == "tau_max" else "Give a finite value.")
            for k, v in values.items()
        }
        with _within(lwhere):
            joints[names.index(name)] = replace(joints[names.index(name)], **changes)
    return tuple(joints)


def _calibrated_model_text(path: Path) -> str:
    """The refusal of a calibrated-model file (``psdm identify``'s JSON) given where a robot file is expected, with
    the commands that read one; "" for any other file (a new user passed model.json to identify again)."""
    import json
    import re

    if path.suffix.lower() != ".json" or not path.is_file():
        return ""
    try:
        with path.open(encoding="utf-8") as handle:
            head = handle.read(4096)
        if not re.search(r'"format"\s*:\s*"psdm-calibrated-model"', head):
            return ""
        main = str((json.loads(path.read_text(encoding="utf-8")).get("robot") or {}).get("main_file") or "")
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):
        return ""
    source = f" ({main}, a copy of which the model file keeps)" if main else ""
    return (
        f"{path.name!r} is a calibrated model (written by 'psdm identify'), not a robot file (.toml, .urdf or .xml). "
        f"To refine it, run 'psdm diagnose {path.name} --train REC --validate REC --apply NEW.json' (it finds what "
        f"the model misses and identifies it again with that); to check it on a recording, 'psdm validate "
        f"{path.name} REC'; to identify afresh, give the robot file it was identified from{source}."
    )
