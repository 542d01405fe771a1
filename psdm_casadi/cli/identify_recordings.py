"""``psdm identify`` on exciting recordings (the default route): a physically consistent calibrated-model file.

``psdm identify ROBOT --data A.csv [B.csv ...] [--validate C.csv ...] --out model.json`` filters the
recordings (the cutoff follows the sampling rate and is stated), fits base parameters, friction and
drive inertias by weighted least squares, then physically consistent standard parameters
(``identification.calibration.trajectory_fit``), checks the mass matrix on random configurations,
validates on the held-out recordings against the unconstrained fit and the robot file's prior, and
writes one calibrated-model file (``identification.calibration.calibrated_model``).
"""

from __future__ import annotations

import contextlib
import sys

import numpy as np

from psdm_casadi.cli.checks import add_topic_argument, check_not_input, load_robot_argument, recording_layout
from psdm_casadi.cli.html_report import html_output, write_identify_html
from psdm_casadi.cli.identify_inputs import check_outputs, fit_settings, read_training
from psdm_casadi.cli.identify_text import envelope_warnings, print_identify
from psdm_casadi.cli.identify_validation import json_numbers, loads_said, store_held_out, validation_report
from psdm_casadi.cli.output import EXIT_CHECK_FAILED, EXIT_OK, progress
from psdm_casadi.cli.torque_scale_step import check_torque_scales, store_torque_scales
from psdm_casadi.errors import SolverError
from psdm_casadi.said_once import SAID
from psdm_casadi.state_cache import remembering

MASS_CHECK_CONFIGURATIONS = 2000
FRICTION_SHAPES = ("auto", "coulomb-viscous", "stribeck", "lugre")  # column_choice.FRICTION_CHOICES
SWITCHES = ("auto", "on", "off")  # column_choice.SWITCH_CHOICES
COULOMB_VELOCITY_HELP = (
    "the Coulomb friction column's smoothing velocity [rad/s], fc tanh(qd / V): one for every joint, or one per joint "
    "separated by commas (0.02,0.02,0.085,...) (default: chosen from the joints' reversals, at most 0.05: slow "
    "motions reverse at a fraction of an exciting trajectory's acceleration and want a sharper sign; stated in the "
    "output and the model file)"
)

#: ``--one-way-friction`` (``identification.calibration.one_way_friction``).
ONE_WAY_HELP = (
    "the friction of joints that move one way only in the training recordings: auto (default) holds it to the robot "
    "file's rigid body's friction fit where the data do not determine it (a standard deviation above its value) and "
    "the --validate recordings, if any, find the fitted one worse than the robot file; hold: on every such joint; "
    "fit: from the data everywhere"
)
#: ``--worse-joint`` (``identification.calibration.worse_joint_hold``).
WORSE_JOINT_HELP = (
    "a joint the --validate recordings find worse than the robot file: hold (default) fits again with its friction, "
    "then the links it carries, held at the robot file's, each kept where it leaves fewer joints worse and none new "
    "(stated in the output and the model file); report: name it only"
)

#: ``--friction-drift`` (``identification.calibration.drift_choice``).
FRICTION_DRIFT_HELP = (
    "friction that changed between the --data recordings (a joint warming up, wear between days): auto (default) "
    "fits each recording's friction beside one rigid body, names the joints whose friction differs beyond noise and "
    "estimation uncertainty, keeps the friction the data choose (along the logged temperature, else the recording "
    "closest to --validate, else the latest) and fits the rigid body beside each recording's own friction; report: "
    "name it only; off: no check"
)


