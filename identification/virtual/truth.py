"""The truth of a virtual-robot run (SimulationTruth) and the files that keep it beside a recording.

``write_recording`` writes ``<name>.<fmt>`` (the recording), ``<name>.truth.json`` (parameters,
options, hidden physics) and ``<name>.truth.npz`` (noise-free state trajectories); ``read_truth``
and ``drives_from_truth`` read the parameters back as plain data.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from identification.data.io import save_recording
from identification.data.recording import Recording
from identification.virtual.effects import ExtraPhysics, Payload
from identification.virtual.lugre_exact import FRICTION_FIELDS
from psdm_casadi.errors import ParameterError
from psdm_casadi.fileio import OutputFolder, atomic_write
from psdm_casadi.robot import DriveParameters

__all__ = ["TRUTH_FORMAT", "SimulationTruth", "write_recording", "read_truth", "drives_from_truth"]

TRUTH_FORMAT = "psdm-truth/1"


@dataclass(frozen=True, eq=False)
class SimulationTruth:
    """What the virtual robot really was and did: parameters and noise-free state trajectories.

    Attributes
    ----------
    robot_name : str
    standard_parameters : array, shape (n_dof, 11)
        True rigid-body parameters of the robot (without payload and extra physics).
    kt : array, shape (n_dof,)
        True motor torque constants [N m/A].
    friction : array, shape (n_dof, 7)
        True LuGre parameters, columns ``fc, fs, vs, fv, dv, sigma0, sigma1``.
    gravity : array, shape (3,)
        Gravity used in the simulation [m/s^2] (after any extra physics).
    payload : Payload or None
        Known end-effector load.
    extras : tuple of ExtraPhysics
        Hidden extra physics.
    options : SimulationOptions
        Options of the run.
    t, q, qd, qdd, z, tau_motor, tau_friction, tau_extra : arrays
        True trajectories at the samples, (n_samples,) or (n_samples, n_dof).
    """

    robot_name: str
    standard_parameters: np.ndarray
    kt: np.ndarray
    friction: np.ndarray
    gravity: np.ndarray
    payload: Payload | None
    extras: tuple
    options: object  # the SimulationOptions of the run
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    z: np.ndarray
    tau_motor: np.ndarray
    tau_friction: np.ndarray
    tau_extra: np.ndarray

    def describe(self) -> dict:
        """The JSON-serialisable parameter part of the truth."""
        opts = {k: (v.describe() if isinstance(v, ExtraPhysics) else v) for k, v in vars(self.options).items()}
        return {
            "format": TRUTH_FORMAT,
            "robot": self.robot_name,
            "kt": self.kt.tolist(),
            "friction_fields": list(FRICTION_FIELDS),
            "friction": self.friction.tolist(),
            "standard_parameter_layout": (
                "per joint: m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz (link frame origin), Im"
            ),
            "standard_parameters": self.standard_parameters.tolist(),
            "gravity": self.gravity.tolist(),
            "payload": None if self.payload is None else self.payload.describe(),
            "extras": [e.describe() for e in self.extras],
            "options": opts,
        }


def write_recording(
    recording: Recording,
    truth: SimulationTruth,
    directory,
    name: str = "recording",
    fmt: str = "csv",
    overwrite: bool = False,
) -> dict:
    """Write a simulated recording and its truth beside it, atomically.

    Files: ``<name>.<fmt>`` (the recording), ``<name>.truth.json`` (parameters, options, extras) and
    ``<name>.truth.npz`` (noise-free state trajectories t, q, qd, qdd, z, tau_motor, tau_friction, tau_extra).

    Parameters
    ----------
    recording : Recording
    truth : SimulationTruth
    directory : str or Path
        Created when missing.
    name : str
    fmt : {"csv", "npz"}
    overwrite : bool
        Replace existing files; otherwise an existing file raises ``FileExistsError`` before anything is written.
        The files are written into a staging folder and moved into ``directory`` together, so that an error or
        an interrupt leaves none of them.

    Returns
    -------
    dict
        Paths of the written files under keys ``recording``, ``truth``, ``states``.
    """
    if fmt not in ("csv", "npz"):
        raise ParameterError(f"write_recording fmt must be 'csv' or 'npz'; got {fmt!r}.")
    directory = Path(directory)
    paths = {
        "recording": directory / f"{name}.{fmt}",
        "truth": directory / f"{name}.truth.json",
        "states": directory / f"{name}.truth.npz",
    }
    if not overwrite:
        for path in paths.values():
            if path.exists():
                raise FileExistsError(f"{str(path)!r} exists; pass overwrite=True (or --overwrite) to replace it.")
    text = json.dumps(truth.describe(), indent=2, default=_json_default)
    keys = ("t", "q", "qd", "qdd", "z", "tau_motor", "tau_friction", "tau_extra")
    states = {key: getattr(truth, key) for key in keys}
    # the three files appear together or not at all (an error or Ctrl-C leaves none of them)
    with OutputFolder(directory, [p.name for p in paths.values()], shared=True).staging() as stage:
        save_recording(
            recording,
            stage / paths["recording"].name,
            comment=f"virtual robot {truth.robot_name}; truth in {paths['truth'].name}",
        )
        atomic_write(stage / paths["truth"].name, lambda handle: handle.write(text + "\n"))
        atomic_write(stage / paths["states"].name, lambda handle: np.savez(handle, **states), mode="wb")
    return paths


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, ExtraPhysics):
        return value.describe()
    return str(value)


def read_truth(path) -> dict:
    """Read a ``<name>.truth.json`` file written by ``write_recording`` (plain data)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"truth file {str(path)!r} does not exist. Check the path.")
    data = json.loads(path.read_text())
    if data.get("format") != TRUTH_FORMAT:
        raise ParameterError(f"{path.name}: format must be {TRUTH_FORMAT!r}; got {data.get('format')!r}.")
    return data


def drives_from_truth(truth: dict) -> tuple:
    """The true DriveParameters per joint from a truth dictionary (``read_truth``)."""
    return tuple(
        DriveParameters(kt=kt, **dict(zip(truth["friction_fields"], row)))
        for kt, row in zip(truth["kt"], truth["friction"])
    )
