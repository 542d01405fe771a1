"""Fleet benchmark (issue 27): a virtual fleet with known events through ``psdm fleet``'s run on Dask.

A virtual fleet (``identification.virtual.fleet``: robots of the Denso VS-6556G with manufacturing spread, a
daily health-check motion logging currents, six kinds of event with onset days, healthy robots) is processed
with 1 and with 2 Dask workers (fresh history each; a LocalCluster per worker count, its start-up excluded).
Detection is scored against the truth written beside the fleet: an event counts as detected when a finding
names its robot and its parameter (``fc3``, ``spring_k_2``, ``payload_mass``, ...) with an onset within 3
recording days; its size is compared with the truth's (relative change, or kg) in the finding's sigma. A false
alarm is a finding on a healthy robot, or on a joint of an event robot that carries no event (a payload change
loads every joint: its robot's findings other than on the payload count as related, not false). The
incremental rerun (nothing new) is timed against the first run. A 5-minute health check at 1 kHz is timed
serially to project the cluster that processes 1000 robots x 5 min a day in under an hour.

    python benchmarks/fleet.py [--robots 20] [--days 30] [--duration 6] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import tempfile
import time
from pathlib import Path

from identification.fleet.baseline import SharedModels, build_baseline
from identification.fleet.drift import DriftFinding
from identification.fleet.history import History
from identification.fleet.layout import read_fleet
from identification.fleet.plan import plan_run
from identification.fleet.runner import dask_client, run_fleet
from identification.fleet.session import process_session
from identification.virtual.fleet import VirtualFleetOptions, write_virtual_fleet
from psdm_casadi.model_cache import ModelCache

ONSET_DAYS = 3


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def score(findings: list, truth: dict, start: str) -> dict:
    """Detection rate, false alarms, worst onset error [days] and sizes in sigma against the truth."""
    import datetime as dt

    day0 = dt.date.fromisoformat(start)
    events = truth["events"]
    detected, onset_errors, size_z, missed = 0, [], [], []
    event_joints = {(e["robot_id"], e["joint"]) for e in events}
    payload_robots = {e["robot_id"] for e in events if e["kind"] == "payload_change"}
    for e in events:
        hits = [f for f in findings if f.robot_id == e["robot_id"] and f.parameter == e["parameter"]]
        hits = [f for f in hits if f.onset and abs((f.onset - day0).days - e["onset_index"]) <= ONSET_DAYS]
        if not hits:
            missed.append(f"{e['robot_id']} {e['kind']} {e['parameter']}")
            continue
        f = hits[0]
        detected += 1
        onset_errors.append(abs((f.onset - day0).days - e["onset_index"]))
        if e["kind"] == "payload_change":
            size_z.append(abs(f.size - e["size"]) / f.size_sigma)
        elif f.relative_percent is not None:
            sigma_percent = abs(f.relative_percent / f.size) * f.size_sigma if f.size else math.inf
            size_z.append(abs(f.relative_percent - 100 * e["size"]) / sigma_percent)
    false = [f.text for f in findings if (f.robot_id, f.joint) not in event_joints and f.robot_id not in payload_robots]
    return {
        "events": len(events),
        "detected": detected,
        "detection_rate": detected / max(len(events), 1),
        "false_alarms": len(false),
        "false_alarm_texts": false,
        "missed": missed,
        "onset_error_days": max(onset_errors) if onset_errors else None,
        "size_error_sigma_max": max(size_z) if size_z else None,
        "size_within_2_sigma_fraction": sum(z <= 2 for z in size_z) / max(len(size_z), 1),
    }


def _timed_run(fleet, db: Path, workers: int, derive) -> tuple:
    with dask_client(workers=workers) as client:
        summary = run_fleet(fleet, db, derive=derive, client=client)
        peaks = client.run(_peak_mb)
    return summary, max(peaks.values())


def _projection(folder: Path, derive) -> dict:
    """Cost of one 5-minute, 1 kHz robot-day (serial, one BLAS thread) and the cluster for 1000 robots in 1 h."""
    from threadpoolctl import threadpool_limits

    options = VirtualFleetOptions(n_robots=1, n_days=1, duration=300.0, rate=1000.0, event_robots=0, seed=7)
    write_virtual_fleet(folder, options)
    fleet = read_fleet(folder)
    baseline, model = build_baseline(fleet.robots[0], fleet.track, SharedModels(derive))
    task = plan_run(fleet).tasks[0]
    start = time.perf_counter()
    with threadpool_limits(limits=1, user_api="blas"):
        result = process_session(task, baseline, model)
    seconds = time.perf_counter() - start
    cores = math.ceil(1000 * seconds / 3600.0 / 0.8)  # at the 2-worker scaling efficiency target
    return {"status": result.status, "seconds_per_robot_day": round(seconds, 2), "peak_mb": round(_peak_mb(), 1),
            "cores_for_1000_robots_in_1_hour": cores}  # fmt: skip


def run(args) -> dict:
    out = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="psdm-fleet-"))
    options = VirtualFleetOptions(n_robots=args.robots, n_days=args.days, duration=args.duration, rate=args.rate)
    start = time.perf_counter()
    truth = write_virtual_fleet(out / "fleet", options)
    generate = time.perf_counter() - start
    fleet = read_fleet(out / "fleet")
    derive = SharedModels(ModelCache().derive)
    n = fleet.n_sessions
    rpm, peaks, summaries = {}, {}, {}
    for workers in args.workers:
        db = out / f"history_{workers}.duckdb"
        db.unlink(missing_ok=True)
        summary, peak = _timed_run(fleet, db, workers, derive)
        rpm[str(workers)] = round(60.0 * n / summary.seconds, 1)
        peaks[str(workers)] = round(peak, 1)
        summaries[workers] = summary
    last = max(args.workers)
    db = out / f"history_{last}.duckdb"
    rerun, _ = _timed_run(fleet, db, last, derive)
    with History(db) as history:
        findings = [DriftFinding(*row) for row in history.findings()]
    scores = score(findings, truth, options.start)
    efficiency = None
    if 1 in args.workers and last > 1:
        efficiency = round(rpm[str(last)] / (last * rpm["1"]), 3)
    result = {
        "robots": args.robots,
        "days": args.days,
        "recordings": n,
        "event_kinds": len({e["kind"] for e in truth["events"]}),
        **{
            k: scores[k]
            for k in (
                "detection_rate",
                "false_alarms",
                "onset_error_days",
                "size_within_2_sigma_fraction",
                "size_error_sigma_max",
                "missed",
                "false_alarm_texts",
            )
        },  # fmt: skip
        "recordings_per_minute": rpm,
        "scaling_efficiency": efficiency,
        "peak_mb_per_worker": max(peaks.values()),
        "incremental_rerun_fraction": round(rerun.seconds / summaries[last].seconds, 4),
        "generate_seconds": round(generate, 1),
        "failed_sessions": summaries[last].failed,
    }
    if not args.no_projection:
        result["projection_1000_robots_5_min_1khz"] = _projection(out / "long", derive)
    return result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=20)
    parser.add_argument("--days", type=int, default=30)
    parser.add_argument("--duration", type=float, default=6.0, help="health-check motion [s]")
    parser.add_argument("--rate", type=float, default=200.0, help="sample rate [Hz]")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--keep", default=None, help="write the fleet and histories here (default: a temp folder)")
    parser.add_argument("--no-projection", action="store_true", help="skip the 5-minute 1 kHz robot-day")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    args = parser.parse_args(argv)
    result = run(args)
    if args.json:
        print(json.dumps(result, indent=1, default=str))
    else:
        for key, value in result.items():
            print(f"{key:36s} {value}")


if __name__ == "__main__":
    main()
