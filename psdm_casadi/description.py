"""RobotDescription and its parts: kinematics, limits and modelling assumptions of a serial arm.

The first value of the flow. Everything downstream (the oracle, the derivation, excitation limits,
the virtual robot) reads only this value; ``psdm_casadi.robot`` builds it from DH rows, a robot file
or a URDF.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from psdm_casadi.errors import RobotFileError
from psdm_casadi.link_envelope import check_envelopes
from psdm_casadi.recording_layout import RecordingLayout
from psdm_casadi.transmission import Transmission
from psdm_casadi.values import float_array, format_value, inertia_violation, is_real_number

JOINT_KINDS = ("revolute", "prismatic")
CONVENTIONS = ("standard", "modified")

# Names of the per-link inertial quantities that a robot file may force to zero. They refer to the
# physical parameters of the paper's X (eq. 2): COM position r in the link frame, inertia about the COM.
PHYSICAL_PARAMETER_NAMES = ("m", "rx", "ry", "rz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
GRAVITY_STANDARD = 9.806132  # m/s^2, the value the published Denso model uses
_JOINT_UNITS = {"a": "m", "alpha": "rad", "d": "m", "theta": "rad", "q_min": "rad or m", "q_max": "rad or m",
                "qd_max": "rad/s or m/s", "qdd_max": "rad/s^2 or m/s^2", "tau_max": "N m or N"}  # fmt: skip


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
        Every value must be finite except ``tau_max``, whose default ``inf`` means no torque limit.

    Raises
    ------
    RobotFileError
        For an unknown kind, an empty name, a NaN or infinite value, ``q_min >= q_max`` or a
        limit that is not positive.
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
        if not isinstance(self.name, str) or not self.name.strip():
            raise RobotFileError(
                f"Joint.name must be a non-empty string; got {format_value(self.name)}. Name the joint."
            )
        where = f"Joint {self.name!r}"
        if self.kind not in JOINT_KINDS:
            raise RobotFileError(
                f"{where}.type must be one of {JOINT_KINDS}; got {format_value(self.kind)}. "
                'Write type = "revolute" or type = "prismatic".'
            )
        for key, unit in _JOINT_UNITS.items():
            value = getattr(self, key)
            if not is_real_number(value) or math.isnan(value):
                raise RobotFileError(
                    f"{where}.{key} must be a number [{unit}]; got {format_value(value)}. Fix the value."
                )
            if math.isinf(value) and not (key == "tau_max" and value > 0):  # tau_max = inf: no torque limit
                raise RobotFileError(
                    f"{where}.{key} must be finite [{unit}]; got {format_value(value)}. Give a finite value"
                    + (" or leave tau_max out for a joint without a torque limit." if key == "tau_max" else ".")
                )
        if not self.q_min < self.q_max:
            raise RobotFileError(
                f"{where}.q_min must be below q_max; got q_min={format_value(self.q_min)}, "
                f"q_max={format_value(self.q_max)}. Swap them."
            )
        for key in ("qd_max", "qdd_max", "tau_max"):
            if getattr(self, key) <= 0:
                raise RobotFileError(
                    f"{where}.{key} must be positive; got {format_value(getattr(self, key))}. "
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
        Inertia tensor about the centre of mass, in the link frame [kg m^2] (or the six values
        ``[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]``).

    Raises
    ------
    RobotFileError
        For a negative or non-finite mass, a non-finite centre of mass, or an inertia that is not
        finite, positive semi-definite and within the triangle inequality (:func:`inertia_violation`).
    """

    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def __post_init__(self):
        if not is_real_number(self.mass) or not math.isfinite(self.mass) or self.mass < 0:
            raise RobotFileError(
                f"LinkInertia.mass must be a finite number >= 0 [kg]; got {format_value(self.mass)}. "
                "Give the mass in kg."
            )
        com = float_array(self.com, "LinkInertia.com", "3 numbers [m]")
        if com.size != 3 or not np.all(np.isfinite(com)):
            raise RobotFileError(f"LinkInertia.com must be 3 finite numbers [m]; got {format_value(com)}.")
        inertia = float_array(self.inertia, "LinkInertia.inertia", "a 3x3 matrix [kg m^2]")
        if inertia.shape == (6,):  # [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]
            ixx, iyy, izz, ixy, ixz, iyz = inertia
            inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        if inertia.shape != (3, 3):
            raise RobotFileError(
                f"LinkInertia.inertia must be 3x3 or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]; got shape {inertia.shape}."
            )
        if not np.all(np.isfinite(inertia)):
            raise RobotFileError(f"LinkInertia.inertia must be finite [kg m^2]; got {format_value(inertia)}.")
        inertia = 0.5 * (inertia + inertia.T)
        problem = inertia_violation(inertia)
        if problem:
            raise RobotFileError(
                f"LinkInertia.inertia {problem}. Give the inertia about the centre of mass in kg m^2 "
                "(check the signs of Ixy, Ixz, Iyz and that no moment is too large)."
            )
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "com", com.reshape(3))
        object.__setattr__(self, "inertia", inertia)

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
        for key in ("kt", "fc", "fs", "vs", "fv", "dv", "sigma0", "sigma1"):
            value = getattr(self, key)
            if not is_real_number(value) or not math.isfinite(value):
                raise RobotFileError(f"DriveParameters.{key} must be a finite number; got {format_value(value)}.")
        for key in ("kt", "vs", "dv", "sigma0"):
            if not getattr(self, key) > 0:
                raise RobotFileError(
                    f"DriveParameters.{key} must be positive; got {format_value(getattr(self, key))}. Fix the value."
                )
        for key in ("fc", "fs", "fv", "sigma1"):
            if getattr(self, key) < 0:
                raise RobotFileError(
                    f"DriveParameters.{key} must be >= 0; got {format_value(getattr(self, key))}. Fix the sign."
                )


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
        When set, kinematics and nominal inertia come from this URDF through Pinocchio (or from this MJCF file,
        ``.xml``, through MuJoCo's compiler: ``psdm_casadi.mjcf``).
    locked_joints : tuple of (str, float)
        URDF joints fixed at a position [rad or m] (grippers), as ``(name, value)`` pairs; a bare name
        locks at zero, and a mapping ``{name: value}`` is accepted too (see :func:`locked_positions`).
    source : str or None
        The robot file (TOML or URDF) the description was read from, for messages; not compared.
    replaced_inertias : tuple of urdf.ReplacedInertia
        URDF link inertias that were not physical and are replaced in ``links`` by a neutral stand-in.
    transmission, recording_layout : Transmission, RecordingLayout or None
        Motor/joint gears (``[transmission]``); how recordings are written (``[recording]``); not compared.
    envelopes : tuple or None
        Per link, its physical envelope (``link_envelope.LinkEnvelope``) or None (the identification derives one).
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
    source: str | None = field(default=None, compare=False)
    replaced_inertias: tuple = field(default=(), compare=False)
    transmission: Transmission | None = field(default=None, compare=False)
    recording_layout: RecordingLayout | None = field(default=None, compare=False)
    envelopes: tuple | None = field(default=None, compare=False)

    def __post_init__(self):
        joints = tuple(self.joints)
        n = len(joints)
        if self.transmission is not None and self.transmission.n_dof != n:
            raise RobotFileError(
                f"RobotDescription.transmission must couple {n} motors; got {self.transmission.n_dof}."
            )
        if not isinstance(self.name, str):
            raise RobotFileError(f"RobotDescription.name must be a string; got {format_value(self.name)}.")
        if n == 0:
            raise RobotFileError(
                "RobotDescription.joints must hold at least one joint; got none. Add [[joint]] tables."
            )
        _check_joints(joints)
        if self.convention not in CONVENTIONS:
            raise RobotFileError(
                f"RobotDescription.convention must be one of {CONVENTIONS}; got {format_value(self.convention)}."
            )
        gravity = float_array(self.gravity, "RobotDescription.gravity", "3 numbers [m/s^2]").reshape(-1)
        if gravity.shape != (3,) or not np.all(np.isfinite(gravity)):
            raise RobotFileError(
                f"RobotDescription.gravity must be 3 finite numbers [m/s^2]; got {format_value(gravity)}. "
                "Write gravity = [gx, gy, gz] in the base frame."
            )
        object.__setattr__(self, "gravity", gravity)
        drive_inertia = tuple(bool(x) for x in self.drive_inertia) if self.drive_inertia else (False,) * n
        if len(drive_inertia) != n:
            raise RobotFileError(
                f"RobotDescription.drive_inertia must have one flag per joint ({n}); got {len(drive_inertia)}. "
                "Write drive_inertia = true, false, or a list of n booleans."
            )
        object.__setattr__(self, "drive_inertia", drive_inertia)
        for link in self.massless_links:
            if not (isinstance(link, int) and not isinstance(link, bool) and 1 <= link <= n):
                raise RobotFileError(
                    f"RobotDescription.massless_links must hold link numbers 1..{n}; got {format_value(link)}."
                )
        for name in self.zero_parameters:
            parse_parameter_name(name, n)
        _check_parts(self.links, LinkInertia, "links", "one per link", n)
        _check_parts(self.drives, DriveParameters, "drives", "one per joint", n)
        object.__setattr__(self, "envelopes", check_envelopes(self.envelopes, n))
        rotor = np.zeros(n) if self.rotor_inertia is None else self.rotor_inertia
        rotor = float_array(rotor, "RobotDescription.rotor_inertia", f"{n} numbers [kg m^2]").reshape(-1)
        if rotor.shape != (n,) or not np.all(np.isfinite(rotor)) or np.any(rotor < 0):
            raise RobotFileError(
                f"RobotDescription.rotor_inertia must be {n} finite numbers >= 0 [kg m^2]; got {format_value(rotor)}."
            )
        object.__setattr__(self, "rotor_inertia", rotor)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "massless_links", tuple(self.massless_links))
        object.__setattr__(self, "zero_parameters", tuple(self.zero_parameters))
        object.__setattr__(self, "locked_joints", locked_positions(self.locked_joints))

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

    def with_links(self, links, rotor_inertia=None) -> RobotDescription:
        """A copy with other nominal inertial parameters (e.g. a perturbed truth for simulation)."""
        return replace(
            self, links=tuple(links), rotor_inertia=self.rotor_inertia if rotor_inertia is None else rotor_inertia
        )


