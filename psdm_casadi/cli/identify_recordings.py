"""``psdm identify`` on exciting recordings (the default route): a physically consistent calibrated-model file.

``psdm identify ROBOT --data A.csv [B.csv ...] [--validate C.csv ...] --out model.json`` filters the
recordings (the cutoff follows the sampling rate and is stated), fits base parameters, friction and
drive inertias by weighted least squares, then physically consistent standard parameters
(``identification.calibration.trajectory_fit``), checks the mass matrix on random configurations,
validates on the held-out recordings against the unconstrained fit and the robot file's prior, and
writes one calibrated-model file (``identification.calibration.calibrated_model``).
"""

from __future__ import annotations

import sys

import numpy as np

from psdm_casadi.cli.checks import add_topic_argument, load_robot_argument, output_file
from psdm_casadi.cli.output import EXIT_BAD_INPUT, EXIT_CHECK_FAILED, EXIT_OK, print_json, progress

MASS_CHECK_CONFIGURATIONS = 2000
FRICTION_SHAPES = ("coulomb-viscous", "stribeck", "lugre")


def add_arguments(p) -> None:
    """The options of the recordings route (the folder route shares ``--data``, ``--out`` and the rest)."""
    p.add_argument("--validate", nargs="+", default=(), help="held-out recordings for the validation report")
    p.add_argument("--offset", action="store_true", help="also identify a constant torque offset per joint")
    p.add_argument(
        "--friction",
        choices=FRICTION_SHAPES,
        default="coulomb-viscous",
        help="friction shape per joint: fc tanh(qd/eps) + fv qd (default); stribeck: (fc + (fs - fc) "
        "exp(-(qd/vs)^2)) tanh(qd/eps) + fv qd, with fs and vs fitted (a --cutoff well above the motion's "
        "frequencies keeps the sharp low-velocity friction the filter would smear); lugre: not in this route yet",
    )
    p.add_argument("--no-drive-inertia", action="store_true", help="do not identify drive (rotor) inertias")
    p.add_argument(
        "--no-consistency",
        action="store_true",
        help="keep the unconstrained weighted least-squares estimate (base parameters only), marked as not checked",
    )
    p.add_argument("--cutoff", type=float, default=None, help="low-pass cutoff [Hz] (default: min(10, rate/10))")
    add_topic_argument(p)


def run(args) -> int:
    from identification.calibration.calibrated_model import CalibratedModel, recording_provenance
    from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
    from identification.data.io import load_recording
    from psdm_casadi.derive import derive_psdm
    from psdm_casadi.model import load_model

    if args.friction == "lugre":
        print("psdm identify: error: --friction lugre is not available on recordings yet (the LuGre shooting fit "
              "needs the paper's friction experiments). Pass --friction stribeck, or run --protocol four-step on "
              "a data folder, which identifies LuGre friction.", file=sys.stderr)  # fmt: skip
        return EXIT_BAD_INPUT
    out = output_file(args.out, "--out", args.overwrite)
    robot = load_robot_argument(args)
    recordings = [load_recording(path, robot.n_dof, robot.joint_names, args.topic) for path in args.data]
    validation = [load_recording(path, robot.n_dof, robot.joint_names, args.topic) for path in args.validate]
    friction = ("fc", "fs", "fv") if args.friction == "stribeck" else ("fc", "fv")
    friction = (*friction, "offset") if args.offset else friction
    options = TrajectoryOptions(friction=friction, drive_inertia=not args.no_drive_inertia,
                                consistency=not args.no_consistency, cutoff_hz=args.cutoff)  # fmt: skip
    if args.model:
        model = load_model(args.model)
    else:
        progress(f"identify: deriving the PSDM model of {robot.name} ...", quiet=args.json)
        model = derive_psdm(robot)
    fit = identify_trajectories(robot, model, recordings, options)
    for warning in _negative_drive_inertias(fit):
        print(warning, file=sys.stderr)
    mass_eigenvalue = _min_mass_eigenvalue(robot, fit) if fit.checked else None
    report = _validation(robot, model, fit, validation, args.validate)
    report["min_mass_eigenvalue"] = mass_eigenvalue
    calibrated = CalibratedModel.from_fit(
        robot, model, fit, robot_source=args.robot,
        recordings=[recording_provenance(r, p) for r, p in zip(recordings, args.data)], validation=report,
    )  # fmt: skip
    consistent = fit.consistent and (mass_eigenvalue is None or mass_eigenvalue > 0)
    if fit.checked and not consistent and not args.allow_inconsistent:
        print(f"psdm identify: error: the identified model is not physically consistent (smallest pseudo-inertia "
              f"eigenvalue {fit.min_pseudo_inertia_eigenvalue:.3g}, smallest mass-matrix eigenvalue "
              f"{mass_eigenvalue:.3g}). Nothing was written to {args.out!r}. Record a better-exciting trajectory, "
              "or pass --allow-inconsistent to save it marked as inconsistent.", file=sys.stderr)  # fmt: skip
        return EXIT_CHECK_FAILED
    if not fit.checked:
        warning = ("psdm identify: warning: --no-consistency: the model holds the unconstrained base parameters "
                   "only; it is NOT checked for physical consistency (its mass matrix may be indefinite).")  # fmt: skip
        print(warning, file=sys.stderr)
    with out.staging() as stage:
        calibrated.save(stage, overwrite=True, allow_inconsistent=True)
    _print(args, robot, model, fit, report, calibrated)
    return EXIT_OK


