"""The torque-scale step of identify and diagnose: a joint whose torque constant the known payload finds off is read
with the payload's value.

Before any fit, recordings with and without a known payload give each joint's torque scale
(``identification.calibration.torque_scale``). A joint whose scale is off (a datasheet ``motor_kt`` 15 % high) is
a finding of its own, stated with the robot file's field and the value the payload gives, and identify takes it:
the currents are read through the corrected constant, and the model file's copy of the robot file holds it, so
``validate`` and ``diagnose`` on the model read them the same way. Where the robot file states the constants in a way
that copy cannot be corrected in (no single ``motor_kt = [...]`` line), identify says what to change and fits with
the file's constants as given.

``diagnose`` of a robot file does the same over its training and validation recordings together (its sidecars say
which carry a known payload) and names the corrected constants in its nominal model (:func:`diagnose_torque_scales`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from psdm_casadi.cli.output import progress

__all__ = ["ScaleStep", "check_torque_scales", "diagnose_torque_scales", "store_torque_scales", "torque_scale_lines"]


@dataclass
class ScaleStep:
    """The torque scales found (None without a known payload beside an unloaded recording), the robot identify
    reads the currents with, and the corrected robot-file text the model file stores (None: not taken)."""

    scales: object = None
    robot: object = None
    text: str | None = None
    unchecked: str = ""  # motor currents whose constants the recordings cannot check: why, and what would

    def sentences(self) -> list:
        """identify's warnings: each finding identify could not take (the robot file's constants kept)."""
        if self.scales is None or self.text is not None:
            return []
        return [f"{finding}: identify kept the robot file's value (its torque constants are not one motor_kt line it "
                "can correct in the model file's copy); correct the robot file and identify again"
                for finding in self.scales.findings()]  # fmt: skip


def check_torque_scales(args, robot, model, recordings, configurations, paths) -> ScaleStep:
    """The :class:`ScaleStep` of the training recordings (their ``--cutoff``); where they alone do not check the
    constants, of the training and validation recordings together (``recordings``: both lists; the validation
    recordings' sidecars, ``args.validate``, say which carry a known payload): one scale per joint, a sensor's
    calibration, not a model the validation judges."""
    from identification.calibration.torque_scale import corrected_robot_text, torque_scales
    from identification.calibration.trajectory_fit import TrajectoryOptions, torque_constants
    from identification.data.configuration import stated_configuration

    recordings, validation = recordings
    kt = torque_constants(robot, TrajectoryOptions(), recordings)
    names = [Path(p).name for p in paths]
    scales = torque_scales(robot, model, recordings, configurations, kt, args.cutoff, names)
    if scales is None and validation and kt is not None:
        configurations = [*configurations, *map(stated_configuration, args.validate)]
        names += [Path(p).name for p in args.validate]
        scales = torque_scales(robot, model, [*recordings, *validation], configurations, kt, args.cutoff, names)
    if scales is None:
        return ScaleStep(robot=robot, unchecked="" if kt is None else _unchecked(configurations))
    if not scales.off.any() or scales.corrected_motor_kt() is None:
        return ScaleStep(scales, robot)
    text = corrected_robot_text(Path(args.robot).read_text(), scales.corrected_motor_kt())
    if text is None:
        return ScaleStep(scales, robot)
    for finding in scales.findings():
        progress(f"identify: {finding}: reading the currents with the payload's value", quiet=args.json)
    return ScaleStep(scales, scales.corrected_robot(robot), text)


def _unchecked(configurations) -> str:
    """Why recordings of currents do not check the torque constants, and what would."""
    kinds = {c.kind for c in configurations or ()}
    if kinds == {"known"}:
        return ("every recording carries the known payload: its torque is then a multiple of the arm's and the "
                "scale is not determined; add a recording without it")  # fmt: skip
    return (
        "no recording carries a known payload beside one without it (a known payload on part of the recordings, "
        "A.payload.json beside A.csv, lets identify check each joint's torque constant against its torque)"
    )


def store_torque_scales(document: dict, step: ScaleStep) -> None:
    """The model file's ``identification.torque_scale`` block, and its robot text with the corrected constants."""
    from identification.calibration.model_file_check import robot_digest

    if step.unchecked:
        document["identification"]["torque_scale"] = {"checked": False, "reason": step.unchecked}
    if step.scales is None:
        return
    document["identification"]["torque_scale"] = {
        "checked": True,
        **step.scales.to_dict(),
        "taken": step.text is not None,
    }
    if step.text is not None:
        block = document["robot"]
        block["files"][block["main_file"]] = step.text
        block["sha256"] = robot_digest(block["files"])


def torque_scale_lines(document: dict) -> list:
    """identify's report lines of the model file's ``identification.torque_scale`` block (none without it)."""
    from identification.calibration.torque_scale import compared_recordings

    block = document["identification"].get("torque_scale")
    if not block:
        return []
    if block.get("checked") is False:
        return [f"torque constants: not checked: {block['reason']}"]
    each = ", ".join(
        f"{s:.3f}" + ("" if sd is None else f" +/- {sd:.3f}") for s, sd in zip(block["scale"], block["std"])
    )
    head = (f"torque constants: each joint's torque scale from the known payload on "
            f"{compared_recordings(block['loaded'], block['unloaded'])} (1 = the robot file's constants are right): "
            f"{each}")  # fmt: skip
    lines = [head]
    done = ("identify read the currents with the payload's value (the model file's copy of the robot file holds it); "
            "correct the robot file" if block["taken"] else "identify kept the robot file's value")  # fmt: skip
    lines += [f"  {finding}: {done}" for finding in block["findings"]]
    if not block["findings"]:
        lines.append(f"  none off by more than {block['margin'] * 100:g} % and {block['sigmas']:g} standard deviations")
    unchecked = [str(j + 1) for j, known in enumerate(block["determined"]) if not known]
    if unchecked:
        lines.append(f"  joint(s) {', '.join(unchecked)}: not determined by the payload (its torque there is small or "
                     "a multiple of the arm's): not checked")  # fmt: skip
    return lines


def diagnose_torque_scales(args, robot, recordings, cutoff_hz) -> tuple:
    """(the robot reading the currents with the corrected constants, a sentence for the nominal model or "") of
    ``diagnose ROBOT --train A --validate B ...``: the recordings' sidecars say which carry a known payload."""
    from identification.calibration.torque_scale import torque_scales
    from identification.calibration.trajectory_fit import TrajectoryOptions, torque_constants
    from identification.data.configuration import stated_configuration
    from psdm_casadi.cli.checks import command_model

    paths = [args.train, *args.validate]
    configurations = [stated_configuration(path) for path in paths]
    if not any(c.kind == "known" for c in configurations):
        return robot, ""
    kt = torque_constants(robot, TrajectoryOptions(), recordings)
    names = [Path(p).name for p in paths]
    scales = torque_scales(robot, command_model(args, robot), recordings, configurations, kt, cutoff_hz, names)
    if scales is None or not scales.off.any() or scales.corrected_kt() is None:
        return robot, ""
    for finding in scales.findings():
        progress(f"diagnose: {finding}: reading the currents with the payload's value", quiet=args.json)
    said = "; ".join(scales.findings())
    return scales.corrected_robot(robot), f"; torque constants corrected by the known payload ({said})"
