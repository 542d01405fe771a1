"""A virtual fleet: N robots of one model, a daily health-check motion, and known events with onset days.

Each robot is the built-in robot (default the Denso VS-6556G) with manufacturing spread (every link's inertia
scaled by a few %, friction by tens of %, torque constants by 2 %), written as its own robot file (as if each robot
had been calibrated once: the fleet's baseline), with LuGre friction of linear viscous part (``dv = 1``), a
counterbalance spring on one joint and a torque ripple on another (both tracked by the fleet), day-to-day friction
jitter (temperature) and current noise. Every day it runs the same health-check motion (a two-tone sine per
joint, ``duration`` s at ``rate`` Hz) and logs positions and motor currents: the motor torque is the rigid body of
the robot's true inertia (Pinocchio RNEA, a payload in the last link), LuGre steady-state friction, the spring and
the ripple (``effects.Spring``, ``effects.TorqueRipple``), and the current is that torque over the true torque
constant.

Events (:data:`EVENT_KINDS`), each with an onset day after the baseline window, change one true parameter:
friction wear (Coulomb and static friction rising along a ramp), viscous rise (lubricant ageing, a ramp), a
counterbalance losing stiffness (a step), a payload change (a step), ripple growth (a ramp) and a torque-constant
drop (a step); with ``unmodelled_robots``, a current-sensor offset (:data:`UNMODELLED_KINDS`) that no tracked
term models (a step: only the validation error and the automatic diagnosis see it). Robots without an event are
healthy. :func:`write_virtual_fleet` writes the fleet folder
(``FLEET/ROBOT/YYYY-MM-DD/health.csv``, ``robot.toml``, ``fleet.toml``) and ``truth.json`` beside it.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from identification.data.io import save_recording
from identification.data.recording import Recording
from identification.virtual.effects import Payload, Spring, TorqueRipple
from identification.virtual.lugre_exact import LuGreArrays, steady_state_friction
from psdm_casadi.errors import ParameterError
from psdm_casadi.oracle import build_pinocchio_model
from psdm_casadi.robot import load_robot
from psdm_casadi.robot_writer import write_robot_file

__all__ = [
    "EVENT_KINDS",
    "UNMODELLED_KINDS",
    "FleetEvent",
    "VirtualFleetOptions",
    "health_check_motion",
    "write_virtual_fleet",
]

EVENT_KINDS = ("friction_wear", "viscous_rise", "spring_loss", "payload_change", "ripple_growth", "kt_drop")
#: events the fleet's daily update does not model (no tracked term absorbs them): the baseline's and the refit's
#: validation error rise, and the automatic diagnosis must name the effect
UNMODELLED_KINDS = ("sensor_offset",)
RAMPS = ("friction_wear", "viscous_rise", "ripple_growth")


@dataclass(frozen=True)
class VirtualFleetOptions:
    """Size, motion, spread, noise and events of a virtual fleet (module docstring).

    ``event_robots`` robots carry one event each (``kinds`` in turn), the next ``unmodelled_robots`` robots a
    ``sensor_offset`` each (drawn from a generator of its own, ``seed + 1``, so that the other robots are the same
    with or without them; on a joint without a tracked spring, whose preload would take the offset up); the others
    are healthy. ``sizes`` are the relative changes at the last day (ramps) or from the onset (steps); the payload
    change is in kg; the sensor offset is a fraction of the joint's Coulomb friction.
    """

    n_robots: int = 20
    n_days: int = 30
    start: str = "2026-10-01"
    robot: str = "denso_vs6556g"
    duration: float = 6.0
    rate: float = 200.0
    inertia_spread: float = 0.03
    friction_spread: float = 0.2
    kt_spread: float = 0.02
    friction_jitter: float = 0.01
    current_noise: float = 0.01
    spring_joint: int = 2
    spring_stiffness: float = 150.0
    ripple_joint: int = 4
    ripple_harmonic: int = 12
    ripple_amplitude: float = 1.0
    payload_com: tuple = (0.0, 0.0, 0.05)
    baseline_days: int = 7
    event_robots: int | None = None
    kinds: tuple = EVENT_KINDS
    unmodelled_robots: int = 0
    sizes: tuple = (("friction_wear", 0.5), ("viscous_rise", 0.4), ("spring_loss", -0.3), ("payload_change", 2.0),
                    ("ripple_growth", 2.0), ("kt_drop", -0.1), ("sensor_offset", 0.5))  # fmt: skip
    seed: int = 0

    def __post_init__(self):
        unknown = [k for k in self.kinds if k not in EVENT_KINDS]
        if unknown:
            raise ParameterError(f"VirtualFleetOptions.kinds must be among {EVENT_KINDS}; got {unknown}. Unmodelled "
                                 "events go on their own robots: unmodelled_robots=N.")  # fmt: skip


@dataclass(frozen=True)
class FleetEvent:
    """A known change: robot, kind, joint (1-based; 0 for the payload), onset day index and date, the tracked
    parameter it should show in, and its size (relative, or kg for the payload) at the last day."""

    robot_id: str
    kind: str
    joint: int
    onset_index: int
    onset: str
    parameter: str
    size: float


def health_check_motion(robot, duration: float, rate: float) -> tuple:
    """``(t, q, qd, qdd)`` of the daily motion: per joint two sines within a third of its range and speed."""
    t = np.arange(0.0, duration, 1.0 / rate)
    n = robot.n_dof
    q, qd, qdd = (np.zeros((t.size, n)) for _ in range(3))
    w1, w2 = 2 * np.pi / duration * 2, 2 * np.pi / duration * 5
    for j, joint in enumerate(robot.joints):
        centre = 0.5 * (joint.q_min + joint.q_max)
        amplitude = min(0.3 * (joint.q_max - joint.q_min) / 2, 1.0, 0.3 * joint.qd_max / (0.6 * w1 + 0.4 * w2))
        phase = 0.7 * j
        q[:, j] = centre + amplitude * (0.6 * np.sin(w1 * t + phase) + 0.4 * np.sin(w2 * t + 2 * phase))
        qd[:, j] = amplitude * (0.6 * w1 * np.cos(w1 * t + phase) + 0.4 * w2 * np.cos(w2 * t + 2 * phase))
        qdd[:, j] = -amplitude * (0.6 * w1**2 * np.sin(w1 * t + phase) + 0.4 * w2**2 * np.sin(w2 * t + 2 * phase))
    return t, q, qd, qdd


def _unmodelled(options: VirtualFleetOptions, ids: list, n_dof: int) -> list:
    """The ``sensor_offset`` events of the ``unmodelled_robots`` robots after the event robots."""
    rng = np.random.default_rng(options.seed + 1)
    n_events = options.event_robots if options.event_robots is not None else min(len(ids), 2 * len(options.kinds))
    free = [j for j in range(1, n_dof + 1) if j != options.spring_joint]
    events = []
    for robot_id in ids[n_events : n_events + options.unmodelled_robots]:
        onset = int(rng.integers(options.baseline_days + 2, max(options.baseline_days + 3, options.n_days - 4)))
        joint = int(rng.choice(free))
        day = (dt.date.fromisoformat(options.start) + dt.timedelta(days=onset)).isoformat()
        events.append(FleetEvent(robot_id, "sensor_offset", joint, onset, day, f"rmse_{joint}",
                                 dict(options.sizes)["sensor_offset"]))  # fmt: skip
    return events


def _events(options: VirtualFleetOptions, ids: list, rng) -> list:
    kinds = options.kinds
    n_events = options.event_robots if options.event_robots is not None else min(len(ids), 2 * len(kinds))
    sizes = dict(options.sizes)
    events = []
    for k, robot_id in enumerate(ids[:n_events]):
        kind = kinds[k % len(kinds)]
        onset = int(rng.integers(options.baseline_days + 2, max(options.baseline_days + 3, options.n_days - 4)))
        # a torque constant is identifiable with the rigid body held only where that torque is large beside the
        # friction (the daily update holds the others): its drop goes on joints 1-3 (else it reads as friction)
        joint = {"spring_loss": options.spring_joint, "ripple_growth": options.ripple_joint, "payload_change": 0,
                 "kt_drop": int(rng.integers(1, 4))}.get(kind, int(rng.integers(1, 7)))  # fmt: skip
        parameter = {"friction_wear": f"fc{joint}", "viscous_rise": f"fv{joint}", "spring_loss": f"spring_k_{joint}",
                     "payload_change": "payload_mass", "kt_drop": f"kt{joint}",
                     "ripple_growth": f"ripple_amp{options.ripple_harmonic}_{joint}"}[kind]  # fmt: skip
        day = (dt.date.fromisoformat(options.start) + dt.timedelta(days=onset)).isoformat()
        events.append(FleetEvent(robot_id, kind, joint, onset, day, parameter, sizes[kind]))
    return events


def _factor(event: FleetEvent, day: int, n_days: int) -> float:
    """The event's relative change (or kg) on ``day``: a ramp reaching ``size`` on the last day, or a step."""
    if day < event.onset_index:
        return 0.0
    if event.kind in RAMPS:
        return event.size * (day - event.onset_index + 1) / (n_days - event.onset_index)
    return event.size