def add_arguments(p) -> None:
    """The options of the recordings route (the folder route shares ``--data``, ``--out`` and the rest)."""
    p.add_argument("--validate", nargs="+", default=(), help="held-out recordings for the validation report")
    p.add_argument(
        "--offset",
        nargs="?",
        const="on",
        default="auto",
        choices=SWITCHES,
        help="a constant torque offset per joint: auto (default) identifies it on the joints whose data want it "
        "(information criterion on the training data, checked on --validate or a block cross-validation; stated in "
        "the output and the model file); on (or plain --offset): on every joint; off: on none",
    )
    p.add_argument(
        "--friction",
        choices=FRICTION_SHAPES,
        default="auto",
        help="friction shape: auto (default) chooses coulomb-viscous or stribeck from the data as --offset does, "
        "and LuGre where the --validate residual lags the velocity at its reversals and the LuGre model predicts it "
        "better, worse on no joint (stated); coulomb-viscous: fc tanh(qd/eps) + fv qd; stribeck: (fc + (fs - fc) "
        "exp(-(qd/vs)^2)) tanh(qd/eps) + fv qd, with fs and vs fitted (a --cutoff well above the motion's "
        "frequencies keeps the sharp low-velocity friction the filter would smear); lugre: the Stribeck fit, then "
        "all seven LuGre parameters per joint (fc, fs, vs, fv with dv = 1, bristle stiffness sigma0 and damping "
        "sigma1) by multiple shooting along the recorded series (the friction left after the rigid body and drive "
        "terms); sigma0 is reported as not identifiable where the motion never dwells at low speed. Predict, "
        "validate, simulate and the exported C carry the bristle state along the series",
    )
    p.add_argument(
        "--drive-inertia",
        choices=SWITCHES,
        default="auto",
        help="drive (rotor) inertia columns: auto (default) keeps a joint's where the data want it, and drops it where "
        "they want it negative (torques measured behind the gearbox, as by link-side torque sensors, hold no rotor "
        "inertia); on: every joint's; off: none",
    )
    p.add_argument(
        "--no-drive-inertia", dest="drive_inertia", action="store_const", const="off", help="--drive-inertia off"
    )
    p.add_argument(
        "--drive-loss",
        choices=SWITCHES,
        default="auto",
        help="a gear efficiency that depends on the power flow (motor currents: the current torque is the link's / eta "
        "when the motor drives, x eta when back-driven): auto (default) keeps it on the joints whose data want it, "
        "tried only when currents are the torque source; on: every joint; off: none. Stored in the model file as a "
        "load-dependent friction of the model's own torque (predict, validate and the exported C apply it)",
    )
    p.add_argument("--no-consistency", action="store_true", help="keep the unconstrained weighted least-squares "
                   "estimate (base parameters only), marked as not checked")  # fmt: skip
    p.add_argument("--cutoff", type=float, default=None, help="low-pass cutoff [Hz] (default: min(10, rate/10))")
    p.add_argument("--coulomb-velocity", default=None, metavar="V", help=COULOMB_VELOCITY_HELP)
    for option, bounded in (
        ("--mass-bounds", "each link's mass stays within LOW-HIGH x the robot file's"),
        ("--drive-inertia-bounds", "each drive inertia stays within LOW-HIGH x the robot file's where it gives one"),
    ):
        p.add_argument(
            option, nargs=2, type=float, default=(0.5, 2.0), metavar=("LOW", "HIGH"), help=f"{bounded} (default 0.5 2)"
        )
    p.add_argument("--prior-uncertainty", type=float, default=None, metavar="U",
                   help="the robot file's inertial parameters are known to U times their size (default 2): the pull "
                   "towards the file that settles what the recordings hardly fix, weighed against their independent "
                   "samples")  # fmt: skip
    for option, what in (("--no-envelope", "do not keep the links inside their physical envelope (bounding "
                          "ellipsoid, mass and drive-inertia bounds): consistent only, as before"),
                         ("--no-counterbalance", "do not try the spring the report names (a link pushed against its "
                          "envelope, or a gravity term held back; kept only if it lowers its joint's error on each "
                          "--validate recording and, with at most one, in each training block)")):  # fmt: skip
        p.add_argument(option, action="store_true", help=what)
    p.add_argument("--one-way-friction", choices=("auto", "hold", "fit"), default="auto", help=ONE_WAY_HELP)
    p.add_argument("--worse-joint", choices=("hold", "report"), default="hold", help=WORSE_JOINT_HELP)
    p.add_argument("--friction-drift", choices=("auto", "report", "off"), default="auto", help=FRICTION_DRIFT_HELP)
    p.add_argument(
        "--missing-torque",
        action="append",
        default=[],
        metavar="FILE:JOINTS",
        help="a recording's joints whose torque column is not a measurement (e.g. RunTrajectory1.csv:1, or "
        "FILE:1,3 or FILE:joint_1; repeatable): their rows of that recording are left out of the fit and the "
        "validation, the other joints' rows count. A column that is zero, constant or NaN throughout is found "
        "without it and named in the output",
    )
    add_topic_argument(p)


