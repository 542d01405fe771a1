"""The ``psdm fleet`` subcommands: run a fleet's new robot-days on Dask, show its status, write its report.

``psdm fleet run FLEET`` processes every new robot-day into the history database (DuckDB) and runs the drift
tests; ``psdm fleet status`` prints what the database holds; ``psdm fleet report --out report.html`` writes the
self-contained page; ``psdm fleet simulate OUT`` writes a virtual fleet with known events (and its truth).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from psdm_casadi.cli.checks import check_count
from psdm_casadi.cli.output import EXIT_OK, print_json, progress
from psdm_casadi.errors import ParameterError

DB_HELP = "the history database (DuckDB file; created when new; default fleet.duckdb)"
LAYOUT_HELP = (
    "a fleet folder FLEET/ROBOT_ID/YYYY-MM-DD/<recordings (.csv .npz .mat .mcap .db3, ROS 2 bag folders)> with "
    "FLEET/ROBOT_ID/baseline.json (a calibrated model of 'psdm identify') or robot.toml / robot.urdf, and an "
    "optional FLEET/fleet.toml ([fleet] baseline_days, [track] spring, ripple, offset, payload_com); or a TOML "
    "manifest listing [[robot]] id, baseline or robot, recordings"
)


def register(subparsers) -> None:
    """Add ``fleet`` (with run, status, report, simulate) to the ``psdm`` parser."""
    p = subparsers.add_parser(
        "fleet",
        help="many robots over time: daily refits on Dask, a parameter history, drift and wear alarms, a report",
        description="Track a fleet of robots: every robot-day's friction, drive and tracked terms refitted with the "
        "baseline rigid body held (a Dask task each), stored with sigma in a DuckDB history, and tested for drift.",
    )
    sub = p.add_subparsers(dest="fleet_command", metavar="ACTION")
    run = sub.add_parser("run", help="process the new robot-days of a fleet and update the drift findings",
                         description=f"FLEET is {LAYOUT_HELP}. Robot-days already stored (same recordings' content) "
                         "are skipped; an interrupted run resumes. Exit 1 when a drift finding stands.")  # fmt: skip
    run.add_argument("fleet", type=Path, help="fleet folder or TOML manifest")
    run.add_argument("--db", type=Path, default=Path("fleet.duckdb"), help=DB_HELP)
    where = run.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, help="worker processes of the embedded Dask cluster "
                       "(default: one per core)")  # fmt: skip
    where.add_argument("--scheduler", default=None, metavar="ADDRESS", help="run on an existing Dask cluster, e.g. "
                       "tcp://10.0.0.5:8786")  # fmt: skip
    where.add_argument("--serial", action="store_true", help="run in this process, without Dask")
    run.add_argument("--reidentify-every", type=int, default=None, metavar="N",
                     help="re-identify each robot after every N recording days of its baseline (a new calibrated "
                     "baseline beside the history, from its last baseline-window days; later days are judged against "
                     "it and the drift tests restart there)")  # fmt: skip
    run.add_argument(
        "--reidentify",
        action="append",
        default=[],
        metavar="ROBOT",
        help="re-identify this robot after its new days, on its latest days (repeat for several)",
    )
    run.add_argument("--export-parquet", type=Path, default=None, metavar="DIR",
                     help="also write every table as DIR/TABLE.parquet")  # fmt: skip
    run.add_argument("--json", action="store_true", help="print one JSON object")
    run.set_defaults(handler=_run)
    status = sub.add_parser("status", help="what the history holds: per robot sessions, failures and findings")
    status.add_argument("--db", type=Path, default=Path("fleet.duckdb"), help=DB_HELP)
    status.add_argument("--json", action="store_true", help="print one JSON object")
    status.set_defaults(handler=_status)
    report = sub.add_parser("report", help="write the fleet report: one self-contained HTML page")
    report.add_argument("--db", type=Path, default=Path("fleet.duckdb"), help=DB_HELP)
    report.add_argument("--out", type=Path, required=True, help="the HTML file to write")
    report.set_defaults(handler=_report)
    simulate = sub.add_parser("simulate", help="write a virtual fleet with known events and its truth (.json)")
    simulate.add_argument("out", type=Path, help="the fleet folder to write (the truth goes beside it)")
    simulate.add_argument("--robots", type=int, default=20)
    simulate.add_argument("--days", type=int, default=30)
    simulate.add_argument("--duration", type=float, default=6.0, help="health-check motion [s]")
    simulate.add_argument("--seed", type=int, default=0)
    simulate.set_defaults(handler=_simulate)
    p.set_defaults(handler=lambda args: _usage(p))


def _usage(parser: argparse.ArgumentParser) -> int:
    parser.print_help()
    return 2


def _open(path: Path, must_exist: bool = True):
    from identification.fleet.history import History

    if must_exist and not path.is_file():
        raise ParameterError(f"--db {path}: no such history database. Run 'psdm fleet run FLEET --db {path}' first.")
    return History(path)


def _run(args) -> int:
    from identification.fleet.layout import read_fleet
    from identification.fleet.report import diagnosis_lines
    from identification.fleet.runner import RunOptions, run_fleet
    from psdm_casadi.cli.checks import derive_model

    if args.workers is not None:
        check_count(args.workers, "--workers", "pass the number of worker processes, e.g. --workers 2")
    if args.reidentify_every is not None:
        check_count(args.reidentify_every, "--reidentify-every", "pass a number of days, e.g. --reidentify-every 30",
                    minimum=2)  # fmt: skip
    fleet = read_fleet(args.fleet)
    unknown = sorted(set(args.reidentify) - {r.robot_id for r in fleet.robots})
    if unknown:
        raise ParameterError(f"--reidentify {', '.join(unknown)}: no such robot in {args.fleet}; its robots are "
                             f"{', '.join(r.robot_id for r in fleet.robots)}.")  # fmt: skip
    progress(f"fleet {fleet.name}: {len(fleet.robots)} robots, {fleet.n_sessions} robot-days")
    options = RunOptions(workers=args.workers, scheduler=args.scheduler, serial=args.serial,
                         reidentify_every=args.reidentify_every, reidentify=tuple(args.reidentify))  # fmt: skip
    summary = run_fleet(fleet, args.db, options, derive=lambda robot: derive_model(args, robot))
    with _open(args.db) as history:
        findings = history.findings()
        diagnoses = [f"{robot}: {line}" for robot, lines in diagnosis_lines(history).items() for line in lines]
        if args.export_parquet is not None:
            history.export_parquet(args.export_parquet)
    out = {"command": "fleet run", "db": str(args.db), "run_id": summary.run_id, "planned": summary.planned,
           "processed": summary.processed, "failed": summary.failed, "skipped": summary.skipped,
           "duplicates": summary.duplicates, "seconds": round(summary.seconds, 3), "where": summary.where,
           "findings": [f[-1] for f in findings], "diagnoses": diagnoses,
           "reidentified": list(summary.reidentified)}  # fmt: skip
    if args.json:
        print_json(out)
    else:
        print(
            f"{summary.processed} robot-days processed ({summary.failed} failed), {summary.skipped} already stored, "
            f"{summary.duplicates} duplicate recordings dropped, on {summary.where} in {summary.seconds:.1f} s"
        )
        for line in summary.reidentified:
            print(f"re-identified {line}")
        for f in findings:
            print(f"ALARM {f[0]}: {f[-1]}")
        for line in diagnoses:
            print(f"DIAGNOSIS {line}")
    return 1 if findings or diagnoses else EXIT_OK


def _status(args) -> int:
    from identification.fleet.report import fleet_rows

    with _open(args.db) as history:
        rows = fleet_rows(history)
        failures = history.failures()
        baselines = {robot_id: (str(since), source) for robot_id, since, source in history.baselines()}
    if args.json:
        robots = [r.__dict__ | {"alarms": list(r.alarms), "diagnoses": list(r.diagnoses),
                                "baseline": baselines.get(r.robot_id)} for r in rows]  # fmt: skip
        print_json({"command": "fleet status", "robots": robots,
                    "failures": [{"robot": r, "day": str(d), "error": e} for r, d, e in failures]})  # fmt: skip
        return EXIT_OK
    for r in rows:
        print(f"{r.robot_id:12s} last {r.last_day}  ok {r.ok:4d}  failed {r.failed:3d}  {r.status}")
        if r.robot_id in baselines:
            print(f"    re-identified: baseline from {baselines[r.robot_id][0]} ({baselines[r.robot_id][1]})")
        for alarm in (*r.alarms, *r.diagnoses):
            print(f"    {alarm}")
    for robot_id, day, error in failures:
        print(f"failed {robot_id} {day}: {error}")
    return EXIT_OK


def _report(args) -> int:
    from identification.fleet.report import write_report

    with _open(args.db) as history:
        path = write_report(history, args.out)
    print(f"wrote {path}")
    return EXIT_OK


def _simulate(args) -> int:
    from identification.virtual.fleet import VirtualFleetOptions, write_virtual_fleet

    check_count(args.robots, "--robots", "pass at least one robot")
    check_count(args.days, "--days", "pass at least 3 days", minimum=3)
    truth = write_virtual_fleet(args.out, VirtualFleetOptions(n_robots=args.robots, n_days=args.days,
                                                              duration=args.duration, seed=args.seed))  # fmt: skip
    print(f"wrote {args.out}: {len(truth['robots'])} robots x {args.days} days, {len(truth['events'])} events")
    return EXIT_OK
