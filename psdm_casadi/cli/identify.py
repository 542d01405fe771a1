"""The ``psdm identify`` subcommand: run the calibration pipeline on a data directory and save the model."""

from __future__ import annotations

from pathlib import Path

from psdm_casadi.cli.output import print_json, progress

__all__ = ["register"]


def register(subparsers) -> None:
    """Add ``identify`` to the ``psdm`` parser."""
    p = subparsers.add_parser(
        "identify",
        help="identify Kt, gravity, LuGre friction and inertial parameters from calibration recordings",
        description=(
            "Run the paper's four calibration steps (motor, gravity, friction, inertial), a joint Ipopt "
            "refinement and a mass-matrix consistency check on a data directory (payload.json, "
            "motor_j<k>_nominal/_payload, gravity, friction_j<k>, excitation recordings; see "
            "identification.data.dataset), then write the identified model and its validation report (Table 3)."
        ),
    )
    p.add_argument("robot", help="robot file (.toml or .urdf)")
    p.add_argument("--data", required=True, help="data directory")
    p.add_argument("--out", required=True, help="output directory of the identified model")
    p.add_argument("--model", default=None, help="derived PSDM model (.npz from 'psdm derive'); derived when omitted")
    p.add_argument("--no-refine", action="store_true", help="skip the joint refinement")
    p.add_argument("--plots", action="store_true", help="also write observed-vs-predicted plots (PNG)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing identified model")
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    p.set_defaults(handler=_run_identify)


def _run_identify(args) -> int:
    from identification.calibration.pipeline import IdentificationPipeline, PipelineOptions
    from identification.calibration.result import RESULT_FILES
    from psdm_casadi.derive import derive_psdm
    from psdm_casadi.model import load_model
    from psdm_casadi.robot import load_robot

    robot = load_robot(args.robot)
    out = Path(args.out)
    if not args.overwrite:
        for name in RESULT_FILES:
            if (out / name).exists():
                raise FileExistsError(f"{str(out / name)!r} exists; pass --overwrite to replace it.")
    if args.model:
        model = load_model(args.model)
    else:
        progress("identify: deriving the PSDM model ...", quiet=args.json)
        model = derive_psdm(robot)
    options = PipelineOptions(refine=not args.no_refine, quiet=args.json)
    pipeline = IdentificationPipeline(robot, model, options).fit(args.data)
    result = pipeline.result_
    result.save(out, overwrite=args.overwrite)
    (out / "report.md").write_text(result.report.to_markdown() + "\n")
    plots = [str(p) for p in pipeline.plot(out)] if args.plots else []
    if args.json:
        print_json(
            {
                "command": "identify",
                "robot": robot.name,
                "out": str(out),
                "kt": result.kt.tolist(),
                "theta": result.theta.tolist(),
                "base_names": list(model.base_names),
                "lugre": [p.as_dict() for p in result.lugre],
                "report": result.report.to_dict(),
                "consistency": result.consistency.to_dict(),
                "timings": pipeline.timings_,
                "plots": plots,
            }
        )
    else:
        print(result.report.to_markdown())
        print(f"identified model written to {out}")
    return 0
