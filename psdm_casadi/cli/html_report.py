"""``report.html`` of ``psdm identify``: the option that names it, its checks before any work, and its writing.

By default the page is written beside the model file (``model.json`` -> ``model.report.html``); ``--html FILE``
names it, ``--no-html`` leaves it out, and with ``--json`` it is written only when ``--html`` asks for it. An
existing file is replaced only with ``--overwrite``; the page is written atomically (``OutputFile.staging``).
The page itself is built by ``identification.report_html.identify_page``.
"""

from __future__ import annotations

from pathlib import Path

from psdm_casadi.cli.checks import check_not_input, check_suffix, output_file
from psdm_casadi.errors import ParameterError


def add_html_argument(p) -> None:
    """Add ``--html FILE`` and ``--no-html`` to ``p``."""
    p.add_argument(
        "--html",
        default=None,
        metavar="FILE",
        help="the HTML report (self-contained: opens from disk, interactive plots); default: beside --out, "
        "MODEL.report.html (not written with --json unless --html names it)",
    )
    p.add_argument("--no-html", action="store_true", help="write no HTML report")


def refuse_html_option(args, why: str) -> None:
    """A route that writes no page refuses ``--html`` rather than ignore it."""
    if args.html is not None:
        raise ParameterError(
            f"--html {args.html!r}: no HTML report on this route ({why}). Drop --html, or identify from recording "
            "files (--data A.csv ...), which writes the page."
        )


def default_html_path(out) -> Path:
    """The page beside a model file: ``model.json`` -> ``model.report.html``."""
    out = Path(str(out))
    return out.with_name(f"{out.stem}.report.html")


def html_output(args):
    """The checked HTML output of ``psdm identify`` (``OutputFile``), or None when none is to be written; never
    one of its inputs (robot, --model, --data, --validate) nor the model file."""
    if args.no_html or (args.json and args.html is None):
        return None
    path = args.html if args.html is not None else default_html_path(args.out)
    inputs = [("ROBOT", args.robot), ("--model", args.model)]
    inputs += [("--data", p) for p in args.data] + [("--validate", p) for p in args.validate]
    check_not_input(path, "--html", inputs, example="report.html")
    check_suffix(path, "--html", (".html", ".htm"), "a self-contained HTML page")
    if Path(str(path)).resolve() == Path(str(args.out)).resolve():
        raise ParameterError(f"--html {str(path)!r} is the model file --out; pass another file, e.g. report.html.")
    return output_file(path, "--html", args.overwrite)


def write_identify_html(output, robot, model, calibrated, recordings, names, files=("MODEL.json", "")) -> Path:
    """Write the identify page of ``calibrated`` with its prediction of ``recordings`` to ``output`` (held out
    when they are not the training recordings the model file names); ``files``: (the model file written, the
    ``psdm diagnose`` command of it with this run's recordings) for the page's next step."""
    from identification.report_html.identify_page import NextFiles, identify_page, torque_series

    trained = {r["name"] for r in calibrated.document.get("provenance", {}).get("recordings") or []}
    held_out = not any(Path(str(name)).name in trained for name in names)
    series = torque_series(calibrated, model, robot, recordings, names, held_out)
    page = identify_page(calibrated.document, series, NextFiles(*files))
    with output.staging() as stage:
        page.write(stage, overwrite=True)
    return output.target