def _negative_drive_inertias(fit, z: float = 3.0) -> list:
    """Warnings for drive-inertia columns whose unconstrained estimate is below zero by more than ``z`` sigma.

    A rotor inertia cannot be negative; the consistent fit holds it at zero and the joint's fit pays for
    it. The usual cause is a torque signal without the rotors in it: a link-side joint torque sensor.
    """
    out = []
    for name, value, std in zip(fit.drive_names, fit.drive_ols, fit.drive_std):
        if name.startswith("Ia") and value < -z * std:
            out.append(
                f"psdm identify: warning: the data ask for a negative drive inertia on joint {name[2:]} "
                f"(unconstrained {name} = {value:.3g} +- {std:.2g} kg m^2); the consistent fit holds it at 0, "
                "which costs fit on that joint. Torques measured on the link side of the gearbox (joint torque "
                "sensors: Franka Panda, KUKA iiwa) hold no rotor inertia: pass --no-drive-inertia."
            )
    return out


def _min_mass_eigenvalue(robot, fit, seed: int = 0) -> float:
    """Smallest eigenvalue of the identified mass matrix over random configurations within the joint limits."""
    from psdm_casadi.oracle import PinocchioOracle

    oracle = PinocchioOracle(robot, fit.standard)
    q = np.random.default_rng(seed).uniform(robot.q_min, robot.q_max, size=(MASS_CHECK_CONFIGURATIONS, robot.n_dof))
    return float(min(np.linalg.eigvalsh(m)[0] for m in oracle.crba(q)))


def _validation(robot, model, fit, recordings, paths) -> dict:
    """Per-joint RMSE [N m] and R^2 on each held-out recording: ours, the unconstrained fit, the prior."""
    from identification.calibration.trajectory_data import prepare_recording
    from identification.calibration.trajectory_fit import predict_torque
    from identification.metrics import r2, rmse
    from psdm_casadi.oracle import PinocchioOracle

    out = {"recordings": []}
    prior = PinocchioOracle(robot) if robot.links is not None else None
    for path, recording in zip(paths, recordings):
        kt = None if recording.tau is not None else np.array([d.kt for d in robot.drives or ()], dtype=float)
        prepared, _, _ = prepare_recording(recording, kt if kt is not None and kt.size else None, fit.cutoff_hz[0])
        x = (prepared.q, prepared.qd, prepared.qdd)
        ours, ols = predict_torque(model, fit, *x), predict_torque(model, fit, *x, ols=True)
        entry = {"recording": str(path), "rmse": _list(rmse(prepared.tau, ours)), "r2": _list(r2(prepared.tau, ours)),
                 "rmse_ols": _list(rmse(prepared.tau, ols))}  # fmt: skip
        if prior is not None:
            entry["rmse_prior"] = _list(rmse(prepared.tau, prior.rnea(*x)))
        out["recordings"].append(entry)
    return out


def _list(values) -> list:
    return [float(v) for v in np.atleast_1d(values)]


def _print(args, robot, model, fit, report, calibrated) -> None:
    if args.json:
        print_json({"command": "identify", "protocol": "recordings", "robot": robot.name, "out": str(args.out),
                    "consistent": calibrated.consistent, "checked": fit.checked,
                    "min_pseudo_inertia_eigenvalue": fit.min_pseudo_inertia_eigenvalue,
                    "min_mass_eigenvalue": report["min_mass_eigenvalue"], "condition_number": fit.condition_number,
                    "cutoff_hz": list(fit.cutoff_hz), "theta": fit.theta.tolist(), "theta_std": fit.theta_std.tolist(),
                    "drive": dict(zip(fit.drive_names, fit.drive.tolist())), "validation": report["recordings"],
                    "drive_std": dict(zip(fit.drive_names, fit.drive_std.tolist())),
                    "stribeck_velocity": list(fit.stribeck_velocity),
                    "stribeck_velocity_std": list(fit.stribeck_velocity_std),
                    "seconds": fit.seconds})  # fmt: skip
        return
    print(f"{robot.name}: {fit.n_samples} samples after filtering at {', '.join(f'{c:g}' for c in fit.cutoff_hz)} Hz "
          f"(decimation {', '.join(map(str, fit.decimation))}); condition number of the weighted regressor "
          f"{fit.condition_number:.3g}")  # fmt: skip
    state = "consistent" if calibrated.consistent else ("NOT CHECKED" if not fit.checked else "NOT CONSISTENT")
    print(f"physical consistency: {state} (smallest pseudo-inertia eigenvalue {fit.min_pseudo_inertia_eigenvalue:.3g}, "
          f"smallest mass-matrix eigenvalue {report['min_mass_eigenvalue']})")  # fmt: skip
    relative = fit.relative_sigma_percent
    print("\nparameter        estimate      sigma   sigma %")
    for k, value in enumerate(fit.theta):
        print(f"theta{k + 1:<10} {value:10.4g} {fit.theta_std[k]:10.3g} {relative[k]:8.1f}")
    for k, name in enumerate(fit.drive_names):
        print(f"{name:<15} {fit.drive[k]:10.4g} {fit.drive_std[k]:10.3g} {relative[model.n_base + k]:8.1f}")
    for j, (vs, vs_std) in enumerate(zip(fit.stribeck_velocity, fit.stribeck_velocity_std)):
        print(f"{f'vs{j + 1} [rad/s]':<15} {vs:10.4g} {vs_std:10.3g} {100 * vs_std / vs:8.1f}")
    for entry in report["recordings"]:
        print(f"\nvalidation on {entry['recording']} (RMSE [N m] per joint; R^2):")
        for key, label in (("rmse", "identified"), ("rmse_ols", "unconstrained"), ("rmse_prior", "robot file")):
            if key in entry:
                print(f"  {label:<14}" + " ".join(f"{v:9.4g}" for v in entry[key]))
        print(f"  {'R^2':<14}" + " ".join(f"{v:9.4f}" for v in entry["r2"]))
    print(f"\ncalibrated model written to {args.out}")