def parse_parameter_name(name: str, n_dof: int) -> tuple:
    """Split a physical parameter name such as ``"Ixz4"`` into its quantity and 1-based link number.

    Parameters
    ----------
    name : str
        One of ``PHYSICAL_PARAMETER_NAMES`` followed by a link number, e.g. ``"rx5"`` or ``"Ixz4"``.
    n_dof : int
        Number of links; the link number must be in 1..n_dof.

    Returns
    -------
    (str, int)
        The quantity (``"Ixz"``) and the link number (4).

    Raises
    ------
    RobotFileError
        When ``name`` is not such a name, naming the fix.
    """
    for base in sorted(PHYSICAL_PARAMETER_NAMES, key=len, reverse=True):
        if isinstance(name, str) and name.startswith(base) and name[len(base) :].isdigit():
            link = int(name[len(base) :])
            if 1 <= link <= n_dof:
                return base, link
    raise RobotFileError(
        f"assumptions.zero_parameters entry {format_value(name)} is not a parameter name; expected one of "
        f"{', '.join(PHYSICAL_PARAMETER_NAMES)} followed by a link number 1..{n_dof}, e.g. 'rx5' or 'Ixz4'."
    )


def locked_positions(locked) -> tuple:
    """Joints to lock as ``((name, value), ...)``: from names (locked at 0), ``(name, value)`` pairs or a mapping.

    Parameters
    ----------
    locked : sequence of str or (str, float), or mapping str -> float
        Joint names with their fixed positions [rad or m]; a bare name means 0.

    Returns
    -------
    tuple of (str, float)
        In the given order, each name once.

    Raises
    ------
    RobotFileError
        For an empty name, a value that is not a finite number, or a joint named twice.

    Examples
    --------
    >>> locked_positions(["finger", ("elbow", 0.5)])
    (('finger', 0.0), ('elbow', 0.5))
    """
    items = locked.items() if isinstance(locked, Mapping) else locked
    pairs, seen = [], set()
    for item in items:
        if isinstance(item, str):
            name, value = item, 0.0
        elif isinstance(item, (tuple, list)) and len(item) == 2:
            name, value = item
        else:
            name, value = None, None
        if not isinstance(name, str) or not name.strip():
            raise RobotFileError(
                f"locked_joints entries must be joint names or (name, value) pairs; got {format_value(item)}. "
                'Write e.g. ["gripper_joint"] or [["elbow_joint", 0.5]].'
            )
        if not is_real_number(value) or not math.isfinite(value):
            raise RobotFileError(
                f"locked joint {name!r} must be locked at a finite number [rad or m]; got {format_value(value)}. "
                "Give its position, e.g. 0.02."
            )
        if name in seen:
            raise RobotFileError(f"locked_joints names {name!r} twice. Lock each joint once.")
        seen.add(name)
        pairs.append((name, float(value)))
    return tuple(pairs)


def _check_joints(joints) -> None:
    seen = {}
    for i, joint in enumerate(joints):
        if not isinstance(joint, Joint):
            raise RobotFileError(
                f"RobotDescription.joints[{i}] must be a Joint; got {type(joint).__name__}. Build it with Joint(...)."
            )
        if joint.name in seen:
            raise RobotFileError(
                f"RobotDescription.joints must have distinct names; got {joint.name!r} for joints "
                f"{seen[joint.name] + 1} and {i + 1}. Rename one of them."
            )
        seen[joint.name] = i


def _check_parts(parts, kind, field_name, per, n) -> None:
    if parts is None:
        return
    if len(parts) != n:
        raise RobotFileError(f"RobotDescription.{field_name} must have {n} entries ({per}); got {len(parts)}.")
    for i, part in enumerate(parts):
        if not isinstance(part, kind):
            raise RobotFileError(
                f"RobotDescription.{field_name}[{i}] must be a {kind.__name__}; got {type(part).__name__}."
            )