@dataclass(frozen=True)
class _Robot:
    """One virtual robot's truth without events: standard parameters, drives, spring and ripple."""

    parameters: np.ndarray
    drives: tuple
    spring: Spring
    ripple: TorqueRipple


def _spread_robot(robot, options: VirtualFleetOptions, rng) -> tuple:
    """(the robot as calibrated: its own inertia, friction and kt; its truth without events)."""
    scale = 1 + options.inertia_spread * rng.standard_normal(robot.n_dof)
    links = [replace(link, mass=link.mass * c, inertia=link.inertia * c) for link, c in zip(robot.links, scale)]
    drives = []
    for d in robot.drives:
        f = np.maximum(1 + options.friction_spread * rng.standard_normal(2), 0.3)
        drives.append(replace(d, fc=d.fc * f[0], fs=d.fs * f[0], fv=d.fv * f[1], dv=1.0,
                              kt=d.kt * (1 + options.kt_spread * rng.standard_normal())))  # fmt: skip
    calibrated = replace(robot.with_links(links, np.asarray(robot.rotor_inertia) * scale), drives=tuple(drives))
    k = options.spring_stiffness * (1 + 0.1 * rng.standard_normal())
    spring = Spring(options.spring_joint - 1, k, q0=float(rng.normal(0.0, 0.1)))
    ripple = TorqueRipple(options.ripple_joint - 1, options.ripple_amplitude * (1 + 0.2 * rng.standard_normal()),
                          options.ripple_harmonic, float(rng.uniform(0, 2 * np.pi)))  # fmt: skip
    return calibrated, _Robot(calibrated.nominal_dynamic_parameters(), tuple(drives), spring, ripple)


