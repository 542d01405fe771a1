"""Robot files written: a RobotDescription of DH rows as a ``psdm-robot/1`` TOML file that ``load_robot`` reads back.

A robot built or changed in Python (a scaled arm, identified inertias) needs a robot file before a calibrated
model can store it (the model file keeps the robot file's text so every command can rebuild the kinematics).
``write_robot_file`` writes every field the reader knows: the DH rows with their limits, the gravity vector,
the ``[assumptions]`` (drive inertia flags, massless links, parameters forced to zero), one ``[[link]]`` table
per link (mass, centre of mass, inertia about it, rotor inertia) and one ``[[drive]]`` table per joint.
Numbers are written with ``repr``, the shortest text that reads back to the same float, so the file reads
back to the same robot bit for bit. The file is written atomically (``psdm_casadi.fileio``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import RobotFileError
from psdm_casadi.fileio import atomic_write
from psdm_casadi.robot_file import ROBOT_FORMAT, ROBOT_FORMAT_ENVELOPES

__all__ = ["robot_file_text", "write_robot_file"]

_DRIVE_FIELDS = ("kt", "fc", "fs", "vs", "fv", "dv", "sigma0", "sigma1")


def _number(value) -> str:
    """A finite float as TOML text that reads back to the same float."""
    return repr(float(value))


def _numbers(values) -> str:
    return "[" + ", ".join(_number(v) for v in np.asarray(values, dtype=float).reshape(-1)) + "]"


def _string(text: str) -> str:
    """A TOML basic string (JSON's escapes are TOML's)."""
    return json.dumps(str(text), ensure_ascii=False)


def _check_writable(robot: RobotDescription) -> None:
    """Refuse what a robot file of DH rows cannot hold, naming the field and the fix."""
    if not isinstance(robot, RobotDescription):
        raise RobotFileError(
            f"write_robot_file: robot must be a RobotDescription; got {type(robot).__name__}. Load or build one."
        )
    if robot.urdf_path is not None:
        raise RobotFileError(
            f"write_robot_file: robot {robot.name!r} is read from a URDF ({robot.urdf_path}); a robot file of DH rows "
            'cannot hold it. Write a robot file with an [urdf] table (path = "robot.urdf") by hand instead.'
        )
    if robot.links is None and np.any(np.asarray(robot.rotor_inertia) != 0.0):
        raise RobotFileError(
            f"write_robot_file: robot {robot.name!r} has rotor inertia but RobotDescription.links is None; a robot "
            "file holds rotor inertia in its [[link]] tables. Give the robot link inertias (robot.with_links(...))."
        )


def robot_file_text(robot: RobotDescription) -> str:
    """The ``psdm-robot/1`` TOML text of a robot of DH rows (see the module docstring).

    Raises
    ------
    RobotFileError
        For a robot read from a URDF, or rotor inertia without link inertias.
    """
    _check_writable(robot)
    lines = [
        "# Written by psdm_casadi.robot_writer.write_robot_file.",
        f"format = {_string(ROBOT_FORMAT if robot.envelopes is None else ROBOT_FORMAT_ENVELOPES)}",
        f"name = {_string(robot.name)}",
        f"convention = {_string(robot.convention)}",
        f"gravity = {_numbers(robot.gravity)}",
        "",
        "[assumptions]",
        "drive_inertia = [" + ", ".join("true" if x else "false" for x in robot.drive_inertia) + "]",
        "massless_links = [" + ", ".join(str(int(k)) for k in robot.massless_links) + "]",
        "zero_parameters = [" + ", ".join(_string(p) for p in robot.zero_parameters) + "]",
    ]
    for joint in robot.joints:
        lines += ["", "[[joint]]", f"name = {_string(joint.name)}", f"type = {_string(joint.kind)}"]
        for key in ("a", "alpha", "d", "theta", "q_min", "q_max", "qd_max", "qdd_max"):
            lines.append(f"{key} = {_number(getattr(joint, key))}")
        if math.isfinite(joint.tau_max):  # no torque limit: the key is left out
            lines.append(f"tau_max = {_number(joint.tau_max)}")
    if robot.links is not None:
        envelopes = robot.envelopes or (None,) * robot.n_dof
        for link, rotor, envelope in zip(robot.links, robot.rotor_inertia, envelopes):
            i = np.asarray(link.inertia, dtype=float)
            six = [i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
            lines += ["", "[[link]]", f"mass = {_number(link.mass)}", f"com = {_numbers(link.com)}"]
            lines += [f"inertia = {_numbers(six)}", f"rotor_inertia = {_number(rotor)}"]
            if envelope is not None:
                axes, rpy = _numbers(envelope.semi_axes), _numbers(_rpy(envelope.rotation))
                lines.append(f"envelope = {{ center = {_numbers(envelope.center)}, semi_axes = {axes}, rpy = {rpy} }}")
    for drive in robot.drives or ():
        lines += ["", "[[drive]]"] + [f"{key} = {_number(getattr(drive, key))}" for key in _DRIVE_FIELDS]
    return "\n".join(lines + _motor_side_lines(robot)) + "\n"


def _motor_side_lines(robot: RobotDescription) -> list:
    """The ``[transmission]`` and ``[recording]`` tables of a robot that has them (``transmission_file``)."""
    lines = []
    transmission, layout = robot.transmission, robot.recording_layout
    if transmission is not None:
        lines += ["", "[transmission]", "matrix = [" + ", ".join(_numbers(row) for row in transmission.coupling) + "]"]
        lines.append(f"joint_offsets = {_numbers(transmission.joint_offsets)}")
        if transmission.motor_kt is not None:
            lines.append(f"motor_kt = {_numbers(transmission.motor_kt)}")
        if transmission.rated_current is not None:
            lines.append(f"rated_current = {_numbers(transmission.rated_current)}")
    if layout is not None:
        sides = ", ".join(f"{signal} = {_string(side)}" for signal, side in layout.sides.items())
        lines += ["", "[recording]", f"side = {{ {sides} }}"]
        if layout.sample_rate is not None:
            lines.append(f"sample_rate = {_number(layout.sample_rate)}")
        if layout.files:
            lines.append("files = { " + ", ".join(f"{s} = {_string(name)}" for s, name in layout.files) + " }")
    return lines


def _rpy(rotation) -> np.ndarray:
    """Roll, pitch, yaw [rad] of a rotation (``robot_file``'s convention, ``Rz(yaw) Ry(pitch) Rx(roll)``)."""
    r = np.asarray(rotation, dtype=float)
    return np.array(
        [np.arctan2(r[2, 1], r[2, 2]), np.arcsin(np.clip(-r[2, 0], -1.0, 1.0)), np.arctan2(r[1, 0], r[0, 0])]
    )


def write_robot_file(robot: RobotDescription, path, overwrite: bool = False) -> Path:
    """Write ``robot`` (DH rows) as a robot file that ``load_robot(path)`` reads back to the same robot.

    Parameters
    ----------
    robot : RobotDescription
        A robot of DH rows (not read from a URDF).
    path : str or Path
        The ``.toml`` file to write.
    overwrite : bool
        Replace an existing file (otherwise it is refused).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    RobotFileError
        For a robot read from a URDF, rotor inertia without link inertias, a path not ending in ``.toml``, or an
        existing file without ``overwrite``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from psdm_casadi.robot import load_robot
    >>> robot = load_robot("scara")
    >>> path = write_robot_file(robot, pathlib.Path(tempfile.mkdtemp()) / "scara_copy.toml")
    >>> load_robot(path).n_dof == robot.n_dof
    True
    """
    path = Path(path)
    if path.suffix.lower() != ".toml":
        raise RobotFileError(f"write_robot_file: path must end in .toml; got {str(path)!r}. Name the file *.toml.")
    text = robot_file_text(robot)
    try:
        return atomic_write(path, lambda handle: handle.write(text), overwrite=overwrite)
    except FileExistsError:
        raise RobotFileError(
            f"write_robot_file: {str(path)!r} exists; pass overwrite=True to replace it, or choose another path."
        ) from None
