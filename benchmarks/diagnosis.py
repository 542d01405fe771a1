"""Concealed-effect benchmark of the missing-physics diagnosis (issue 6).

Each scenario simulates the virtual robot (Denso VS-6556G or Franka Panda) with one hidden effect (or two,
or none) of a size and on a joint drawn from ranges with a seed, records joint torques with noise, and
runs ``diagnose`` on a training and a validation recording. The diagnoser sees only the robot
description and the recordings. A scenario counts as correct when the first finding names the hidden
effect (or an effect the data cannot tell apart from it, see ``EQUIVALENT_EFFECTS``) on the right
joint, and, for two effects, both are found; clean scenarios must give no finding.

    python benchmarks/diagnosis.py [--seeds 0 1 2] [--json] [--quick]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

# benchmarks/identification.py would shadow the identification package: drop this folder from the path
_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]
import importlib.util  # noqa: E402

_spec = importlib.util.spec_from_file_location("_bench_common", _HERE / "_common.py")
_common = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_common)
DENSO_FILE, load_panda, print_table = _common.DENSO_FILE, _common.load_panda, _common.print_table

from identification import extra_physics as xp  # noqa: E402
from identification.diagnosis import EQUIVALENT_EFFECTS, DiagnosisOptions, diagnose  # noqa: E402
from identification.diagnosis.hidden_effects import Backlash, JointElasticity  # noqa: E402
from identification.experiments import sine_reference  # noqa: E402
from identification.synthetic import SimulationOptions, simulate_recording  # noqa: E402
from psdm_casadi.derive import derive_psdm  # noqa: E402
from psdm_casadi.robot import DriveParameters, load_robot  # noqa: E402

TRAIN_S, VALIDATE_S = 24.0, 12.0
TAU_NOISE = 0.1  # N m


def panda_with_drives(panda):
    """The Panda with plausible drives (joint-torque sensing: kt = 1) and LuGre friction (Gaz et al. sizes)."""
    fc = [0.55, 0.85, 0.65, 1.2, 0.8, 0.3, 0.55]
    fv = [0.6, 0.6, 0.5, 0.5, 0.3, 0.3, 0.2]
    drives = tuple(DriveParameters(kt=1.0, fc=c, fs=1.2 * c, vs=0.05, fv=v, dv=1.0, sigma0=5e3, sigma1=5.0)
                   for c, v in zip(fc, fv))
    return dataclasses.replace(panda, drives=drives, rotor_inertia=np.full(7, 0.0))


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _sign(rng):
    return float(rng.choice([-1.0, 1.0]))


# Each maker: (robot_key, rng) -> (list of (effect key, joint or None, ExtraPhysics, true parameters))
def _spring(robot, rng, joints):
    j = int(rng.choice(joints))
    k, q0 = _u(rng, 15, 60) * _sign(rng), _u(rng, -0.3, 0.3)
    return [("spring", j, xp.Spring(joint=j, stiffness=k, q0=q0), {"k": k, "q0": q0})]


def _offset(robot, rng, joints):
    j = int(rng.choice(joints))
    off = _u(rng, 1.0, 4.0) * _sign(rng)
    vec = np.zeros(robot.n_dof)
    vec[j] = off
    return [("torque_offset", j, xp.TorqueOffset(offset=tuple(vec)), {"offset": off})]


def _asym(robot, rng, joints):
    j = int(rng.choice(joints))
    d = _u(rng, 1.5, 4.0)
    return [("coulomb_asymmetry", j, xp.CoulombAsymmetry(joint=j, delta=d), {"delta": d})]


def _load(robot, rng, joints):
    j = int(rng.choice(joints))
    mu = _u(rng, 0.06, 0.15)
    return [("load_dependent_friction", j, xp.LoadDependentFriction(joint=j, coefficient=mu), {"coefficient": mu})]


def _drift(robot, rng, joints):
    j = int(rng.choice(joints))
    rate = _u(rng, 0.05, 0.15)
    return [("friction_drift", j, xp.FrictionDrift(joint=j, rate=rate), {"rate": rate})]


def _ripple(robot, rng, joints):
    j = int(rng.choice(joints))
    a, h = _u(rng, 1.0, 3.0), int(rng.integers(3, 13))
    return [("torque_ripple", j, xp.TorqueRipple(joint=j, amplitude=a, harmonic=float(h), phase=_u(rng, 0, 6.28)),
             {"amplitude": a, "harmonic": float(h)})]


def _rotor(robot, rng, joints):
    j = int(rng.choice(joints))
    im = _u(rng, 0.3, 1.0) if robot.n_dof == 6 else _u(rng, 0.1, 0.3)
    vec = np.zeros(robot.n_dof)
    vec[j] = im
    return [("rotor_inertia", j, xp.ExtraRotorInertia(inertia=tuple(vec)), {"inertia": im})]


def _coupling(robot, rng, joints):
    j = int(rng.choice(joints))
    k = int(rng.choice([x for x in range(robot.n_dof) if x != j]))
    c = _u(rng, 1.0, 4.0) * _sign(rng)
    m = np.zeros((robot.n_dof, robot.n_dof))
    m[j, k] = c
    return [("coupling", j, xp.JointCoupling(matrix=m), {"viscous": c, "source_joint": float(k + 1)})]


def _payload(robot, rng, joints):
    m = _u(rng, 2.0, 5.0)
    com = (0.0, 0.0, _u(rng, 0.05, 0.15))
    return [("payload", None, xp.Payload(mass=m, com=com), {"mass": m, "com_z": com[2]})]


def _tilt(robot, rng, joints):
    ang = np.radians(_u(rng, 1.0, 3.0))
    axis = tuple(rng.standard_normal(3))
    return [("gravity_tilt", None, xp.GravityTilt(angle=ang, axis=axis), {"angle_deg": float(np.degrees(ang))})]


def _delay(robot, rng, joints):
    n = int(rng.integers(4, 11))
    return [("delay", None, xp.SignalDelay(samples=n), {"delay_s": n * 1e-3})]


def _backlash(robot, rng, joints):
    j = int(rng.choice(joints))
    b = np.radians(_u(rng, 0.3, 0.8))
    return [("backlash", j, Backlash(joint=j, width=b), {"backlash_rad": b})]


def _elastic(robot, rng, joints):
    j = int(rng.choice(joints))
    k = _u(rng, 2e3, 6e3)
    return [("joint_elasticity", j, JointElasticity(joint=j, stiffness=k), {"stiffness_Nm_per_rad": k})]


MAKERS = {"spring": _spring, "torque_offset": _offset, "coulomb_asymmetry": _asym, "load_dependent_friction": _load,
          "friction_drift": _drift, "torque_ripple": _ripple, "rotor_inertia": _rotor, "coupling": _coupling,
          "payload": _payload, "gravity_tilt": _tilt, "delay": _delay, "backlash": _backlash,
          "joint_elasticity": _elastic}

# (robot, effects); joints drawn among the robot's main axes
SCENARIOS = [
    ("denso", ("spring",)), ("denso", ("torque_offset",)), ("denso", ("coulomb_asymmetry",)),
    ("denso", ("load_dependent_friction",)), ("denso", ("friction_drift",)), ("denso", ("torque_ripple",)),
    ("denso", ("rotor_inertia",)), ("denso", ("coupling",)), ("denso", ("payload",)), ("denso", ("gravity_tilt",)),
    ("denso", ("delay",)), ("denso", ("backlash",)), ("denso", ("joint_elasticity",)),
    ("panda", ("spring",)), ("panda", ("torque_ripple",)), ("panda", ("coupling",)), ("panda", ("payload",)),
    ("denso", ("spring", "torque_ripple")), ("panda", ("torque_offset", "friction_drift")),
    ("denso", ()), ("panda", ()), ("denso", ()),
]
QUICK = [0, 1, 5, 8, 10, 13, 19]


def simulate_pair(robot, extras, seed):
    """Training and validation recordings of the virtual robot with hidden ``extras``."""
    opts = dict(record_tau=True, record_current=False, tau_noise_std=TAU_NOISE)
    rng = np.random.default_rng(1000 * seed)
    ref = sine_reference(robot, duration=TRAIN_S + VALIDATE_S, rng=rng)
    rec, _ = simulate_recording(robot, ref, SimulationOptions(**opts), rng, extras=extras)
    # one experiment, validated on its last part (a drift continues in time)
    return rec.time_slice(-np.inf, TRAIN_S), rec.time_slice(TRAIN_S, np.inf)


def _correct(found, truth_effects):
    """Right effect (or an indistinguishable one) on the right joint for every hidden effect."""
    ok = []
    for key, joint, _, _ in truth_effects:
        names = (key,) + EQUIVALENT_EFFECTS.get(key, ())
        hit = [f for f in found if f.effect in names and (joint is None or joint in f.joints)]
        ok.append(bool(hit))
    return all(ok)


def run(seeds, quick=False, verbose=True):
    robots = {"denso": load_robot(DENSO_FILE)}
    models = {"denso": derive_psdm(robots["denso"])}
    rows = []
    scenarios = [SCENARIOS[i] for i in QUICK] if quick else SCENARIOS
    for seed in seeds:
        for index, (robot_key, effects) in enumerate(scenarios):
            if robot_key not in robots:
                robots[robot_key] = panda_with_drives(load_panda())
                models[robot_key] = derive_psdm(robots[robot_key])
            robot, model = robots[robot_key], models[robot_key]
            rng = np.random.default_rng(10_000 * seed + index)
            main = (1, 2) if robot_key == "denso" else (1, 3)
            truth = [item for key in effects for item in MAKERS[key](robot, rng, main)]
            start = time.perf_counter()
            train, val = simulate_pair(robot, [x[2] for x in truth], 100 * seed + index)
            sim_s = time.perf_counter() - start
            start = time.perf_counter()
            report = diagnose(robot, train, val, DiagnosisOptions(), model=model)
            diag_s = time.perf_counter() - start
            found = report.findings
            clean = not truth
            correct = (not found) if clean else _correct(found, truth)
            row = {"seed": seed, "robot": robot_key, "hidden": "+".join(effects) or "(clean)",
                   "joint": ",".join(str(x[1] + 1) for x in truth if x[1] is not None) or "-",
                   "found": report.summary(), "correct": bool(correct), "false_alarm": bool(clean and found),
                   "sim_s": sim_s, "diag_s": diag_s}
            if truth:
                key, joint, _, true_params = truth[0]
                hit = next((f for f in found if f.effect in (key,) + EQUIVALENT_EFFECTS.get(key, ())), None)
                j = joint if joint is not None else (hit.joints[0] if hit else int(np.argmax(report.rmse_before)))
                row["rmse_before"] = report.rmse_before[j]
                row["rmse_after"] = report.rmse_after[j]
                row["rmse_reduction"] = 1.0 - report.rmse_after[j] / report.rmse_before[j]
                errs = []
                if hit is not None and hit.effect == key:
                    for name, value in true_params.items():
                        if name in hit.parameters and value != 0:
                            errs.append(abs(hit.parameters[name] - value) / abs(value))
                row["param_error"] = max(errs) if errs else None
                row["true"] = {k: float(v) for k, v in true_params.items()}
                row["estimated"] = {k: float(v) for k, v in hit.parameters.items()} if hit else {}
            rows.append(row)
            if verbose:
                print(f"seed {seed} {robot_key:5s} {row['hidden']:32s} -> {row['found']}  "
                      f"[{'ok' if correct else 'WRONG'}] ({sim_s:.0f}+{diag_s:.0f} s)", file=sys.stderr, flush=True)
    effect_rows = [r for r in rows if r["hidden"] != "(clean)"]
    summary = {
        "scenarios": rows,
        "n_scenarios": len(rows),
        "correct_fraction": float(np.mean([r["correct"] for r in rows])),
        "effect_correct_fraction": float(np.mean([r["correct"] for r in effect_rows])) if effect_rows else None,
        "false_alarms": int(sum(r["false_alarm"] for r in rows)),
        "median_rmse_reduction": float(np.median([r["rmse_reduction"] for r in effect_rows])) if effect_rows else None,
        "fraction_rmse_halved": float(np.mean([r["rmse_reduction"] >= 0.5 for r in effect_rows])) if effect_rows else None,
        "seeds": list(seeds),
    }
    return summary


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--quick", action="store_true", help="a subset of 7 scenarios")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    args = parser.parse_args(argv)
    summary = run(args.seeds, quick=args.quick)
    if args.json:
        print(json.dumps(summary, default=float))
    else:
        print_table(summary["scenarios"], ["seed", "robot", "hidden", "joint", "found", "correct", "param_error",
                                           "rmse_before", "rmse_after", "rmse_reduction"])
        print(f"\ncorrect {summary['correct_fraction']:.0%}, false alarms {summary['false_alarms']}, "
              f"median RMSE reduction {summary['median_rmse_reduction']:.0%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