def _day_truth(base: _Robot, events: list, day: int, options: VirtualFleetOptions, rng) -> tuple:
    """(parameters, drives, spring, ripple, torque offset) of a robot on a day, with its events and friction jitter.

    A ``sensor_offset`` adds ``size`` times the joint's Coulomb friction to its measured torque (a current-sensor
    offset: unmodelled, the daily update has no column for it)."""
    parameters, spring, ripple = base.parameters, base.spring, base.ripple
    offset = np.zeros(len(base.drives))
    jitter = 1 + options.friction_jitter * rng.standard_normal(len(base.drives))
    drives = [replace(d, fc=d.fc * j, fs=d.fs * j, fv=d.fv * j) for d, j in zip(base.drives, jitter)]
    for event in events:
        c, j = _factor(event, day, options.n_days), event.joint - 1
        if event.kind == "friction_wear":
            drives[j] = replace(drives[j], fc=drives[j].fc * (1 + c), fs=drives[j].fs * (1 + c))
        elif event.kind == "viscous_rise":
            drives[j] = replace(drives[j], fv=drives[j].fv * (1 + c))
        elif event.kind == "kt_drop":
            drives[j] = replace(drives[j], kt=drives[j].kt * (1 + c))
        elif event.kind == "spring_loss":
            spring = replace(spring, stiffness=spring.stiffness * (1 + c))
        elif event.kind == "ripple_growth":
            ripple = replace(ripple, amplitude=ripple.amplitude * (1 + c))
        elif event.kind == "payload_change" and c > 0:
            parameters = Payload(mass=c, com=tuple(options.payload_com)).modify_model(None, parameters)[1]
        elif event.kind == "sensor_offset":
            offset[j] = c * base.drives[j].fc
    return parameters, drives, spring, ripple, offset


