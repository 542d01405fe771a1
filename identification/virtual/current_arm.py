"""A virtual arm that logs motor currents: its user's robot file and its recordings (a torque-constant harness).

The user's file (``CurrentArm.robot_file``) states the DH rows and limits, rough link masses with their centres of
mass at the joints, no rotors, ``[transmission] gear_ratios`` and ``motor_kt`` (the datasheet's constants times a
per-joint error, so a joint whose error is 1.15 reads its currents 15 % too strong). The recordings
(``write_current_recordings``) are the true arm's motor currents along faded sums of sines (``faded_sines``), with
a known payload (and its ``.payload.json`` sidecar) on the runs that carry one: what a torque-constant check
needs, a truth it can be held to.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from identification.virtual.effects import Payload
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.description import RobotDescription

__all__ = ["CurrentArm", "CurrentRun", "faded_sines", "write_current_recordings"]

RATE = 1000.0  # [Hz] the logged rate


@dataclass(frozen=True, eq=False)
class CurrentArm:
    """A true arm whose drives log motor currents, and what its user's robot file states about it.

    Attributes
    ----------
    truth : RobotDescription
        The true arm (links, rotors, drives, limits) the recordings come from.
    rows : tuple
        Its standard DH rows ``(a, alpha, d, theta)``, as the file states them.
    limits : tuple of dict
        Per joint ``q_min, q_max, qd_max, qdd_max, tau_max``, as the file states them.
    joint_names : tuple of str
    file_mass : tuple of float
        The file's (rough) link masses [kg]; its centres of mass sit at the joints.
    gear : tuple of float
        Gear ratios.
    motor_kt : tuple of float
        The true motor torque constants [N m/A]; the file states them times a per-joint error.
    name : str
        The file's ``name``.
    current_noise : float
        Standard deviation of the logged motor currents [A].
    """

    truth: RobotDescription
    rows: tuple
    limits: tuple
    joint_names: tuple
    file_mass: tuple
    gear: tuple
    motor_kt: tuple
    name: str
    current_noise: float = 0.03

    def robot_file(self, kt_error) -> str:
        """The user's robot file (TOML text) with ``motor_kt`` the true constants times ``kt_error`` per joint."""
        text = ['format = "psdm-robot/1"', f'name = "{self.name}"', 'convention = "standard"',
                "gravity = [0.0, 0.0, -9.81]"]  # fmt: skip
        for name, (a, alpha, d, theta), limits in zip(self.joint_names, self.rows, self.limits):
            text += ["", "[[joint]]", f'name = "{name}"', f"a = {a}", f"alpha = {alpha!r}", f"d = {d}",
                     f"theta = {theta}", *(f"{k} = {v}" for k, v in limits.items())]  # fmt: skip
        for m in self.file_mass:
            text += ["", "[[link]]", f"mass = {m}", "com = [0.0, 0.0, 0.0]",
                     f"inertia = [{0.01 * m}, {0.01 * m}, {0.006 * m}, 0.0, 0.0, 0.0]"]  # fmt: skip
        stated = [float(k * e) for k, e in zip(self.motor_kt, kt_error)]
        text += ["", "[transmission]", f"gear_ratios = {list(self.gear)}", f"motor_kt = {stated}", "", "[recording]",
                 'side = { q = "joint", tau = "motor", current = "motor" }', ""]  # fmt: skip
        return "\n".join(text)


@dataclass(frozen=True)
class CurrentRun:
    """One recording to write: its file stem, its length [s] and the known payload it carries (or None).

    ``payload`` is the sidecar's content, ``{"mass": kg, "com": [x, y, z]}`` in the flange frame.
    """

    name: str
    duration: float
    payload: dict | None = None


def faded_sines(robot: RobotDescription, duration: float, rng: np.random.Generator) -> tuple:
    """``(t, q)`` at 1 kHz: three sines (0.1-0.5 Hz) per joint within half its limits, faded in and out over 1 s.

    Starting and ending at rest at ``q = 0``, the motion needs no settling and no trimming.
    """
    t = np.arange(0.0, duration + 1e-9, 1.0 / RATE)
    fade = 0.5 * (1.0 - np.cos(np.pi * np.minimum(1.0, np.minimum(t, duration - t))))
    q = np.zeros((t.size, robot.n_dof))
    for j in range(robot.n_dof):
        omega = 2.0 * np.pi * rng.uniform(0.1, 0.5, 3)
        phase, weight = rng.uniform(0.0, 2.0 * np.pi, 3), rng.uniform(0.5, 1.0, 3)
        scale = 0.5 * min(robot.q_max[j] / weight.sum(), robot.qd_max[j] / (weight * omega).sum(),
                          robot.qdd_max[j] / (weight * omega**2).sum())  # fmt: skip
        x = (scale * weight * np.sin(np.outer(t, omega) + phase)).sum(axis=1)
        q[:, j] = fade * (x - x[0])
    return t, q


def write_current_recordings(
    folder: Path,
    arm: CurrentArm,
    runs,
    rng: np.random.Generator,
    q_prefix: str = "q_",
    i_prefix: str = "i_",
    extras=(),
) -> tuple:
    """Write ``<run.name>.csv`` (columns ``timestamp``, ``<q_prefix>1..n``, ``<i_prefix>1..n``) per run into
    ``folder``, the true arm's motor currents with noise, and ``<run.name>.payload.json`` where the run carries a
    payload. ``extras``: effects the true arm has beside its rigid body and drives (``virtual.effects``: a spring, a
    friction hump), in every run, which the user's file does not state. Returns the recordings' paths, in the order of
    ``runs``; the same ``rng`` state gives the same files.
    """
    folder.mkdir(parents=True, exist_ok=True)
    n = arm.truth.n_dof
    gain = np.array(arm.gear, dtype=float) * np.array(arm.motor_kt, dtype=float)
    header = ["timestamp"] + [f"{q_prefix}{j + 1}" for j in range(n)] + [f"{i_prefix}{j + 1}" for j in range(n)]
    paths = []
    for run in runs:
        load = run.payload
        payload = None if load is None else Payload(mass=load["mass"], com=np.array(load["com"]))
        options = SimulationOptions(rate=RATE, record_tau=True, record_current=False, tau_noise_std=0.0,
                                    payload=payload, q_noise_std=0.0)  # fmt: skip
        rec, _ = simulate_recording(arm.truth, faded_sines(arm.truth, run.duration, rng), options, rng, extras)
        current = rec.tau / gain + rng.normal(0.0, arm.current_noise, rec.tau.shape)
        path = folder / f"{run.name}.csv"
        np.savetxt(path, np.column_stack([rec.t, rec.q, current]), delimiter=",", header=",".join(header),
                   comments="", fmt="%.9g")  # fmt: skip
        if load is not None:
            path.with_suffix(".payload.json").write_text(json.dumps(load))
        paths.append(path)
    return tuple(paths)
