"""The steps ``psdm export-urdf`` and ``psdm export-mjcf`` share: options, reading and checking MODEL, writing OUT.

Both commands read the calibrated-model file ``psdm identify`` wrote and write one text file from it; they
differ only in the renderer and in what they report. Keeping the checks here means a model the one refuses
(an output that is an input or the robot file, a physically inconsistent model) is refused by the other too,
with the same message.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from psdm_casadi.cli.checks import check_not_input, check_suffix, output_file
from psdm_casadi.cli.output import report_model_warnings
from psdm_casadi.errors import ParameterError

__all__ = [
    "ExportInput",
    "add_export_arguments",
    "check_not_robot_file",
    "read_export_input",
    "warn_stiff_links",
    "write_export",
]


@dataclass(frozen=True)
class ExportInput:
    """What an export command has read and checked: the loaded model, its output file and its eigenvalue."""

    loaded: object  # identification.calibration.calibrated_model.LoadedModel
    out: object  # psdm_casadi.fileio.OutputFile
    eigenvalue: float

    @property
    def calibrated(self):
        """The calibrated model read from MODEL."""
        return self.loaded.calibrated

    @property
    def robot(self):
        """The robot model MODEL was identified on."""
        return self.loaded.robot


def add_export_arguments(p, out_help: str, handler) -> None:
    """The positional MODEL and OUT and the options every export command takes."""
    p.add_argument("model", help="calibrated-model file (.json) written by 'psdm identify'")
    p.add_argument("out", help=out_help)
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing output file (never MODEL, nor the robot file MODEL was identified from)",
    )
    p.add_argument(
        "--allow-inconsistent",
        action="store_true",
        help="write a model that is not physically consistent (marked as such in the file)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=handler)


def check_not_robot_file(args, calibrated) -> None:
    """OUT must not replace the robot file MODEL was identified from (its text is stored in MODEL, not its path):
    an existing OUT named as one of those files, or holding the same text, is refused even with --overwrite."""

    files = (calibrated.document.get("robot") or {}).get("files") or {}
    path = Path(args.out).expanduser()
    if not path.is_file():
        return
    same_name = path.name in files
    if not same_name and path.stat().st_size > 10_000_000:
        return
    if same_name or path.read_text(errors="replace") in files.values():
        raise ParameterError(
            f"OUT {str(args.out)!r} is (or shares its name with) the robot file {args.model!r} was identified from; "
            f"--overwrite never replaces an input. Name another file, e.g. {path.stem}_identified{path.suffix}."
        )


def read_export_input(args, command: str, suffix: str, what: str) -> ExportInput | None:
    """Check OUT (suffix ``suffix``, format ``what``) and read MODEL; None (after saying why) for a model that is
    not physically consistent without ``--allow-inconsistent``, so nothing is written."""
    from psdm_casadi.cli.checks import read_calibrated_argument

    check_not_input(args.out, "OUT", [("MODEL", args.model)], example=f"{Path(args.model).stem}{suffix}")
    check_suffix(args.out, "OUT", (suffix,), what)
    out = output_file(args.out, "OUT", args.overwrite)
    loaded = read_calibrated_argument(args, args.model)
    calibrated = loaded.calibrated
    report_model_warnings(command, args.model, calibrated)
    warn_stiff_links(command, args.model, loaded)
    check_not_robot_file(args, calibrated)
    eigenvalue = calibrated.document["standard"]["min_pseudo_inertia_eigenvalue"]
    checked = calibrated.document["standard"].get("checked", True)
    if checked and not calibrated.consistent and not args.allow_inconsistent:
        print(
            f"psdm {command}: error: the calibrated model {args.model!r} is not physically consistent (smallest "
            f"pseudo-inertia eigenvalue {eigenvalue}). Nothing was written to {args.out!r}. Re-identify it, or pass "
            "--allow-inconsistent to write it marked as inconsistent.",
            file=sys.stderr,
        )
        return None
    return ExportInput(loaded, out, eigenvalue)


def warn_stiff_links(command: str, source, loaded) -> list:
    """Warn on stderr, before a command writes the model ``loaded`` (``calibrated_model.LoadedModel``) read from
    ``source``, about each link whose rotational inertia is below its plausible floor (``inertia_floor.stiff_links``:
    stiff forward dynamics); return the sentences. A warning, not a refusal: the model still predicts the torques of
    its recordings, and inverse dynamics are unaffected."""
    import numpy as np

    from identification.calibration.inertia_floor import stiff_links

    robot = loaded.robot
    values = (loaded.calibrated.document.get("standard") or {}).get("values")
    if not loaded.calibrated.consistent or values is None or robot.links is None or np.size(values) != robot.n_dof * 11:
        return []  # an inconsistent model has its own refusal (--allow-inconsistent)
    sentences = list(stiff_links(robot, np.asarray(values, dtype=float).reshape(robot.n_dof, 11)))
    for sentence in sentences:
        print(f"psdm {command}: warning: {Path(source).name}: {sentence}", file=sys.stderr)
    return sentences


def write_export(command: str, read: ExportInput, text: str, left_out) -> None:
    """Warn about an inconsistent model and about each of ``left_out`` (what the format cannot hold), then write
    ``text`` to OUT atomically, saying so when that created OUT's folder (a mistyped folder is not made silently)."""
    missing = [folder for folder in read.out.target.parents if not folder.exists()]
    if not read.calibrated.consistent:
        print(f"psdm {command}: warning: writing an INCONSISTENT model (marked in the file)", file=sys.stderr)
    for warning in left_out:
        print(f"psdm {command}: warning: {warning}", file=sys.stderr)
    with read.out.staging() as stage:
        stage.write_text(text)
    if missing:
        print(f"psdm {command}: note: created the folder {str(missing[-1])!r} for OUT", file=sys.stderr)
