"""RobotDescription: kinematics, limits and modelling assumptions of a serial arm (first step of the flow).

A robot comes from a TOML file with Denavit-Hartenberg rows (``load_robot``), from Python
(``from_dh``) or from a URDF read by Pinocchio (``from_urdf``). Everything downstream (the oracle,
the derivation, excitation limits, the virtual robot) reads only this value.
"""

from __future__ import annotations

import ast
import math
import operator
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from psdm_casadi.errors import RobotFileError

ROBOT_FORMAT = "psdm-robot/1"
JOINT_KINDS = ("revolute", "prismatic")
CONVENTIONS = ("standard", "modified")

# Names of the per-link inertial quantities that a robot file may force to zero. They refer to the
# physical parameters of the paper's X (eq. 2): COM position r in the link frame, inertia about the COM.
PHYSICAL_PARAMETER_NAMES = ("m", "rx", "ry", "rz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
GRAVITY_STANDARD = 9.806132  # m/s^2, the value the published Denso model uses


@dataclass(frozen=True)
class Joint:
    """One joint with its DH row and limits.

    Parameters
    ----------
    name : str
    kind : {"revolute", "prismatic"}
    a, alpha, d, theta : float
        DH row [m, rad, m, rad]; ``theta`` (revolute) or ``d`` (prismatic) is the offset added to q.
    q_min, q_max : float
        Position limits [rad or m].
    qd_max, qdd_max, tau_max : float
        Symmetric velocity [rad/s or m/s], acceleration [rad/s^2 or m/s^2] and effort [N m or N] limits.
    """

    name: str
    kind: str = "revolute"
    a: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    q_min: float = -math.pi
    q_max: float = math.pi
    qd_max: float = 2.0
    qdd_max: float = 10.0
    tau_max: float = math.inf

    def __post_init__(self):
        where = f"Joint {self.name!r}"
        if self.kind not in JOINT_KINDS:
            raise RobotFileError(
                f"{where}.type must be one of {JOINT_KINDS}; got {self.kind!r}. "
                "Write type = \"revolute\" or type = \"prismatic\"."
            )
        for key in ("a", "alpha", "d", "theta", "q_min", "q_max", "qd_max", "qdd_max", "tau_max"):
            value = getattr(self, key)
            if not isinstance(value, (int, float)) or math.isnan(value):
                raise RobotFileError(f"{where}.{key} must be a number; got {value!r}.")
        if not self.q_min < self.q_max:
            raise RobotFileError(
                f"{where}.q_min must be below q_max; got q_min={self.q_min}, q_max={self.q_max}. Swap them."
            )
        for key in ("qd_max", "qdd_max", "tau_max"):
            if getattr(self, key) <= 0:
                raise RobotFileError(
                    f"{where}.{key} must be positive; got {getattr(self, key)}. "
                    "Give the magnitude of the symmetric limit."
                )

    @property
    def is_revolute(self) -> bool:
        return self.kind == "revolute"


@dataclass(frozen=True)
class LinkInertia:
    """Physical inertial parameters of one link, in the link frame (the paper's X row).

    Parameters
    ----------
    mass : float
        [kg]
    com : array, shape (3,)
        Centre of mass in the link frame [m].
    inertia : array, shape (3, 3)
        Inertia tensor about the centre of mass, in the link frame [kg m^2].
    """

    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def __post_init__(self):
        com = np.asarray(self.com, dtype=float).reshape(3)
        inertia = np.asarray(self.inertia, dtype=float)
        if inertia.shape == (6,):  # [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]
            ixx, iyy, izz, ixy, ixz, iyz = inertia
            inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        if inertia.shape != (3, 3):
            raise RobotFileError(
                f"LinkInertia.inertia must be 3x3 or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]; got shape {inertia.shape}."
            )
        if self.mass < 0:
            raise RobotFileError(f"LinkInertia.mass must be >= 0; got {self.mass}.")
        object.__setattr__(self, "com", com)
        object.__setattr__(self, "inertia", 0.5 * (inertia + inertia.T))

    def dynamic_parameters(self) -> np.ndarray:
        """The 10 parameters linear in the dynamics, about the link-frame origin.

        Returns
        -------
        array, shape (10,)
            [m, m rx, m ry, m rz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] with the inertia about the
            frame origin (Pinocchio's ``toDynamicParameters`` order).
        """
        return physical_to_dynamic(self.mass, self.com, self.inertia)


def physical_to_dynamic(mass: float, com, inertia_com) -> np.ndarray:
    """Map (m, r, I about COM) to the linear parameters (m, m r, I about the origin), Pinocchio order."""
    r = np.asarray(com, dtype=float)
    inertia_origin = np.asarray(inertia_com, dtype=float) + mass * (r @ r * np.eye(3) - np.outer(r, r))
    i = inertia_origin
    return np.array([mass, *(mass * r), i[0, 0], i[0, 1], i[1, 1], i[0, 2], i[1, 2], i[2, 2]])


@dataclass(frozen=True)
class DriveParameters:
    """Nominal drive model of one joint: motor constant and LuGre friction (paper eqs. 11-14, Table 2).

    Units: kt [N m/A], fc, fs [N m], vs [rad/s], fv [N m s/rad], dv [-], sigma0 [N m/rad], sigma1 [N m s/rad].
    """

    kt: float = 1.0
    fc: float = 0.0
    fs: float = 0.0
    vs: float = 0.01
    fv: float = 0.0
    dv: float = 1.0
    sigma0: float = 1e4
    sigma1: float = 10.0

    def __post_init__(self):
        for key in ("kt", "vs", "dv", "sigma0"):
            if not getattr(self, key) > 0:
                raise RobotFileError(f"DriveParameters.{key} must be positive; got {getattr(self, key)}.")
        for key in ("fc", "fs", "fv", "sigma1"):
            if getattr(self, key) < 0:
                raise RobotFileError(f"DriveParameters.{key} must be >= 0; got {getattr(self, key)}.")


@dataclass(frozen=True)
class RobotDescription:
    """Kinematics, limits, nominal inertia and modelling assumptions of a serial robot.

    Parameters
    ----------
    name : str
    joints : tuple of Joint
    convention : {"standard", "modified"}
        DH convention of the joint rows; ignored when ``urdf_path`` is set.
    gravity : array, shape (3,)
        Acceleration of gravity in the base frame [m/s^2] (e.g. ``[0, 0, -9.81]`` for a z-up base).
    drive_inertia : tuple of bool, length n_dof
        Whether a rotor inertia ``Im_i * qdd_i`` is part of the model on each joint.
    massless_links : tuple of int
        1-based indices of links whose 10 inertial parameters are all zero.
    zero_parameters : tuple of str
        Physical parameters forced to zero, named like ``"rx5"`` or ``"Ixz4"`` (COM frame, 1-based link).
    links : tuple of LinkInertia or None
        Nominal inertial parameters (simulation truth, nominal model), one per link.
    rotor_inertia : array, shape (n_dof,)
        Nominal rotor inertias [kg m^2], reflected to the joint.
    drives : tuple of DriveParameters or None
        Nominal motor constants and friction.
    urdf_path : str or None
        When set, kinematics and nominal inertia come from this URDF through Pinocchio.
    locked_joints : tuple of str
        URDF joints fixed at zero (grippers).
    """

    name: str
    joints: tuple
    convention: str = "standard"
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -GRAVITY_STANDARD]))
    drive_inertia: tuple = ()
    massless_links: tuple = ()
    zero_parameters: tuple = ()
    links: tuple | None = None
    rotor_inertia: np.ndarray | None = None
    drives: tuple | None = None
    urdf_path: str | None = None
    locked_joints: tuple = ()

    def __post_init__(self):
        n = len(self.joints)
        if n == 0:
            raise RobotFileError("RobotDescription.joints must hold at least one joint; got none. Add [[joint]] tables.")
        if self.convention not in CONVENTIONS:
            raise RobotFileError(
                f"RobotDescription.convention must be one of {CONVENTIONS}; got {self.convention!r}."
            )
        gravity = np.asarray(self.gravity, dtype=float).reshape(-1)
        if gravity.shape != (3,) or not np.all(np.isfinite(gravity)):
            raise RobotFileError(f"RobotDescription.gravity must be 3 finite numbers [m/s^2]; got {self.gravity!r}.")
        object.__setattr__(self, "gravity", gravity)
        drive_inertia = tuple(bool(x) for x in self.drive_inertia) if self.drive_inertia else (False,) * n
        if len(drive_inertia) != n:
            raise RobotFileError(
                f"RobotDescription.drive_inertia must have one flag per joint ({n}); got {len(drive_inertia)}. "
                "Write drive_inertia = true, false, or a list of n booleans."
            )
        object.__setattr__(self, "drive_inertia", drive_inertia)
        for link in self.massless_links:
            if not (isinstance(link, int) and 1 <= link <= n):
                raise RobotFileError(
                    f"RobotDescription.massless_links must hold link numbers 1..{n}; got {link!r}."
                )
        for name in self.zero_parameters:
            _parse_parameter_name(name, n)
        if self.links is not None and len(self.links) != n:
            raise RobotFileError(f"RobotDescription.links must have {n} entries (one per link); got {len(self.links)}.")
        if self.drives is not None and len(self.drives) != n:
            raise RobotFileError(f"RobotDescription.drives must have {n} entries (one per joint); got {len(self.drives)}.")
        rotor = np.zeros(n) if self.rotor_inertia is None else np.asarray(self.rotor_inertia, dtype=float).reshape(-1)
        if rotor.shape != (n,) or np.any(rotor < 0):
            raise RobotFileError(
                f"RobotDescription.rotor_inertia must be {n} non-negative numbers [kg m^2]; got {self.rotor_inertia!r}."
            )
        object.__setattr__(self, "rotor_inertia", rotor)
        object.__setattr__(self, "joints", tuple(self.joints))
        object.__setattr__(self, "massless_links", tuple(self.massless_links))
        object.__setattr__(self, "zero_parameters", tuple(self.zero_parameters))
        object.__setattr__(self, "locked_joints", tuple(self.locked_joints))

    # --- convenience views -------------------------------------------------------------------
    @property
    def n_dof(self) -> int:
        return len(self.joints)

    @property
    def joint_names(self) -> tuple:
        return tuple(j.name for j in self.joints)

    @property
    def revolute(self) -> np.ndarray:
        return np.array([j.is_revolute for j in self.joints])

    @property
    def q_min(self) -> np.ndarray:
        return np.array([j.q_min for j in self.joints])

    @property
    def q_max(self) -> np.ndarray:
        return np.array([j.q_max for j in self.joints])

    @property
    def qd_max(self) -> np.ndarray:
        return np.array([j.qd_max for j in self.joints])

    @property
    def qdd_max(self) -> np.ndarray:
        return np.array([j.qdd_max for j in self.joints])

    @property
    def tau_max(self) -> np.ndarray:
        return np.array([j.tau_max for j in self.joints])

    @property
    def gravity_magnitude(self) -> float:
        return float(np.linalg.norm(self.gravity))

    @property
    def has_inertia(self) -> bool:
        return self.links is not None

    def nominal_dynamic_parameters(self) -> np.ndarray:
        """Nominal standard parameters, shape (n_dof, 11): the 10 of ``LinkInertia.dynamic_parameters`` plus Im.

        Raises
        ------
        RobotFileError
            When the robot carries no nominal inertia (no ``[[link]]`` tables).
        """
        if self.links is None:
            raise RobotFileError(
                f"RobotDescription.links is empty for {self.name!r}; nominal inertia is needed here. "
                "Add one [[link]] table per joint with mass, com and inertia."
            )
        rows = [np.append(link.dynamic_parameters(), im) for link, im in zip(self.links, self.rotor_inertia)]
        return np.array(rows)

    def with_links(self, links, rotor_inertia=None) -> "RobotDescription":
        """A copy with other nominal inertial parameters (e.g. a perturbed truth for simulation)."""
        return replace(self, links=tuple(links),
                       rotor_inertia=self.rotor_inertia if rotor_inertia is None else rotor_inertia)


