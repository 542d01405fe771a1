"""Pre-sliding or elasticity: how many true joint elasticities the diagnosis names, and how many it names falsely.

The virtual Denso VS-6556G (LuGre friction: its bristles give pre-sliding on every joint; torque sensors, 0.1 N m
noise) is recorded with a joint elasticity of 0.2 deg torsion at the joint's RMS torque on one joint, and without
any; each recording pair is diagnosed against the robot file's LuGre friction as the selection's first round sees
it (the nominal model alone, ``rigid_body="prior"``), and the elasticity of each joint is compared with pre-sliding
alone on it (``diagnosis.presliding_or_elasticity.compare``). Two motions:

- ``bench``: the diagnosis benchmark's motion (``diagnosis.exciting_reference``), 12 s training and the next 6 s for
  validation, joints 2, 3, 5, 6 (seed 2: no compliance only, as measured when the rule was written);
- ``sine``: 10 s and 5 s sine experiments (``trajopt.experiments.sine_experiment``), joints 5 and 6.

Per case: the validation RMSE of the joint with each, the training blocks the elasticity wins beyond the noise
(of 4), whether it is named (``named``: the rule, three blocks of four and every validation recording) and whether
every block would have been needed (``named_all_blocks``: the rule before). Targets: no joint without compliance
named (``false_named`` 0) and more true elasticities named than with every block.

``--torsion`` sets the true torsion [deg] at the RMS torque (0.2, the elasticity's nominal secant, by default): the
comparison fits the secant's size on the training recording (``presliding_or_elasticity.fitted_torsion``), and another
torsion measures that.

Usage: python benchmarks/presliding_or_elasticity.py [--seeds 0 1 2 3 4 5 6] [--motions bench sine] [--torsion 0.2]
       [--json]
"""

from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np
from bench_support import DENSO_FILE, print_json, print_table
from diagnosis import exciting_reference, reference_scale, simulate_pair

from identification.diagnosis import DiagnosisOptions
from identification.diagnosis.candidates import JointElasticityTerm
from identification.diagnosis.design import WeightedDesign, joint_weights, left_out
from identification.diagnosis.diagnose import prepare_problem
from identification.diagnosis.friction_rival import FrictionRival, PreslidingColumn, fitted_scales
from identification.diagnosis.presliding_or_elasticity import compare
from identification.virtual.recording_pair import recording_pair
from identification.virtual.transmission_effects import JointElasticity
from psdm_casadi.derive import derive_psdm
from psdm_casadi.robot import load_robot
from trajopt.experiments import sine_experiment

TORSION_DEG = 0.2
JOINTS = {"bench": (1, 2, 4, 5), "sine": (4, 5)}


def _pairs(robot, model, train, validation, joints) -> dict:
    """``RivalPair`` of each joint's elasticity and pre-sliding, as the selection's first round compares them."""
    problem = prepare_problem(robot, model, train, [validation], DiagnosisOptions(rigid_body="prior"))
    sigma = joint_weights(problem.ctx_t.tau, left_out(problem.ctx_t))
    design = WeightedDesign(problem.base_t, problem.base_v, problem.y_t, problem.y_v, sigma)
    rival = FrictionRival(problem.ctx_t, [(problem.ctx_v, problem.base_v, problem.y_v)])
    scales = fitted_scales(design, problem.ctx_t, joints)
    out = {}
    for j in joints:
        presliding = PreslidingColumn(j, float(scales[j, 2]))
        out[j] = compare(design, JointElasticityTerm(joint=j), presliding, rival.train_ctx, rival.validations)
    return out


def _sine_pair(robot, extras, seed):
    """10 s training and 5 s validation sine experiments (``identification.virtual.recording_pair``, as the diagnosis
    tests draw theirs)."""

    def sine(duration, rng):
        return sine_experiment(robot, duration=duration, rng=rng).reference()

    return recording_pair(robot, extras, seed, sine, (10.0, 5.0))


