"""A 210 kg-class heavy arm as its controller traces it: a case of ``unseen_cases`` (``heavy_trace_percent``).

The HX-210 of ``unseen_cases`` (1 t of links, a hydropneumatic counterbalance on joint 2: a gas strut that stiffens as
it is compressed) traced by its controller over a morning's first minutes:

- one CSV per trace, a 12 ms interpolation cycle (83.3 Hz) with time stamps in milliseconds that jitter, two cycles
  dropped in each trace, axis angles in degrees and motor currents in per cent of each motor's rated current, the
  vendor's column names (``TimeStamp``, ``AxisAct_A1..6``, ``CurrAct_A1..6``);
- the robot file written from the datasheet: the DH table, CAD link inertials 5-15 % off, rotor inertias from the
  motors' inertias times the gear ratios squared (10 % off), the gear ratios (joint 1's turns the other way), the
  motors' torque constants and rated currents (``[transmission]``), with a datasheet-style CSV and a README beside;
- a cold start: the arm has stood overnight and its friction starts 1.45 times the warm arm's, falling as
  ``1 + 0.45 exp(-t / 150 s)`` over the session (no temperature is logged); the first trace starts with 2 s at rest;
- a gripper (85 kg, centre of mass 0.22 m out on the flange axis) mounted for the second training trace and taken
  off for the held-out one, which no file states (no sidecar: the user did not think of it);
- the held-out trace pauses 3 s at its centre pose half-way through (the cell's door opened).

The truth (links, the counterbalance, the gripper, the floor: current noise, LuGre's dynamics and the held-out
trace's warming left over) is kept in the :class:`unseen_cases.Case`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from unseen_cases import Case, _hx210_truth, _reference, friction_shapes

from identification.virtual.counterbalance import gas_spring_counterbalance
from identification.virtual.effects import Payload
from identification.virtual.lugre_exact import LuGreArrays, steady_state_friction
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.description import LinkInertia
from psdm_casadi.robot_writer import write_robot_file

__all__ = ["DATASHEET", "heavy_trace"]

#: The drives' datasheet per axis: gear ratio (motor turns per joint turn; A1's motor turns the other way), motor
#: torque constant [N m/A], rated current [A], motor inertia [kg m^2].
DATASHEET = (
    (-225.0, 2.1, 28.0, 0.0083),
    (240.0, 2.1, 32.0, 0.0080),
    (200.0, 1.6, 24.0, 0.0065),
    (120.0, 0.9, 12.0, 0.0026),
    (110.0, 0.9, 12.0, 0.0028),
    (80.0, 0.6, 8.0, 0.0022),
)
CYCLE = 0.012  # [s] the controller's interpolation cycle
CURRENT_NOISE = 0.1  # [% of the rated current]
COLD, WARMING_S = 0.45, 150.0  # friction over the warm arm's at the cold start, its time constant [s]
GRIPPER = Payload(mass=85.0, com=np.array([0.0, 0.0, 0.22]))
#: (file stem, start in the session [s], length [s], gripper mounted, pause half-way [s]); the last is held out
RUNS = (("trace_001", 0.0, 40.0, False, 0.0), ("trace_002", 240.0, 40.0, True, 0.0),
        ("trace_003", 600.0, 24.0, False, 3.0))  # fmt: skip


def _gains() -> np.ndarray:
    """[N m per % of the rated current] joint torque per per cent of each motor's rated current."""
    return np.array([abs(g) * kt * rated / 100.0 for g, kt, rated, _ in DATASHEET])


def _files(folder: Path, rng):
    """Write the user's robot file, the datasheet and its README; return (user's file, the true robot)."""
    base, truth = _hx210_truth(folder)

    def off(low: float, high: float) -> float:
        return 1.0 + float(rng.choice([-1.0, 1.0])) * float(rng.uniform(low, high))

    links = tuple(LinkInertia(mass=k.mass * off(0.05, 0.15), com=np.asarray(k.com) * off(0.05, 0.15),
                              inertia=np.asarray(k.inertia) * off(0.05, 0.15)) for k in truth.links)  # fmt: skip
    rotors = np.array([m * g**2 * off(0.0, 0.10) for g, _, _, m in DATASHEET])
    user = dataclasses.replace(base, links=links, rotor_inertia=rotors, source=None)
    path = write_robot_file(user, folder / "hx210_cad.toml", overwrite=True)
    numbers = [", ".join(f"{row[k]:g}" for row in DATASHEET) for k in range(3)]
    path.write_text(path.read_text() + f"\n[transmission]\ngear_ratios = [{numbers[0]}]\nmotor_kt = [{numbers[1]}]\n"
                    f"rated_current = [{numbers[2]}]\n\n"
                    '[recording]\nside = { q = "joint", current = "motor" }\n')  # fmt: skip
    rows = "\n".join(f"A{j + 1},{g:g},{kt:g},{rated:g},{m:g}" for j, (g, kt, rated, m) in enumerate(DATASHEET))
    (folder / "hx210_drives_datasheet.csv").write_text(
        "axis,gear_ratio,motor_kt_Nm_per_A,rated_current_A,motor_inertia_kgm2\n" + rows + "\n"
    )
    (folder / "README.txt").write_text(
        "HX-210 traces, cell 4, first start of the morning.\nTimeStamp: ms since the trace started (12 ms IPO cycle)."
        "\nAxisAct_A1..6: axis angles [deg]. CurrAct_A1..6: motor current [% of the motor's rated current].\n"
        "Drives: hx210_drives_datasheet.csv (rated currents, gear ratios, motor kt).\n"
        "trace_002: the gripper was on (weight not known).\n"
    )
    return path, truth