def _parse_parameter_name(name: str, n_dof: int):
    """Split ``"Ixz4"`` into ("Ixz", 4); raise a RobotFileError naming the fix otherwise."""
    for base in sorted(PHYSICAL_PARAMETER_NAMES, key=len, reverse=True):
        if isinstance(name, str) and name.startswith(base) and name[len(base):].isdigit():
            link = int(name[len(base):])
            if 1 <= link <= n_dof:
                return base, link
    raise RobotFileError(
        f"assumptions.zero_parameters entry {name!r} is not a parameter name; expected one of "
        f"{', '.join(PHYSICAL_PARAMETER_NAMES)} followed by a link number 1..{n_dof}, e.g. 'rx5' or 'Ixz4'."
    )


# --- construction from Python -----------------------------------------------------------------

def from_dh(rows, *, convention="standard", kinds=None, gravity=(0.0, 0.0, -GRAVITY_STANDARD), name="robot",
            drive_inertia=(), massless_links=(), zero_parameters=(), links=None, rotor_inertia=None,
            limits=None) -> RobotDescription:
    """Build a RobotDescription from DH rows ``(a, alpha, d, theta)``.

    Parameters
    ----------
    rows : sequence of 4-sequences
        DH rows (a [m], alpha [rad], d [m], theta offset [rad]).
    kinds : sequence of str, optional
        "revolute" (default) or "prismatic" per joint.
    limits : sequence of dict, optional
        Per joint keyword limits (q_min, q_max, qd_max, qdd_max, tau_max).
    Other parameters are those of RobotDescription.
    """
    rows = [tuple(float(x) for x in row) for row in rows]
    kinds = kinds or ["revolute"] * len(rows)
    limits = limits or [{}] * len(rows)
    joints = []
    for i, (row, kind, lim) in enumerate(zip(rows, kinds, limits)):
        if len(row) != 4:
            raise RobotFileError(f"from_dh rows[{i}] must be (a, alpha, d, theta); got {len(row)} values.")
        a, alpha, d, theta = row
        if kind == "prismatic":
            lim = {"q_min": -0.5, "q_max": 0.5, **lim}
        joints.append(Joint(name=f"joint{i + 1}", kind=kind, a=a, alpha=alpha, d=d, theta=theta, **lim))
    return RobotDescription(name=name, joints=tuple(joints), convention=convention, gravity=np.asarray(gravity),
                            drive_inertia=tuple(drive_inertia), massless_links=tuple(massless_links),
                            zero_parameters=tuple(zero_parameters), links=links, rotor_inertia=rotor_inertia)