def _recordings(robot, motion, seed):
    """``(pair(extras), tau_rms)``: a function simulating the seed's training and validation recordings with
    ``extras``, and each joint's RMS torque along the motion (the torsion's scale)."""
    if motion == "sine":
        clean, _ = _sine_pair(robot, [], seed)
        return (lambda extras: _sine_pair(robot, extras, seed)), np.sqrt(np.mean(clean.tau**2, axis=0))
    rng = np.random.default_rng(10_000 * seed + 99)
    reference = exciting_reference(robot, 18.0, rng)
    tau_rms = reference_scale(robot, reference, 18.0).tau_rms
    return (lambda extras: simulate_pair(robot, extras, reference, seed, train_s=12.0)), tau_rms


def _row(motion, seed, joint, truth, pair) -> dict:
    (p, e), = pair.validation  # fmt: skip
    return {
        "motion": motion,
        "seed": seed,
        "joint": joint + 1,
        "elasticity": truth,
        "val_presliding": p,
        "val_elasticity": e,
        "blocks_won": pair.blocks_won,
        "named": pair.elasticity_wins,
        "named_all_blocks": pair.elasticity_wins and pair.blocks_won == len(pair.blocks),
    }


def run(seeds, motions, torsion_deg=TORSION_DEG) -> list:
    robot = load_robot(DENSO_FILE)
    model = derive_psdm(robot)
    rows = []
    for motion in motions:
        for seed in seeds:
            simulate, tau_rms = _recordings(robot, motion, seed)
            joints = JOINTS[motion]
            for j, pair in _pairs(robot, model, *simulate([]), joints).items():
                rows.append(_row(motion, seed, j, False, pair))
            if motion == "bench" and seed == 2:
                continue
            for j in joints:
                stiffness = float(tau_rms[j]) / np.radians(torsion_deg)
                train, validation = simulate([JointElasticity(joint=j, stiffness=stiffness)])
                rows.append(_row(motion, seed, j, True, _pairs(robot, model, train, validation, [j])[j]))
    return rows


def summary(rows) -> dict:
    out = {}
    for motion in sorted({r["motion"] for r in rows}):
        true = [r for r in rows if r["motion"] == motion and r["elasticity"]]
        null = [r for r in rows if r["motion"] == motion and not r["elasticity"]]
        out[motion] = {
            "true_cases": len(true),
            "true_named": sum(r["named"] for r in true),
            "true_named_all_blocks": sum(r["named_all_blocks"] for r in true),
            "null_cases": len(null),
            "false_named": sum(r["named"] for r in null),
            "false_named_all_blocks": sum(r["named_all_blocks"] for r in null),
        }
    total = {k: sum(m[k] for m in out.values()) for k in next(iter(out.values()))}
    gain = total["true_named"] > total["true_named_all_blocks"]
    return {"motions": out, "total": total, "targets_met": total["false_named"] == 0 and gain}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(7)))
    parser.add_argument("--motions", nargs="+", choices=sorted(JOINTS), default=["bench", "sine"])
    parser.add_argument("--torsion", type=float, default=TORSION_DEG, help="true torsion [deg] at the RMS torque")
    parser.add_argument("--json", action="store_true", help="print the cases and the summary as JSON")
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a sine experiment may graze a limit
        if not (np.isfinite(args.torsion) and args.torsion > 0):
            parser.error(f"--torsion must be a torsion > 0 [deg]; got {args.torsion}")
        rows = run(args.seeds, args.motions, args.torsion)
    result = summary(rows)
    if args.json:
        print_json({"cases": rows, **result})
    else:
        print_table(rows, list(rows[0]))
        print()
        print_table([{"motion": k, **v} for k, v in result["motions"].items()], ["motion", *result["total"]])
        print(f"targets met: {result['targets_met']}")
    return 0 if result["targets_met"] else 1


if __name__ == "__main__":
    sys.exit(main())
