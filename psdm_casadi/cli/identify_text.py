"""The report ``psdm identify`` prints on the recordings route (``identify_recordings``): text, or ``--json``."""

from __future__ import annotations

import numpy as np

from psdm_casadi.cli.output import print_json
from psdm_casadi.cli.torque_scale_step import torque_scale_lines


def _print_lugre(block) -> None:
    """The LuGre parameters per joint with their standard deviations (the steady state above is the start)."""
    if not block:
        return
    from identification.friction.models import LUGRE_PARAMETER_NAMES

    start = ("the drive values above are the other joints' steady state" if None in block["fc"] else
             "the Stribeck values above are its start")  # fmt: skip
    print(f"\nLuGre friction (fitted along the series; {start}), value +- sigma:")
    print("joint " + " ".join(f"{name:>20}" for name in LUGRE_PARAMETER_NAMES))
    for j, identifiable in enumerate(block["sigma0_identifiable"]):
        if block["fc"][j] is None:  # a mixed model's steady-state joint (its friction is in the drive table above)
            print(f"{j + 1:<5} the steady-state shape (no LuGre friction on this joint)")
            continue
        cells = [f"{block[n][j]:10.4g} +- {_sigma(block['std'][n][j]):<6}" for n in LUGRE_PARAMETER_NAMES]
        note = "" if identifiable else "  (sigma0 not identifiable)"
        print(f"{j + 1:<5} " + " ".join(f"{c:>20}" for c in cells) + note)


def _print_payloads(payloads) -> None:
    """Each unknown payload's mass and centre of mass (flange frame) with sigma, or why they are not separable."""
    if not payloads:
        return
    print("\nunknown payloads (a body fixed to the flange; the arm's parameters shared by every configuration):")
    for p in payloads:
        where = f"{p.name} ({len(p.recordings)} recording{'s' if len(p.recordings) != 1 else ''})"
        if not p.identifiable:
            print(f"  {where}: not separable from the arm's last link (every recording carries it, or the motion does "
                  "not tell them apart). Record the arm without it too.")  # fmt: skip
            continue
        com = ", ".join(f"{v:.4f}" for v in p.com)
        com_std = ", ".join(_sigma(None if not np.isfinite(v) else v) for v in p.com_std)
        print(f"  {where}: mass {p.mass:.4g} +- {_sigma(p.mass_std)} kg, centre of mass [{com}] +- [{com_std}] m")