# --- TOML files ---------------------------------------------------------------------------------

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
    raise RobotFileError(
        f"{where} must be a number or an expression of numbers and pi such as \"-pi/2\"; got {value!r}."
    )


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
        f"{', '.join(builtin_robot_names())}.")


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
        raise RobotFileError(f"{where}: format must be {ROBOT_FORMAT!r}; got {fmt!r}. Convert the file or fix the line.")
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
            raise RobotFileError(
                f"{jwhere}.type must be \"revolute\" or \"prismatic\"; got {kind!r}. Fix the joint type."
            )
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
        raise RobotFileError(f"{where}: convention must be \"standard\" or \"modified\"; got {value!r}.")
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


# --- URDF ---------------------------------------------------------------------------------------

def _robot_from_urdf_table(data, assumptions, source, where):
    table = data["urdf"]
    _check_keys(table, _URDF_KEYS, f"{where} [urdf]")
    if "path" not in table:
        raise RobotFileError(f"{where} [urdf].path is missing. Give the URDF path relative to the robot file.")
    urdf = Path(table["path"])
    if not urdf.is_absolute() and source is not None:
        urdf = source.parent / urdf
    robot = from_urdf(urdf, locked_joints=table.get("locked_joints", []),
                      gravity=data.get("gravity"), name=data.get("name"))
    drive = _drive_flags(assumptions.get("drive_inertia", False), robot.n_dof, where)
    return replace(robot, drive_inertia=drive,
                   massless_links=_massless(assumptions.get("massless_links", []), robot.n_dof, where),
                   zero_parameters=tuple(assumptions.get("zero_parameters", [])))