@remembering()  # the recordings' regressors evaluated once (state_cache)
def run(args) -> int:
    from identification.calibration.held_out_arm import held_out_arm, held_out_configurations
    from identification.data.io import not_held_out
    from psdm_casadi.cli.checks import derive_model
    from psdm_casadi.model import load_model

    out, html = check_outputs(args), html_output(args)  # report.html: refused before any work like --out
    robot = load_robot_argument(args)
    check_not_input(args.out, "--out", [("robot's URDF", robot.urdf_path)])
    read = read_training(args, robot, recording_layout(args))  # --columns, --rate
    paths, configurations, recordings, validation = read.paths, read.configurations, read.recordings, read.validation
    request, options = fit_settings(args, robot.n_dof)
    if args.model:
        model = load_model(args.model)
    else:
        progress(f"identify: deriving the PSDM model of {robot.name} ...", quiet=args.json)
        model = derive_model(args, robot)
    robot = (scale := check_torque_scales(args, robot, model, (recordings, validation), configurations, paths)).robot
    held_loads = held_out_configurations(args.validate, paths, configurations)  # what each held-out one states
    arm = held_out_arm(robot, model, recordings, validation, configurations, held_loads, options, args.validate)
    result, judged = _judged_route(args, (robot, model, recordings, options, request, configurations), validation,
                                   paths, arm)  # fmt: skip
    fit, calibrated, held_out = result.fit, result.calibrated, not_held_out([str(p) for p in paths], read.explicit)
    worse = [result.file_check.describe()] if result.file_check.worse else []  # never worse than the robot file
    report = validation_report(robot, model, result.start, validation, args.validate, calibrated, held_loads)
    loads = loads_said(report, judged, args)  # stored with the warnings; the text report prints them in its table
    said = (*scale.sentences(), *result.warnings, *read.missing, *held_out, *worse, *filter(None, loads))
    warnings = [_concrete_route(w, args, paths) for w in dict.fromkeys(said)]
    _print_warnings(args, warnings, loads, fit, paths)
    mass_eigenvalue = _min_mass_eigenvalue(robot, fit) if fit.checked else None
    report["min_mass_eigenvalue"] = mass_eigenvalue
    store_held_out(args, report, calibrated, len(read.explicit))  # which part of each recording was held out
    for entry, comparison in zip(report["recordings"], result.file_check.each):  # the model identify replaces
        entry["rmse_robot_file_baseline"] = json_numbers(comparison.before)  # per joint: file+friction or file
    _complete_document(args, paths, calibrated.document, (report, warnings, scale))
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
    print_identify(args, robot, model, fit, report, calibrated, result, lambda text: _concrete_route(text, args, paths),
                   loads)  # fmt: skip
    if html is not None:  # the held-out recordings' prediction, else the training recordings'
        files = (str(args.out), _diagnose_model_command(args, paths))  # the next step's commands with this run's files
        page = write_identify_html(html, robot, model, calibrated, validation or recordings, args.validate or paths,
                                   files)  # fmt: skip
        progress(f"identify: HTML report written to {page}", quiet=args.json)
    return EXIT_OK


def _print_warnings(args, warnings, loads, fit, paths) -> None:
    """Each warning on stderr once: none its robot's loading printed already (``said_once``), and, where the text
    report follows, none it says in its place (a load in the validation table, a link pushed against its envelope in
    the envelope section: ``identify_text.envelope_warnings``). With ``--json`` the text report is not printed."""
    said = set() if args.json else {*loads, *(_concrete_route(w, args, paths) for w in envelope_warnings(fit))}
    for warning in (w for w in warnings if w not in SAID and w not in said):
        print(f"psdm identify: warning: {warning}", file=sys.stderr)


def _judged_route(args, problem, validation, paths, arm) -> tuple:
    """(``IdentifyResult``, the ``held_out_arm.HeldOutArm`` its judges weighed): the route on the held-out recordings
    with every load taken off (``arm``); where a load nothing states was, the route once more with it taken off as the
    model identified weighs it (``HeldOutArm.rejudged``: the training fit's estimate is the rougher)."""
    from identification.calibration.identify_route import identify_recordings

    robot, model, recordings, options, request, configurations = problem
    while arm is not None:
        with _lugre_messages(args, robot):  # the route's choices, fit and counterbalance (identification.calibration)
            result = identify_recordings(robot, model, recordings, options, request, list(arm.recordings),
                                         configurations, counterbalance=not args.no_counterbalance,
                                         robot_source=args.robot, paths=paths, one_way=args.one_way_friction,
                                         worse_joint=args.worse_joint, friction_drift=args.friction_drift,
                                         temperatures=_temperatures(recordings, validation),
                                         held_configurations=arm.configurations)  # fmt: skip
        judged, arm = arm, arm.rejudged(robot, model, result.calibrated, validation, options)
    return result, judged