def _paused(reference, pause: float):
    """``reference`` (t, q) slowed to rest at its first pose for ``pause`` seconds around its middle (1 s ramps)."""
    t, q = reference
    if pause <= 0:
        return t, q
    middle = 0.5 * t[-1]
    distance = np.clip((np.abs(t - middle) - 0.5 * pause) / 1.0, 0.0, 1.0)
    weight = 0.5 * (1.0 - np.cos(np.pi * distance))
    return t, q[0] + weight[:, None] * (q - q[0])


def _trace(folder: Path, truth, gas, run, rng) -> tuple:
    """Write one trace; return (its path, the floor per joint [N m]: current noise, LuGre's dynamics, warming)."""
    name, start, seconds, loaded, pause = run
    reference = _paused(_reference(truth, seconds, rng, still=2.0 if start == 0 else 0.0, slow=0.7), pause)
    options = SimulationOptions(rate=1000.0, record_tau=True, record_current=False, tau_noise_std=0.0,
                                payload=GRIPPER if loaded else None, q_noise_std=0.0)  # fmt: skip
    rec, sim = simulate_recording(truth, reference, options, rng, extras=(gas,))
    steady = steady_state_friction(sim.qd, LuGreArrays.from_drives(truth.drives))
    warming = COLD * np.exp(-(start + rec.t) / WARMING_S)[:, None] * steady
    keep = np.arange(0, rec.n_samples, int(round(CYCLE * 1000.0)))
    keep = np.delete(keep, rng.choice(np.arange(20, keep.size - 20), 2, replace=False))  # two cycles dropped
    stamps = rec.t[keep] + rng.normal(0.0, 4e-4, keep.size)  # the trace's clock jitters by 0.4 ms
    stamps = np.maximum.accumulate(stamps)
    stamps[1:] = np.maximum(stamps[1:], stamps[:-1] + 1e-3)
    signs = np.sign([row[0] for row in DATASHEET])
    noise = rng.normal(0.0, CURRENT_NOISE, (keep.size, 6))
    percent = np.round(signs * (rec.tau + warming)[keep] / _gains() + noise, 2)  # logged to 0.01 %
    header = ["TimeStamp", *(f"AxisAct_A{j + 1}" for j in range(6)), *(f"CurrAct_A{j + 1}" for j in range(6))]
    path = folder / f"{name}.csv"
    data = np.column_stack([1000.0 * (stamps - stamps[0]), np.degrees(rec.q[keep]), percent])
    formats = ["%.1f"] + ["%.4f"] * 6 + ["%.2f"] * 6  # ms, degrees, % as the trace writes them
    np.savetxt(path, data, delimiter=",", header=",".join(header), comments="", fmt=formats)
    dynamic = sim.tau_friction - steady  # LuGre's departure from its steady state
    floor = np.sqrt((CURRENT_NOISE * _gains()) ** 2 + np.mean(dynamic**2, axis=0) + np.mean(warming**2, axis=0))
    return path, floor


def heavy_trace(folder: Path, rng) -> Case:
    """Write the case's files into ``folder`` (the traces drawn from ``rng``) and return it with its truth."""
    user, truth = _files(folder, rng)
    low, high = np.asarray(truth.q_min), np.asarray(truth.q_max)
    centre = np.clip(0.0, low + 0.25 * (high - low), high - 0.25 * (high - low))  # as ``_reference`` centres them
    share = float(rng.uniform(0.5, 0.8))
    gas = gas_spring_counterbalance(truth, 1, centre, share, a=0.2, b=0.6, stiffening=0.5)
    paths, floor = [], None
    for run in RUNS:
        path, floor = _trace(folder, truth, gas, run, rng)
        paths.append(path)
    return Case(
        name="heavy_trace_percent",
        what=f"HX-210 (210 kg class) controller trace: 12 ms cycle with jitter, 2 cycles dropped, degrees, motor "
        f"currents in % of rated (datasheet in [transmission]), CAD masses 5-15 % off, hydropneumatic balancer on J2 "
        f"taking {share:.0%} of its gravity, cold start (friction 1.45x -> 1x), an unstated 85 kg gripper on trace 2, "
        "a 3 s pause in the held-out trace",
        robot=user,
        train=tuple(paths[:-1]),
        validate=paths[-1],
        extra=("--columns", "t=TimeStamp:ms,q=AxisAct_A:deg,i=CurrAct_A:%"),
        unstated=("--columns", "t=TimeStamp:ms,q=AxisAct_A:deg,i=CurrAct_A"),  # the % read as amperes
        # the fix as the option to pass for this file: its own columns with the unit added (cli.column_hint)
        refusal_words=("trace_001.csv", "rated current", "--columns t=TimeStamp:ms,q=AxisAct_A:deg,i=CurrAct_A:%"),
        true_links=np.array([link.mass for link in truth.links]),
        payload_mass=GRIPPER.mass,
        payload_known=False,
        floor_nm=floor,
        hidden=(("counterbalance", 2),),
        friction_shapes=friction_shapes(truth),
        effects=(gas,),
    )