def from_urdf(path, *, locked_joints=(), gravity=None, name=None) -> RobotDescription:
    """Read a URDF through Pinocchio: joints, limits and link inertias.

    Parameters
    ----------
    path : str or Path
        URDF file; meshes are not needed.
    locked_joints : sequence of str
        Joints fixed at zero (e.g. gripper fingers).
    gravity : 3 numbers, optional
        Gravity acceleration in the base frame; default ``[0, 0, -9.806132]``.

    Raises
    ------
    RobotFileError
        When Pinocchio cannot parse the file, a locked joint is unknown, or a joint is neither
        revolute nor prismatic with one degree of freedom.
    """
    from psdm_casadi.oracle import load_urdf_model  # Pinocchio is imported lazily

    path = Path(path)
    model = load_urdf_model(path, locked_joints)
    joints, links = [], []
    for jid in range(1, model.njoints):
        jmodel = model.joints[jid]
        shortname = jmodel.shortname()
        if jmodel.nq != 1 or jmodel.nv != 1:
            raise RobotFileError(
                f"{path.name}: joint {model.names[jid]!r} has type {shortname} with nq={jmodel.nq}; "
                "only 1-DOF revolute or prismatic joints are supported. Lock it or make it revolute with limits."
            )
        kind = "prismatic" if "Prismatic" in shortname or shortname.startswith("JointModelP") else "revolute"
        idx = jmodel.idx_q
        q_min, q_max = float(model.lowerPositionLimit[idx]), float(model.upperPositionLimit[idx])
        if not (np.isfinite(q_min) and np.isfinite(q_max) and q_min < q_max):
            q_min, q_max = -math.pi, math.pi
        qd_max = float(model.velocityLimit[idx]) if model.velocityLimit[idx] > 0 else 2.0
        tau_max = float(model.effortLimit[idx]) if model.effortLimit[idx] > 0 else math.inf
        joints.append(Joint(name=model.names[jid], kind=kind, q_min=q_min, q_max=q_max,
                            qd_max=min(qd_max, 1e3), qdd_max=10.0, tau_max=tau_max))
        inertia = model.inertias[jid]
        links.append(LinkInertia(mass=float(inertia.mass), com=np.array(inertia.lever),
                                 inertia=np.array(inertia.inertia)))
    g = np.array([0.0, 0.0, -GRAVITY_STANDARD]) if gravity is None else _vector(list(gravity), 3, "gravity")
    return RobotDescription(name=name or path.stem, joints=tuple(joints), convention="standard", gravity=g,
                            links=tuple(links), urdf_path=str(path.resolve()),
                            locked_joints=tuple(locked_joints))