def _temperatures(recordings, validation) -> tuple:
    """The joints' mean temperatures [°C] each training and held-out recording logs (``data.temperature``, read with
    the recording; None for one that logs none)."""
    from identification.data.temperature import logged_temperatures

    return tuple([logged_temperatures(r) for r in group] for group in (recordings, validation))


def _complete_document(args, paths, document: dict, parts) -> None:
    """The model file's validation report, warnings, torque scales (and the corrected robot text), the suggested
    counterbalance route with this run's files and the ``--columns`` it read them with."""
    from psdm_casadi.cli.checks import stored_layout

    document["validation"], document["warnings"], scale = parts
    store_torque_scales(document, scale)
    counterbalance = document["identification"]["counterbalance"]  # its suggested route, with these files
    counterbalance["reason"] = _concrete_route(counterbalance["reason"], args, paths)
    document["provenance"].update({"columns": stored_layout(args)} if stored_layout(args) else {})


def _concrete_route(warning: str, args, paths) -> str:
    """A warning's suggested ``psdm diagnose`` command with this run's robot and recordings (and how they are
    read: ``--columns``, ``--rate``) in it: the first training recording (diagnose takes one) and every held-out one
    (``--holdout``: the same cut of the training recording)."""
    from identification.calibration.envelope_report import DIAGNOSE_COMMAND

    parts = getattr(args, "held_out", None) or ()
    given = args.validate[: len(args.validate) - len(parts)]  # the --validate recordings, without the held-out parts
    validate = f" --validate {' '.join(map(str, given))}" if given else "" if parts else " --validate OTHER.csv"
    holdout = f" --holdout {parts[0].fraction:g}" if parts else ""
    layout = "".join(f" --{key} {getattr(args, key)}" for key in ("columns", "rate") if getattr(args, key, None))
    command = f"psdm diagnose {args.robot} --train {paths[0]}{holdout}{validate}{layout}"
    return warning.replace(DIAGNOSE_COMMAND, command)


def _diagnose_model_command(args, paths) -> str:
    """``psdm diagnose`` of the model file written (``--out``) with this run's recordings, as identify prints it below
    a joint predicted worse than by its mean torque."""
    from identification.calibration.envelope_report import DIAGNOSE_COMMAND

    return _concrete_route(DIAGNOSE_COMMAND, args, paths).replace(str(args.robot), str(args.out), 1)


@contextlib.contextmanager
def _lugre_messages(args, robot):
    """With ``--friction lugre``: the LuGre fit's warnings printed, and a joint's LuGre fit that fails reported in the
    command line's words (``_lugre_failure``)."""
    import warnings

    from identification.calibration.lugre_recordings import LuGreWarning

    if args.friction != "lugre":
        yield
        return
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LuGreWarning)
        try:
            yield
        except SolverError as exc:
            if exc.joint is None:  # not one joint's LuGre fit (the linear fits): its own message
                raise
            raise SolverError(_lugre_failure(robot, args.cutoff, exc), exc.status, exc.iterations, exc.joint) from None
    for warning in caught:
        print(f"psdm identify: warning: {warning.message}", file=sys.stderr)


def _lugre_failure(robot, cutoff_hz, exc) -> str:
    """The LuGre fit's failure in the command line's words: the joint, Ipopt's status, the options that help."""
    joint = f"joint {exc.joint + 1} ({robot.joint_names[exc.joint]})"
    cutoff = "the default cutoff" if cutoff_hz is None else f"--cutoff {cutoff_hz:g}"
    higher = 40 if cutoff_hz is None else max(40, 2 * cutoff_hz)
    return (
        f"--friction lugre: the LuGre friction fit of {joint} did not converge (Ipopt status {exc.status} after "
        f"{exc.iterations} iterations); nothing was written. The low-pass filter at {cutoff} may smear the "
        f"low-velocity friction the bristle model is fitted to: pass a higher --cutoff (e.g. --cutoff {higher:g}), "
        "or --friction stribeck for the steady-state friction without the bristle state."
    )


def _min_mass_eigenvalue(robot, fit, seed: int = 0) -> float:
    """Smallest eigenvalue of the identified mass matrix over random configurations within the joint limits."""
    from psdm_casadi.oracle import PinocchioOracle

    oracle = PinocchioOracle(robot, fit.standard)
    q = np.random.default_rng(seed).uniform(robot.q_min, robot.q_max, size=(MASS_CHECK_CONFIGURATIONS, robot.n_dof))
    return float(min(np.linalg.eigvalsh(m)[0] for m in oracle.crba(q)))