def sigma_percent(value, std) -> np.ndarray:
    """100 sigma / |value| [%] of each printed estimate (inf for an estimate of zero), so that the table's columns
    agree: the file's ``relative_sigma_percent`` is relative to the least-squares estimate (``ols``) instead."""
    value, std = np.asarray(value, dtype=float), np.asarray(std, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(value == 0, np.inf, 100.0 * np.abs(std) / np.abs(value))


NOT_IDENTIFIABLE_PERCENT = 100.0  # sigma above the estimate's own size: the sign is not even known


def sigma_percent_cell(percent: float) -> str:
    """The table's ``sigma %`` cell: the number up to 100 %; beyond it the estimate is smaller than its standard
    deviation (a parameter near zero), where a relative figure runs to thousands of percent and says nothing, so the
    cell says "not identifiable" and the absolute sigma beside it (in the parameter's units) is the figure to read."""
    if np.isfinite(percent) and percent <= NOT_IDENTIFIABLE_PERCENT:
        return f"{percent:8.1f}"
    return f"   > {NOT_IDENTIFIABLE_PERCENT:g}  not identifiable"


#: Said once below the parameter table where a cell says "not identifiable" (on the Kinova 35 of its 57 rows carried
#: the whole sentence).
NOT_IDENTIFIABLE_NOTE = (
    f"not identifiable: sigma above the estimate (sigma % > {NOT_IDENTIFIABLE_PERCENT:g}), a parameter near zero whose "
    "sign the data do not fix; read its absolute sigma, in the parameter's units"
)


def _sigma(value) -> str:
    return "inf" if value is None else f"{value:.2g}"


def _value(value) -> str:
    return "not checked" if value is None else f"{value:.3g}"


def envelope_warnings(fit) -> tuple:
    """The warnings the envelope section says (its ``PUSHED`` lines: the links the data press against their bounds;
    none when the section is not printed, or names the torques' unit instead): printed there, not on stderr too."""
    from identification.calibration.trajectory_checks import unit_factor

    if "envelopes" not in dict(fit.envelope_bounds) or unit_factor(fit.torque_ratio) is not None:
        return ()
    return tuple(f.message for f in fit.envelope if f.pressed)


def _print_envelope(fit, route=str) -> None:
    """The physical envelope the links were kept in, and the links the data pushed against it (``route`` puts this
    run's files into a suggested ``psdm diagnose`` command, as in the warning that repeats it)."""
    from identification.calibration.trajectory_checks import unit_factor

    bounds = dict(fit.envelope_bounds)
    if "envelopes" not in bounds:  # not bounded (the ``prior`` pull alone)
        return
    sources = sorted({s for s in bounds["envelopes"] if s})
    mass, rotor = ("-".join(f"{v:g}" for v in bounds[key]) for key in ("mass_ratio", "drive_inertia_ratio"))
    print(
        f"physical envelope: each link's mass within {mass} x the robot file's, drive inertias within {rotor} x, "
        f"the mass inside a bounding ellipsoid ({', '.join(sources)})"
        + (
            f", its spread about its centre of mass at least {floor['share']:g} x the robot file's per unit mass "
            f"(links {', '.join(str(k) for k in floor['links'])})"
            if (floor := bounds.get("inertia_floor"))
            else ""
        )
    )
    for note in (floor or {}).get("at_floor", ()):
        print(f"  AT ITS INERTIA FLOOR (note): {note['message']}")
    for entry in bounds.get("drive_inertia_reference", []):
        source = (
            "the training data beside the robot file's links"
            if entry["from"] == "training data"
            else "the drive inertias of joints " + ", ".join(str(j) for j in entry["from_joints"]) + " (same actuator)"
        )
        same = entry.get("same_actuator")
        if same and same.get("taken", True):  # taken apart where the held-out data confirmed it (``rotors_apart``)
            source += (
                f", not the {same['kg_m2']:.3g} kg m^2 of joints {', '.join(str(j) for j in same['joints'])} with the "
                f"same torque constant (training BIC {same['delta_bic']:+.3g}, confirmed held out: see drive columns)"
            )
        fitted = float(np.asarray(fit.standard)[entry["joint"] - 1, -1])  # the pull is weak: it may end far off
        print(
            f"  joint {entry['joint']}'s drive inertia lies inside the base parameters and the robot file "
            f"states none: held near {entry['kg_m2']:.3g} kg m^2 from {source} (fitted: {fitted:.3g} kg m^2), not "
            "absorbed by the links"
        )
    if not any(f.pressed for f in fit.envelope):
        print("  every link inside, none pushed against its bounds" if not fit.envelope else "  none pushed hard")
    elif unit_factor(fit.torque_ratio) is not None:  # every link pushed by the unit: the warning names it
        print(f"  links {', '.join(str(f.link + 1) for f in fit.envelope)} pushed: the torques are in another unit")
        return
    for finding in fit.envelope:
        print(f"  {'PUSHED' if finding.pressed else 'AT A BOUND (note)'}: {route(finding.message)}")


def _below_mean(entry, diagnose: str, fitted=()) -> list:
    """A line per held-out joint the model predicts worse than the joint's mean torque (R^2 < 0), with what the
    robot file's rigid body alone gives there and the diagnosis that looks for the missing torque: the shared TX40's
    joint 5 (R^2 -12, 4.715 N m against the file's 1.375: the wrist coupling) was printed without a word. ``fitted``:
    the labels of the coupling terms the model already holds (``CoupledDrives.kept``, ``coupling[jm->jk]``), named on
    the joint they act on, so the line does not send the user after a torque the model fits."""
    lines = []
    for j, r2 in enumerate(entry["r2"]):
        if r2 is None or r2 >= 0.0:
            continue
        ours, file = entry["rmse"][j], (entry.get("rmse_prior") or [None] * len(entry["r2"]))[j]
        alone = f"; the robot file's rigid body alone gives {file:.4g}" if file is not None and file < ours else ""
        held = [label for label in fitted if label.endswith(f"->j{j + 1}]")]
        held = f"; the model already fits {', '.join(held)} on it" if held else ""
        lines.append(f"  joint {j + 1}: R^2 {r2:.3g}, predicted worse than by its mean torque (RMSE {ours:.4g} N m"
                     f"{alone}): a torque the model lacks acts on it (a coupling, a spring, a load{held}); "
                     f"'{diagnose} --apply NEW.json' looks for it and adds what holds held out")  # fmt: skip
    return lines


def _validation_title(entry) -> str:
    """A validation recording's name; for ``--holdout``, which part of the training recording was held out."""
    from identification.data.holdout import HeldOutPart

    if not entry.get("held_out"):
        return entry["recording"]
    part = HeldOutPart.from_dict(entry["held_out"])
    return f"{part.describe()}; its first {part.cut_sample} samples trained"


def held_label(result, name: str) -> str:
    """Why a drive column of ``result`` (``IdentifyResult``) is held, not estimated ("" where it is estimated): at the
    robot-file check's baseline (``worse_joint_hold``, which replaces a one-way hold of the same column), or at the
    robot file's fit (``one_way_friction``)."""
    if name in dict(result.worse_joints.held_friction):
        return "worse than the robot file: its baseline's"
    return "one way only: the robot file's fit" if name in dict(result.one_way.held) else ""


def print_identify(args, robot, model, fit, report, calibrated, result, route=str, loads=()) -> None:
    """The command's output: ``--json``'s summary, or the text report (preparation, consistency, envelope, columns,
    counterbalance, unstated loads, parameters, LuGre, payloads, validation); ``route`` puts this run's files in;
    ``loads`` the line on the load nothing states of each held-out recording (None: none), said in its table only."""
    from identification.calibration.drive_loss import drive_loss_summary
    from identification.calibration.envelope_report import DIAGNOSE_COMMAND
    from identification.calibration.trajectory_data import samples_text

    if args.json:
        print_json({"command": "identify", "protocol": "recordings", "robot": robot.name, "out": str(args.out),
                    "consistent": calibrated.consistent, "checked": fit.checked,
                    "min_pseudo_inertia_eigenvalue": fit.min_pseudo_inertia_eigenvalue,
                    "min_mass_eigenvalue": report["min_mass_eigenvalue"], "condition_number": fit.condition_number,
                    "cutoff_hz": list(fit.cutoff_hz), "theta": fit.theta.tolist(), "theta_std": fit.theta_std.tolist(),
                    "drive": dict(zip(fit.drive_names, fit.drive.tolist())), "validation": report["recordings"],
                    "drive_std": dict(zip(fit.drive_names, fit.drive_std.tolist())),
                    "stribeck_velocity": list(fit.stribeck_velocity),
                    "stribeck_velocity_std": list(fit.stribeck_velocity_std), "viscous_exponent": fit.viscous_exponent,
                    "lugre": calibrated.document["drive"].get("lugre"), "seconds": fit.seconds,
                    "payloads": [p.to_dict() for p in fit.payloads], "configurations": calibrated.configurations,
                    "envelope": dict(fit.envelope_bounds), "envelope_findings": [f.to_dict() for f in fit.envelope],
                    "columns": calibrated.document["identification"]["column_choice"],
                    "counterbalance": calibrated.document["identification"]["counterbalance"],
                    "drive_loss": drive_loss_summary(calibrated.document),
                    **{key: calibrated.document["identification"].get(key)
                       for key in ("robot_file_check", "one_way_friction", "worse_joints", "torque_scale",
                                   "friction_drift", "unstated_loads", "lugre_trial", "coupled_drives")},
                    "warnings": calibrated.document.get("warnings", [])})  # fmt: skip
        return
    print(f"{robot.name}: {samples_text(fit.joint_samples or (fit.n_samples,))} after filtering at "
          f"{', '.join(f'{c:g}' for c in fit.cutoff_hz)} Hz (decimation {', '.join(map(str, fit.decimation))}; "
          f"{fit.edge_periods:g} filter periods trimmed at each end, the filter's start-up transient); condition "
          "number of the weighted regressor "
          f"{fit.condition_number:.3g}")  # fmt: skip
    state = "consistent" if calibrated.consistent else ("NOT CHECKED" if not fit.checked else "NOT CONSISTENT")
    print(f"physical consistency: {state} (smallest pseudo-inertia eigenvalue {fit.min_pseudo_inertia_eigenvalue:.3g}, "
          f"smallest mass-matrix eigenvalue {_value(report['min_mass_eigenvalue'])})")  # fmt: skip
    _print_envelope(fit, route)
    if result.pull is not None:
        print(result.pull.describe())
    for item in result.held_back:
        print(f"  HELD BACK: {route(item.message)}")
    print("drive columns: " + "; ".join(result.columns), *torque_scale_lines(calibrated.document), sep="\n")
    if result.counterbalance.reason:  # as the model file states it (the suggested route with this run's files)
        print(f"counterbalance: {calibrated.document['identification']['counterbalance']['reason']}")
    lines = (result.lugre_trial.describe(), result.unstated.line, result.payload.line, result.drift.describe(),
             result.one_way.describe(), result.coupled.describe(), result.worse_joints.describe())  # fmt: skip
    print(*filter(None, lines), sep="\n", end="\n" if any(lines) else "")
    for entry in drive_loss_summary(calibrated.document):
        print(
            f"drive loss of joint {entry['joint']}: mu {entry['mu']:.4g} +- {entry['mu_std']:.2g}, gear efficiency "
            f"eta {entry['efficiency']:.3f} ({entry['efficiency_range'][0]:.3f}-{entry['efficiency_range'][1]:.3f})"
        )
    _print_parameters(fit, model, result)
    _print_shapes(fit, calibrated)
    _print_lugre(calibrated.document["drive"].get("lugre"))
    _print_payloads(fit.payloads)
    for entry, load in zip(report["recordings"], tuple(loads) or (None,) * len(report["recordings"])):
        _print_validation(
            entry, route(DIAGNOSE_COMMAND).replace(str(args.robot), str(args.out), 1), load, result.coupled.kept
        )
    if (result.file_check.comparison is not None or result.file_check.reason) and not result.file_check.worse:
        # worse: a warning (stderr)
        print(f"\n{result.file_check.describe()}")
    print(f"\ncalibrated model written to {args.out}")


def _print_parameters(fit, model, result) -> None:
    """The parameter table: each estimate with its sigma and sigma % (held columns said held, columns held at 0 left
    out), and once below it what "not identifiable" means where a row says it."""
    relative = sigma_percent(np.concatenate([fit.theta, fit.drive]), np.concatenate([fit.theta_std, fit.drive_std]))
    print("\nparameter        estimate      sigma   sigma % (of the estimate printed)")
    cells = []
    for k, value in enumerate(fit.theta):
        cells.append(sigma_percent_cell(relative[k]))
        print(f"theta{k + 1:<10} {value:10.4g} {fit.theta_std[k]:10.3g} {cells[-1]}")
    for k, name in enumerate(fit.drive_names):
        zero = name.startswith(("offset", "fs")) or (name.startswith(("fc", "fv")) and fit.drive[k] == 0)
        if zero and fit.drive_std[k] == 0:  # a LuGre joint's friction columns too (the LuGre table below)
            continue  # held at 0: no offset or static friction on that joint (the drive columns above say so)
        if label := held_label(result, name):  # not estimated
            print(f"{name:<15} {fit.drive[k]:10.4g}       held ({label})")
            continue
        cells.append(sigma_percent_cell(relative[model.n_base + k]))
        print(f"{name:<15} {fit.drive[k]:10.4g} {fit.drive_std[k]:10.3g} {cells[-1]}")
    if any("not identifiable" in cell for cell in cells):
        print(f"({NOT_IDENTIFIABLE_NOTE})")


def _print_validation(entry, diagnose: str, load=None, fitted=()) -> None:
    """One held-out recording's table (identified, unconstrained, robot file, its baseline; R^2), the line on the load
    nothing states that it carries (``load``: ``held_out_load``, what the judges took off) and the joints predicted
    worse than by their mean torque (``fitted``: the coupling terms the model holds, ``_below_mean``)."""
    print(f"\nvalidation on {_validation_title(entry)} (RMSE [N m] per joint; R^2):")
    print(f"  {'joint':<14}" + " ".join(f"{j + 1:>9}" for j in range(len(entry["r2"]))))
    for key, label in (
        ("rmse", "identified"),
        ("rmse_ols", "unconstrained"),
        ("rmse_prior", "robot file"),
        ("rmse_robot_file_baseline", "file baseline"),
    ):
        if key in entry:
            print(f"  {label:<14}" + " ".join("        -" if v is None else f"{v:9.4g}" for v in entry[key]))
    print(f"  {'R^2':<14}" + " ".join("        -" if v is None else f"{v:9.4f}" for v in entry["r2"]))
    if load:  # a load nothing states, taken off or not (``held_out_load``): said here, not among the warnings
        print(f"  payload: {load}")
    for line in _below_mean(entry, diagnose, fitted):
        print(line)


def _print_shapes(fit, calibrated) -> None:
    """The Stribeck velocity and the viscous power law's exponent of each joint that has one (``column_choice``), with
    their standard deviations."""
    for j, (vs, vs_std) in enumerate(zip(fit.stribeck_velocity, fit.stribeck_velocity_std)):
        if vs == 0:
            continue  # a Coulomb-viscous joint: no Stribeck velocity
        print(f"{f'vs{j + 1} [rad/s]':<15} {vs:10.4g} {vs_std:10.3g} {100 * vs_std / vs:8.1f}")
    spread = {e["joint"]: e["std"] for e in calibrated.document["identification"]["column_choice"].get("evidence", [])
              if e["term"] == "viscous"}  # fmt: skip
    for j, dv in enumerate(fit.viscous_exponent):
        if dv != 1.0:
            std = spread.get(j + 1, 0.0)
            print(f"{f'dv{j + 1} [-]':<15} {dv:10.4g} {std:10.3g} {100 * std / dv:8.1f}")
