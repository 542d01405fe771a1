"""CalibrationData: the recordings of the four calibration experiments, read from a data directory.

Directory layout (CSV or NPZ recordings in the format of ``io.load_recording``; names as written
by ``psdm simulate --experiment ...``)::

    DATA/
      payload.json                     {"mass": kg, "com": [x, y, z] m (flange frame), "inertia": optional 3x3}
      tool.json                        optional: a load mounted during every experiment (same keys)
      motor_j<k>_nominal.csv|npz       step 1: sweep of joint k without the calibration mass ...
      motor_j<k>_payload.csv|npz       ... and the same sweep with it (k = 1..n)
      gravity*.csv|npz                 step 2: one or more out-and-back slow jogs
      friction_j<k>.csv|npz            step 3: joint k oscillating, the others held
      friction_j<k>_validation.csv|npz optional: a second friction experiment of joint k for validation
                                       (otherwise the last 15 % of friction_j<k> validates)
      excitation*.csv|npz | sine*.csv  step 4: fast exciting trajectory (e.g. trajopt's)

Joints are numbered from 1 in file names and from 0 in the API.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from identification.data.io import load_recording, save_recording
from identification.data.payload import Payload, payload_json, read_payload
from identification.data.robot_recordings import load_robot_recording
from psdm_casadi.errors import ParameterError, RecordingError
from psdm_casadi.fileio import atomic_write

__all__ = ["CalibrationData", "load_calibration_data", "save_calibration_data", "read_payload"]

_SUFFIXES = (".csv", ".npz")


@dataclass(frozen=True, eq=False)
class CalibrationData:
    """Raw (unfiltered) recordings of the calibration experiments.

    Parameters
    ----------
    payload : Payload
        The known calibration mass of the motor step (:mod:`identification.data.payload`).
    motor : tuple of (int, Recording, Recording)
        Per swept joint (0-based): the sweep without and with the mass.
    gravity : tuple of Recording
        Out-and-back slow jogs.
    friction : tuple of (int, Recording)
        Per joint (0-based): its friction experiment.
    excitation : tuple of Recording
        Fast exciting trajectories (step 4 and the "All" validation).
    tool : Payload or None
        A known load mounted during every experiment (tau_ee of eq. 15).
    friction_validation : tuple of (int, Recording)
        Optional second friction experiment per joint (e.g. the same design at other frequencies),
        used for validation instead of the last 15 % of the first one.
    """

    payload: Payload
    motor: tuple
    gravity: tuple
    friction: tuple
    excitation: tuple
    tool: Payload | None = None
    friction_validation: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "friction_validation", tuple(self.friction_validation))
        if not isinstance(self.payload, Payload):
            raise ParameterError(f"CalibrationData.payload must be a Payload; got {type(self.payload).__name__}.")
        for name in ("motor", "gravity", "friction", "excitation"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
            if not getattr(self, name):
                raise RecordingError(
                    f"CalibrationData.{name} must hold at least one experiment; got none. "
                    f"Record the {name} experiment (see identification.data.dataset)."
                )

    @property
    def n_dof(self) -> int:
        return self.gravity[0].n_dof


def _find(directory: Path, pattern: str):
    regex = re.compile(pattern)
    try:
        paths = sorted(directory.iterdir())
    except OSError as exc:
        raise RecordingError(
            f"data directory {str(directory)!r} cannot be listed ({exc.strerror or exc}). Check its permissions."
        ) from None
    return [
        path
        for path in paths
        if path.suffix.lower() in _SUFFIXES and not path.name.endswith(".truth.npz") and regex.fullmatch(path.stem)
    ]


def _joint(path: Path, n_dof: int | None) -> int:
    """The 0-based joint of a file named ``..._j<k>...`` (k counted from 1), refusing k = 0 or k > n_dof."""
    k = int(re.search(r"_j([0-9]+)", path.stem).group(1))
    if k < 1:
        first = path.name.replace("_j0", "_j1", 1)
        raise RecordingError(
            f"{path.name}: the joint number in a file name must be 1 or more (joints are numbered from 1 in file "
            f"names); got j{k}. Rename the files so that the first joint is {first}, the second _j2, and so on."
        )
    if n_dof is not None and k > n_dof:
        raise RecordingError(
            f"{path.name}: the joint number in a file name must be 1..{n_dof} (the robot has {n_dof} joints, "
            f"numbered from 1); got j{k}. Rename or remove the file."
        )
    return k - 1


def _one_per_joint(paths: list, n_dof: int | None) -> list:
    """``(joint, path)`` per file, refusing two files of one joint (``friction_j1.csv`` and ``friction_j1.npz``)."""
    seen = {}
    for path in paths:
        joint = _joint(path, n_dof)
        if joint in seen:
            raise RecordingError(
                f"{seen[joint].name} and {path.name} are both joint {joint + 1}'s recording of one experiment. "
                "Keep one of them."
            )
        seen[joint] = path
    return list(seen.items())


def load_calibration_data(directory, n_dof: int | None = None, robot=None) -> CalibrationData:
    """Read a data directory laid out as in the module docstring.

    Parameters
    ----------
    directory : str or Path
    n_dof : int, optional
        Joints of the robot, checked against every file.
    robot : RobotDescription, optional
        Read each file as the robot file's ``[recording]`` says (``robot_recordings.load_robot_recording``:
        motor-side signals mapped to the joints, files without time timed by its sample rate).

    Returns
    -------
    CalibrationData

    Raises
    ------
    FileNotFoundError
        When the directory or payload.json is missing.
    RecordingError
        When ``directory`` is a file, an experiment has no file, a motor sweep lacks its partner, a
        file name's joint number is 0 or above ``n_dof``, or a recording is refused by ``load_recording``.
    """
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise RecordingError(
            f"data directory {str(directory)!r} is a file, not a folder. Pass the folder that holds payload.json "
            "and the recordings (--data)."
        )
    if not directory.is_dir():
        raise FileNotFoundError(f"data directory {str(directory)!r} does not exist. Check the --data path.")
    payload_path = directory / "payload.json"
    if not payload_path.exists():
        raise FileNotFoundError(
            f"{payload_path} is missing: the motor step needs the calibration mass. "
            'Write {"mass": 2.0, "com": [0.05, 0.0, 0.05]} there.'
        )
    payload = read_payload(payload_path)

    def read(path):
        return load_recording(path, n_dof) if robot is None else load_robot_recording(path, robot)

    tool = read_payload(directory / "tool.json") if (directory / "tool.json").exists() else None
    motor = []
    for joint, path in _one_per_joint(_find(directory, r"motor_j([0-9]+)_nominal"), n_dof):
        k = joint + 1
        partner = [p for p in (directory / f"motor_j{k}_payload{s}" for s in _SUFFIXES) if p.exists()]
        if not partner:
            raise RecordingError(
                f"{path.name} has no partner motor_j{k}_payload.csv|npz; record the sweep with the mass."
            )
        motor.append((k - 1, read(path), read(partner[0])))
    friction = [(joint, read(p)) for joint, p in _one_per_joint(_find(directory, r"friction_j([0-9]+)"), n_dof)]
    friction_validation = [
        (joint, read(p)) for joint, p in _one_per_joint(_find(directory, r"friction_j([0-9]+)_validation"), n_dof)
    ]
    gravity = [read(p) for p in _find(directory, r"gravity.*")]
    excitation = [read(p) for p in _find(directory, r"(excitation|sine).*")]
    for name, items in (
        ("motor_j<k>_nominal", motor),
        ("gravity", gravity),
        ("friction_j<k>", friction),
        ("excitation", excitation),
    ):
        if not items:
            raise RecordingError(
                f"{directory}: no {name}.csv|npz recording found. Add it (see identification.data.dataset)."
            )
    return CalibrationData(
        payload=payload,
        motor=tuple(motor),
        gravity=tuple(gravity),
        friction=tuple(friction),
        excitation=tuple(excitation),
        tool=tool,
        friction_validation=tuple(friction_validation),
    )


def save_calibration_data(data: CalibrationData, directory, fmt: str = "npz", overwrite: bool = False) -> Path:
    """Write ``data`` in the directory layout of the module docstring (atomic files)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    atomic_write(directory / "payload.json", lambda h: h.write(payload_json(data.payload) + "\n"), overwrite=overwrite)
    if data.tool is not None:
        atomic_write(directory / "tool.json", lambda h: h.write(payload_json(data.tool) + "\n"), overwrite=overwrite)
    for joint, nominal, loaded in data.motor:
        save_recording(nominal, directory / f"motor_j{joint + 1}_nominal.{fmt}", overwrite=overwrite)
        save_recording(loaded, directory / f"motor_j{joint + 1}_payload.{fmt}", overwrite=overwrite)
    for k, rec in enumerate(data.gravity):
        save_recording(rec, directory / (f"gravity.{fmt}" if k == 0 else f"gravity_{k + 1}.{fmt}"), overwrite=overwrite)
    for joint, rec in data.friction:
        save_recording(rec, directory / f"friction_j{joint + 1}.{fmt}", overwrite=overwrite)
    for joint, rec in data.friction_validation:
        save_recording(rec, directory / f"friction_j{joint + 1}_validation.{fmt}", overwrite=overwrite)
    for k, rec in enumerate(data.excitation):
        save_recording(
            rec, directory / (f"excitation.{fmt}" if k == 0 else f"excitation_{k + 1}.{fmt}"), overwrite=overwrite
        )
    return directory
