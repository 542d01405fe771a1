"""Robot files: the ``psdm-robot/1`` TOML reader (DH rows or a URDF reference) and the built-in robots.

``load_robot`` turns a file, or the name of a robot shipped in ``psdm_casadi/robots``, into a
RobotDescription. Every malformed entry raises a RobotFileError naming the table, the row and the
fix; numbers may be written as small expressions of ``pi`` (``"-pi/2"``).
"""

from __future__ import annotations

import ast
import math
import operator
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
)
from psdm_casadi.errors import RobotFileError
from psdm_casadi.urdf import from_urdf

ROBOT_FORMAT = "psdm-robot/1"

_NUMBER_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv}


def _number(value, where: str) -> float:
    """A float from a TOML number or a small expression like ``"-pi/2"``."""
    if isinstance(value, bool):
        raise RobotFileError(f"{where} must be a number; got {value!r}.")
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str):
        try:
            return float(_eval_expression(ast.parse(value, mode="eval").body))
        except (SyntaxError, ValueError, ZeroDivisionError):
            pass
    raise RobotFileError(f'{where} must be a number or an expression of numbers and pi such as "-pi/2"; got {value!r}.')


def _eval_expression(node):
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return node.value
    if isinstance(node, ast.Name) and node.id == "pi":
        return math.pi
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _eval_expression(node.operand)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.BinOp) and type(node.op) in _NUMBER_OPS:
        return _NUMBER_OPS[type(node.op)](_eval_expression(node.left), _eval_expression(node.right))
    raise ValueError("unsupported expression")


def _vector(value, length, where):
    if not isinstance(value, list) or len(value) != length:
        raise RobotFileError(f"{where} must be a list of {length} numbers; got {value!r}.")
    return np.array([_number(v, f"{where}[{k}]") for k, v in enumerate(value)])


def _check_keys(table: dict, allowed: set, where: str):
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise RobotFileError(
            f"{where} has unknown key(s) {unknown}; allowed keys are {sorted(allowed)}. Check the spelling."
        )


_JOINT_KEYS = {"name", "type", "a", "alpha", "d", "theta", "q_min", "q_max", "qd_max", "qdd_max", "tau_max"}
_LINK_KEYS = {"mass", "com", "inertia", "rotor_inertia"}
_DRIVE_KEYS = {"kt", "fc", "fs", "vs", "fv", "dv", "sigma0", "sigma1"}
_TOP_KEYS = {"format", "name", "convention", "gravity", "joint", "link", "drive", "assumptions", "urdf", "description"}
_ASSUMPTION_KEYS = {"drive_inertia", "massless_links", "zero_parameters"}
_URDF_KEYS = {"path", "locked_joints", "limits"}


#: The robot files that ship with the package, found by name (``load_robot("denso_vs6556g")``).
BUILTIN_ROBOTS_DIR = Path(__file__).resolve().parent / "robots"


def builtin_robot_names() -> list[str]:
    """Names of the built-in robot files, for ``load_robot(name)`` and ``psdm ... NAME``."""
    return sorted(p.stem for p in BUILTIN_ROBOTS_DIR.glob("*.toml"))


def resolve_robot_path(path) -> Path:
    """The file a robot argument names: an existing path, or the name of a built-in robot."""
    candidate = Path(path)
    if candidate.exists():
        return candidate
    if candidate.parent == Path(".") and candidate.stem in builtin_robot_names() and candidate.suffix in ("", ".toml"):
        return BUILTIN_ROBOTS_DIR / f"{candidate.stem}.toml"
    raise RobotFileError(
        f"robot file {str(path)!r} does not exist. Check the path, or name a built-in robot: "
        f"{', '.join(builtin_robot_names())}."
    )


def load_robot(path) -> RobotDescription:
    """Read a robot file: ``.toml`` (DH rows) or ``.urdf`` (through Pinocchio), or a built-in robot by name.

    Parameters
    ----------
    path : str or Path
        A file, or the name of a built-in robot (:func:`builtin_robot_names`).

    Returns
    -------
    RobotDescription

    Raises
    ------
    RobotFileError
        Naming the field, the row and the fix, for every malformed entry.
    """
    path = resolve_robot_path(path)
    if path.suffix.lower() == ".urdf":
        return from_urdf(path)
    if path.suffix.lower() != ".toml":
        raise RobotFileError(f"robot file {str(path)!r} must end in .toml or .urdf; got {path.suffix!r}.")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise RobotFileError(f"{path.name}: not valid TOML ({exc}). Fix the syntax at that line.") from None
    return robot_from_mapping(data, source=path)


