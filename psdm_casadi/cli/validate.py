"""The ``psdm validate`` subcommand: a calibrated model against recordings, per-joint RMSE and R^2, plots."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from psdm_casadi.cli.checks import (
    add_topic_argument,
    check_not_input,
    model_layout,
    output_file,
    output_folder,
)
from psdm_casadi.cli.output import EXIT_OK, print_json, report_model_warnings


def register(subparsers) -> None:
    """Add ``validate`` to the ``psdm`` parser."""
    p = subparsers.add_parser(
        "validate",
        help="compare a calibrated model with recordings: per-joint RMSE and R^2, and plots",
        description=(
            "Read a calibrated-model file written by 'psdm identify', prepare each recording as the identification "
            "did (the same low-pass cutoff, central differences), and report per joint the RMSE [N m] and R^2 of "
            "the model's torque against the recorded one. The model's torque includes its torque-type findings "
            "(psdm diagnose MODEL --apply); its measurement corrections (a torque delay, an encoder before a "
            "compliant joint or a play) are applied to the recordings first, as the recalibration did. A model with "
            "LuGre friction (identify --friction lugre) carries its bristle state along each recording: relaxed at "
            "the recording's start, carried over the samples the filter trims. The warnings 'psdm identify' stored "
            "in the model file (a friction held at zero, masses far from the robot file's, a joint its own training "
            "data did not explain) are repeated on stderr (and under 'warnings' with --json). A recording in the "
            "wrong units, or in which a joint barely moves, is refused (exit 2)."
        ),
    )
    p.add_argument("model", help="calibrated-model file (.json) written by 'psdm identify'")
    p.add_argument(
        "recordings",
        nargs="*",
        help="recordings (.csv, .npz, .mat, or ROS 2 bags) with joint torques. A model identified with --holdout "
        "validates on the part of its training recording it held out: with no recordings given, on every such part; "
        "a training recording given again (recognised by its content) stands for its held-out part",
    )
    add_topic_argument(p)
    p.add_argument(
        "--plots",
        type=Path,
        default=None,
        help="folder for one plot per recording (RECORDING.png): new or empty, or with --overwrite one an earlier "
        "'psdm validate' wrote (only the plots listed in its .psdm-manifest.json are replaced)",
    )
    p.add_argument(
        "--predictions",
        type=Path,
        default=None,
        metavar="FILE",
        help="write the prepared samples (recording, t, q, qd, qdd, the measured tau) and the model's torques "
        "(tau_model) of every recording to this CSV file",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the plots an earlier run wrote in --plots, and an existing --predictions file",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=_run_validate)


def _run_validate(args) -> int:
    from identification.calibration.dropped_findings import dropped_notes
    from identification.calibration.payload_fit import stated_payload
    from identification.calibration.refit_training import listed_configuration
    from identification.calibration.trajectory_checks import check_validation_recording
    from identification.data.missing_torque import find_missing_torque, missing_torque_messages
    from identification.data.robot_recordings import load_robot_recording, recording_paths
    from psdm_casadi.cli.checks import read_calibrated_argument
    from psdm_casadi.cli.holdout import validate_parts

    plots = None
    if args.plots is not None:  # refused before any work
        names = [f"{Path(p).stem}.png" for p in args.recordings]
        plots = output_folder(args.plots, names, args.overwrite, command="validate", label="--plots")
        inputs = [("MODEL", args.model), *(("RECORDINGS", path) for path in args.recordings)]
        check_not_input(args.plots, "--plots", inputs)
    predictions = _predictions_output(args)
    loaded = read_calibrated_argument(args, args.model)  # checked; its robot and model derived once
    calibrated, robot, model = loaded.calibrated, loaded.robot, loaded.model
    preparation = _preparation_noted(args.model, calibrated.document)
    layout = model_layout(args, calibrated.document, "validate")  # --columns, --rate (or identify's)
    grouped = recording_paths(args.recordings, robot)  # a recording split per signal: its folder
    if plots is not None and grouped != list(args.recordings):  # one plot per recording, named after the folder
        names = [f"{Path(p).stem}.png" for p in grouped]
        plots = output_folder(args.plots, names, args.overwrite, command="validate", label="--plots")
    parts = validate_parts(
        calibrated.document, grouped, lambda path: load_robot_recording(path, robot, args.topic, layout), args.model
    )
    args.recordings = [path for path, _, _ in parts]
    warnings = report_model_warnings("validate", args.model, calibrated, args.recordings)  # each load: its own line
    if plots is not None and not grouped:  # the held-out parts the model stores: one plot each
        names = [f"{Path(p).stem}.png" for p in args.recordings]
        plots = output_folder(args.plots, names, args.overwrite, command="validate", label="--plots")
    recordings = [recording for _, recording, _ in parts]
    recordings = [find_missing_torque(r) for r in recordings]  # a dead torque channel: that joint left out, named
    for message in missing_torque_messages(recordings, robot.joint_names, "validation"):
        warnings.append(message)
        print(f"psdm validate: warning: {message}", file=sys.stderr)
    for recording in recordings:  # in the robot's units, every joint moving (else its R^2 says nothing)
        check_validation_recording(robot, recording)
    rows = []
    for (path, _, part), recording in zip(parts, recordings):
        listed = listed_configuration(calibrated.document, path)  # its sidecar, else the model's list for it
        stated, note = stated_payload(listed, calibrated.configurations, args.model)
        if note is not None:
            warnings.append(note)
            print(f"psdm validate: warning: {path}: {note}", file=sys.stderr)
        error, r2, prepared, predicted, load, left_in = _judged(robot, calibrated, model, recording, stated, path)
        rows.append({"recording": str(path), "rmse": _numbers(error), "r2": _numbers(r2), "held_out": part,
                     "prepared": prepared, "predicted": predicted, "payload": load, "rmse_load_left_in": left_in,
                     "stated_payload_kg": None if stated is None else float(stated[0]),
                     "temperature": _temperature(calibrated, robot, recording, prepared)})  # fmt: skip
    if predictions is not None:
        with predictions.staging() as stage:
            stage.write_text(predictions_csv(rows, robot.n_dof))
    if plots is not None:
        with plots.staging() as stage:
            for row in rows:
                _plot(stage / f"{Path(row['recording']).stem}.png", row, robot.joint_names)
    if args.json:
        print_json({"command": "validate", "model": str(args.model), "consistent": calibrated.consistent,
                    "warnings": warnings, "preparation": preparation.to_dict(),
                    "not_written": dropped_notes(calibrated.document),
                    "recordings": [_json_row(row) for row in rows]})  # fmt: skip
    else:
        for row in rows:
            title = row["recording"] if row["held_out"] is None else row["held_out"].describe()
            print(validation_table(title, robot.joint_names, row["rmse"], row["r2"]))
            for line in filter(None, (row["payload"] and f"payload: {_payload_sentence(row)}", row["temperature"])):
                print(f"  {line}")  # the load the model does not have, the temperatures its friction was read at
        if predictions is not None:
            print(f"prepared samples and the model's torques written to {predictions.target}")
        if not calibrated.consistent:
            print("warning: this model is NOT physically consistent (written with --allow-inconsistent)")
    return EXIT_OK


def _judged(robot, calibrated, model, recording, stated, path) -> tuple:
    """(RMSE, R^2, prepared recording, prediction, load, RMSE with the load left in or None) of the model on a raw
    recording (``held_out_load.judge_recording``): with a stated load (``stated``: its 10 parameters) that load added
    to the prediction and a load beyond it named (``payload_check.new_payload``); with none, a load nothing states
    found, and taken off if plausible (``held_out_load``, as identify and diagnose judge it)."""
    from identification.calibration.held_out_load import judge_recording
    from identification.calibration.payload_check import model_columns, new_payload
    from identification.data.torque_constants import recording_kt

    check = judge_recording(robot, calibrated, model, recording, recording_kt(robot, recording), stated, str(path))
    if stated is None:
        left_in = _numbers(check.rmse_left_in) if check.taken_off else None
        return check.rmse, check.r2, check.prepared, check.predicted, check.load, left_in
    own = model_columns(calibrated, model, check.prepared)  # the model's own error, allowed for in the load's
    load = new_payload(robot, check.prepared, check.predicted, name=str(path), own=own)
    return check.rmse, check.r2, check.prepared, check.predicted, load, None


def _preparation_noted(model, document):
    """The model file's own preparation (as every judging command's), its note and one note per finding the diagnosis
    that wrote the file left out (``dropped_findings``: why, and the diagnosis's hint) printed on stderr."""
    from identification.calibration.dropped_findings import dropped_notes
    from identification.calibration.model_preparation import model_preparation

    preparation = model_preparation(document)
    for note in filter(None, (preparation.note, *dropped_notes(document))):
        print(f"psdm validate: note: {model}: {note}", file=sys.stderr)
    return preparation


def _numbers(values) -> list:
    """Per joint, the value, or None for a joint whose torque the recording does not measure (NaN)."""
    return [float(v) if np.isfinite(v) else None for v in np.atleast_1d(values)]


def _shown(value, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def _json_row(row) -> dict:
    """A recording's entry of the JSON output: RMSE, R^2, and the payload it appears to carry (or null); a load nothing
    states (``held_out_load.UnstatedLoad``) with whether it was taken off, and then the RMSE with it left in."""
    from identification.calibration.held_out_load import UnstatedLoad

    load = row["payload"]
    held = row.get("held_out")
    if isinstance(load, UnstatedLoad):
        load = {**load.to_dict(), "sentence": _payload_sentence(row)}
    elif load is not None:
        load = load.to_dict()
    return {"recording": row["recording"], "rmse": row["rmse"], "r2": row["r2"],
            "held_out": None if held is None else held.to_dict(),
            "stated_payload_kg": row["stated_payload_kg"], "friction_temperature": row["temperature"] or None,
            "payload": load,
            "rmse_load_left_in": row["rmse_load_left_in"]}  # fmt: skip


def _payload_sentence(row) -> str:
    """The line naming a recording's load: one nothing states as ``held_out_load`` says it (what was done, the
    sidecar), else one beyond the stated load (``payload_check.NewPayload``)."""
    from identification.calibration.held_out_load import UnstatedLoad

    load = row["payload"]
    if isinstance(load, UnstatedLoad):
        return load.sentence(row["rmse_load_left_in"])
    return load.sentence()


def _temperature(calibrated, robot, recording, prepared) -> str:
    """The temperatures a model file's friction law was evaluated at on a recording (its logged ones, else the
    reference: ``temperature_friction``); empty for a model without one."""
    from identification.data.temperature import temperatures_at

    laws = calibrated.temperature_friction
    return "" if laws is None else laws.sentence(temperatures_at(recording, prepared.t), robot.joint_names)


def validation_table(recording: str, joint_names, rmse, r2) -> str:
    """One recording's per-joint RMSE and R^2, a joint a row, its name whole (URDF names are long)."""
    width = max(5, *(len(name) for name in joint_names))
    lines = [f"{recording}:", f"  {'joint':<{width}}  {'RMSE [N m]':>10}  {'R^2':>8}"]
    lines += [f"  {name:<{width}}  {_shown(e, '10.4g'):>10}  {_shown(r, '8.4f'):>8}"
              for name, e, r in zip(joint_names, rmse, r2)]  # fmt: skip
    return "\n".join(lines)


def _predictions_output(args):
    """The checked ``--predictions`` file (None when not asked), refused before any work."""
    from psdm_casadi.cli.checks import check_suffix

    if args.predictions is None:
        return None
    check_suffix(args.predictions, "--predictions", (".csv",), "a CSV file")
    inputs = [("MODEL", args.model), *(("RECORDINGS", path) for path in args.recordings)]
    check_not_input(args.predictions, "--predictions", inputs)
    return output_file(args.predictions, "--predictions", args.overwrite)


def predictions_csv(rows, n_dof: int) -> str:
    """The CSV text of ``--predictions``: per prepared sample its recording (1-based, named in the header
    comments), t, q, qd, qdd, the measured tau and the model's tau_model, every number to full precision."""
    header = ["recording", "t"] + [
        f"{s}{j}" for s in ("q", "qd", "qdd", "tau", "tau_model") for j in range(1, n_dof + 1)
    ]
    lines = [f"# recording {k}: {row['recording']}" for k, row in enumerate(rows, start=1)]
    lines.append(",".join(header))
    for k, row in enumerate(rows, start=1):
        prepared = row["prepared"]
        block = np.column_stack([np.full(prepared.t.shape, k), prepared.t, prepared.q, prepared.qd, prepared.qdd,
                                 prepared.tau, row["predicted"]])  # fmt: skip
        lines += [f"{k}," + ",".join(repr(float(x)) for x in sample[1:]) for sample in block]
    return "\n".join(lines) + "\n"


def _plot(path, row, joint_names) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    prepared, predicted = row["prepared"], row["predicted"]
    n = prepared.n_dof
    fig, axes = plt.subplots(n, 1, figsize=(9, 1.8 * n), sharex=True, squeeze=False)
    for j, ax in enumerate(axes[:, 0]):
        ax.plot(prepared.t, prepared.tau[:, j], lw=0.8, label="recorded")
        ax.plot(prepared.t, predicted[:, j], lw=0.8, label="model")
        ax.set_ylabel(f"{joint_names[j]} [N m]", fontsize=7)
        ax.set_title(
            f"RMSE {_shown(row['rmse'][j], '.3g')}, R^2 {_shown(row['r2'][j], '.3f')}", fontsize=7, loc="right"
        )
    axes[0, 0].legend(fontsize=7)
    axes[-1, 0].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