def _recording(robot, truth: tuple, motion: tuple, options: VirtualFleetOptions, rng, name: str) -> Recording:
    parameters, drives, spring, ripple, offset = truth
    t, q, qd, qdd = motion
    model = build_pinocchio_model(robot, parameters)
    data = model.createData()
    tau = np.array([pin.rnea(model, data, a, b, c) for a, b, c in zip(q, qd, qdd)])
    tau += steady_state_friction(qd, LuGreArrays.from_drives(drives))
    tau += (spring.torque(t, q.T, qd.T, None) + ripple.torque(t, q.T, qd.T, None)).T + offset
    kt = np.array([d.kt for d in drives])
    current = tau / kt + options.current_noise * rng.standard_normal(tau.shape)
    return Recording(t=t, q=q + 1e-6 * rng.standard_normal(q.shape), current=current, name=name)


def _fleet_toml(options: VirtualFleetOptions) -> str:
    com = ", ".join(f"{c:g}" for c in options.payload_com)
    return (f'[fleet]\nname = "virtual fleet"\nbaseline_days = {options.baseline_days}\n\n[track]\n'
            f"spring = [{options.spring_joint}]\nripple = [[{options.ripple_joint}, {options.ripple_harmonic}]]\n"
            f"payload_com = [{com}]\n")  # fmt: skip


def write_virtual_fleet(folder, options: VirtualFleetOptions | None = None) -> dict:
    """Write a virtual fleet into ``folder`` (created) and its truth into ``folder/../<name>_truth.json``.

    Returns the truth: options, robot ids, events (``FleetEvent`` as dicts), each robot's drives, spring and
    ripple before its events (``truth``) and the healthy robots.
    """
    options = options or VirtualFleetOptions()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(options.seed)
    robot = load_robot(options.robot)
    ids = [f"r{k + 1:02d}" for k in range(options.n_robots)]
    events = _events(options, ids, rng) + _unmodelled(options, ids, robot.n_dof)
    motion = health_check_motion(robot, options.duration, options.rate)
    (folder / "fleet.toml").write_text(_fleet_toml(options))
    start = dt.date.fromisoformat(options.start)
    spread = {}
    for robot_id in ids:
        robot_dir = folder / robot_id
        robot_dir.mkdir(exist_ok=True)
        calibrated, base = _spread_robot(robot, options, rng)
        write_robot_file(calibrated, robot_dir / "robot.toml", overwrite=True)
        spread[robot_id] = {"kt": [d.kt for d in base.drives], "fc": [d.fc for d in base.drives],
                            "fv": [d.fv for d in base.drives], "spring_stiffness": base.spring.stiffness,
                            "spring_q0": base.spring.q0, "ripple_amplitude": base.ripple.amplitude}  # fmt: skip
        mine = [e for e in events if e.robot_id == robot_id]
        for day in range(options.n_days):
            date = (start + dt.timedelta(days=day)).isoformat()
            truth = _day_truth(base, mine, day, options, rng)
            rec = _recording(robot, truth, motion, options, rng, f"{robot_id} {date}")
            (robot_dir / date).mkdir(exist_ok=True)
            save_recording(rec, robot_dir / date / "health.csv", overwrite=True)
    document = {"options": asdict(options), "robots": ids, "events": [asdict(e) for e in events], "truth": spread,
                "healthy": [r for r in ids if r not in {e.robot_id for e in events}]}  # fmt: skip
    (folder.parent / f"{folder.name}_truth.json").write_text(json.dumps(document, indent=1))
    return document