def robot_from_mapping(data: dict, source: Path | None = None) -> RobotDescription:
    """Build a RobotDescription from the parsed contents of a robot TOML file."""
    where = source.name if source is not None else "robot file"
    _check_keys(data, _TOP_KEYS, where)
    fmt = data.get("format", ROBOT_FORMAT)
    if fmt != ROBOT_FORMAT:
        raise RobotFileError(
            f"{where}: format must be {ROBOT_FORMAT!r}; got {fmt!r}. Convert the file or fix the line."
        )
    assumptions = data.get("assumptions", {})
    if not isinstance(assumptions, dict):
        raise RobotFileError(f"{where}: assumptions must be a table [assumptions].")
    _check_keys(assumptions, _ASSUMPTION_KEYS, f"{where} [assumptions]")
    if "urdf" in data:
        return _robot_from_urdf_table(data, assumptions, source, where)
    joint_tables = data.get("joint")
    if not isinstance(joint_tables, list) or not joint_tables:
        raise RobotFileError(f"{where}: needs at least one [[joint]] table with a DH row (a, alpha, d, theta).")
    joints = []
    for i, table in enumerate(joint_tables):
        jwhere = f"{where} joint[{i + 1}]"
        _check_keys(table, _JOINT_KEYS, jwhere)
        for key in ("a", "alpha", "d", "theta"):
            if key not in table:
                raise RobotFileError(f"{jwhere}.{key} is missing. Add {key} = <number> to the DH row (0 if absent).")
        kwargs = {k: _number(table[k], f"{jwhere}.{k}") for k in _JOINT_KEYS - {"name", "type"} if k in table}
        kind = table.get("type", "revolute")
        if kind not in JOINT_KINDS:
            raise RobotFileError(f'{jwhere}.type must be "revolute" or "prismatic"; got {kind!r}. Fix the joint type.')
        try:
            joints.append(Joint(name=str(table.get("name", f"joint{i + 1}")), kind=kind, **kwargs))
        except RobotFileError as exc:
            raise RobotFileError(f"{jwhere}: {exc}") from None
    n = len(joints)
    gravity = _vector(data.get("gravity", [0, 0, -GRAVITY_STANDARD]), 3, f"{where}: gravity")
    links, rotor = _links_from_tables(data.get("link"), n, where)
    drives = _drives_from_tables(data.get("drive"), n, where)
    return RobotDescription(
        name=str(data.get("name", source.stem if source else "robot")),
        joints=tuple(joints),
        convention=_convention(data.get("convention", "standard"), where),
        gravity=gravity,
        drive_inertia=_drive_flags(assumptions.get("drive_inertia", False), n, where),
        massless_links=_massless(assumptions.get("massless_links", []), n, where),
        zero_parameters=tuple(assumptions.get("zero_parameters", [])),
        links=links,
        rotor_inertia=rotor,
        drives=drives,
    )


def _convention(value, where):
    if value not in CONVENTIONS:
        raise RobotFileError(f'{where}: convention must be "standard" or "modified"; got {value!r}.')
    return value


def _drive_flags(value, n, where):
    if isinstance(value, bool):
        return (value,) * n
    if isinstance(value, list) and len(value) == n and all(isinstance(v, bool) for v in value):
        return tuple(value)
    raise RobotFileError(
        f"{where} [assumptions].drive_inertia must be true, false or a list of {n} booleans; got {value!r}."
    )


def _massless(value, n, where):
    if not isinstance(value, list) or not all(isinstance(v, int) and 1 <= v <= n for v in value):
        raise RobotFileError(
            f"{where} [assumptions].massless_links must be a list of link numbers 1..{n}; got {value!r}."
        )
    return tuple(value)


def _links_from_tables(tables, n, where):
    if tables is None:
        return None, None
    if not isinstance(tables, list) or len(tables) != n:
        count = len(tables) if isinstance(tables, list) else tables
        raise RobotFileError(f"{where}: needs exactly {n} [[link]] tables (one per joint) or none; got {count}.")
    links, rotor = [], []
    for i, table in enumerate(tables):
        lwhere = f"{where} link[{i + 1}]"
        _check_keys(table, _LINK_KEYS, lwhere)
        mass = _number(table.get("mass", 0.0), f"{lwhere}.mass")
        com = _vector(table.get("com", [0, 0, 0]), 3, f"{lwhere}.com")
        inertia = _vector(table.get("inertia", [0] * 6), 6, f"{lwhere}.inertia ([Ixx, Iyy, Izz, Ixy, Ixz, Iyz])")
        try:
            links.append(LinkInertia(mass=mass, com=com, inertia=inertia))
        except RobotFileError as exc:
            raise RobotFileError(f"{lwhere}: {exc}") from None
        rotor.append(_number(table.get("rotor_inertia", 0.0), f"{lwhere}.rotor_inertia"))
    return tuple(links), np.array(rotor)


def _drives_from_tables(tables, n, where):
    if tables is None:
        return None
    if not isinstance(tables, list) or len(tables) != n:
        raise RobotFileError(f"{where}: needs exactly {n} [[drive]] tables (one per joint) or none.")
    drives = []
    for i, table in enumerate(tables):
        dwhere = f"{where} drive[{i + 1}]"
        _check_keys(table, _DRIVE_KEYS, dwhere)
        try:
            drives.append(DriveParameters(**{k: _number(v, f"{dwhere}.{k}") for k, v in table.items()}))
        except RobotFileError as exc:
            raise RobotFileError(f"{dwhere}: {exc}") from None
    return tuple(drives)


def _robot_from_urdf_table(data, assumptions, source, where):
    table = data["urdf"]
    _check_keys(table, _URDF_KEYS, f"{where} [urdf]")
    if "path" not in table:
        raise RobotFileError(f"{where} [urdf].path is missing. Give the URDF path relative to the robot file.")
    urdf = Path(table["path"])
    if not urdf.is_absolute() and source is not None:
        urdf = source.parent / urdf
    gravity = _vector(list(data["gravity"]), 3, "gravity") if "gravity" in data else None
    robot = from_urdf(urdf, locked_joints=table.get("locked_joints", []), gravity=gravity, name=data.get("name"))
    drive = _drive_flags(assumptions.get("drive_inertia", False), robot.n_dof, where)
    return replace(
        robot,
        drive_inertia=drive,
        massless_links=_massless(assumptions.get("massless_links", []), robot.n_dof, where),
        zero_parameters=tuple(assumptions.get("zero_parameters", [])),
    )
