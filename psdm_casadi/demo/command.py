"""``psdm demo``: the command line of the demo."""

from __future__ import annotations

import json

from psdm_casadi.demo.options import DemoOptions
from psdm_casadi.demo.story import run_demo
from psdm_casadi.overwrite_option import add_overwrite_argument


def register(subparsers) -> None:
    """Add ``psdm demo`` to the command line."""
    parser = subparsers.add_parser(
        "demo",
        help="the whole discovery loop on the built-in virtual Denso, with a report folder",
        description="Derive the Denso model, optimise an excitation, simulate the calibration experiments on "
        "a virtual robot that hides a cable-harness spring on joint 4, identify it in the paper's "
        "four steps (the spring corrupts them), diagnose the hidden spring, identify again with it, "
        "export and compile C of the corrected model, and write a Markdown report with plots. "
        "About 2 minutes; --quick takes about one.",
    )
    parser.add_argument("--out", default="demo_report", help="report folder (default demo_report)")
    parser.add_argument("--quick", action="store_true", help="short experiments, no refinement, no speed run")
    parser.add_argument("--seed", type=int, default=0, help="seed of every random choice (default 0)")
    add_overwrite_argument(
        parser,
        "replace the files an earlier demo report wrote in --out (listed in its .psdm-manifest.json; a folder "
        "that holds anything else is refused)",
        dest="force",
    )
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    parser.set_defaults(handler=run_demo_command)


def run_demo_command(args) -> int:
    """Run the demo; exit 0 when the spring is found and the corrected model is consistent, 1 otherwise."""
    options = DemoOptions.quick(seed=args.seed) if args.quick else DemoOptions(seed=args.seed)
    result = run_demo(args.out, options, overwrite=args.force)
    if args.json:
        print(json.dumps(result.summary, default=float))
    else:
        print(f"report: {result.folder / 'report.md'}")
    found = any(
        f["effect"] == "spring" and options.spring_joint + 1 in f["joints"]
        for f in result.summary["diagnosis"]["findings"]
    )
    return 0 if found and result.summary["final_model_consistent"] else 1
