"""A fleet run: plan the robot-days, skip those stored, process the rest as Dask tasks, write as they finish.

The client plans (``plan``), loads each robot's baseline and PSDM model once (one model per distinct robot file),
sends them to the workers (``Client.scatter``) and submits one :func:`~identification.fleet.session.process_session`
task per new robot-day; it writes each result as it completes (``as_completed``), with the day's own page
(``day_report``), so an interrupted run (Ctrl-C, a killed client, a power cut) keeps every session written and the
next run resumes with the rest. A worker that dies has its tasks rerun by Dask; a task Dask gives up on for the
cluster's sake (``KilledWorker``: its workers died; cancelled: the shared data it needs died with them) is submitted
again, with the shared data scattered again, up to ``RESUBMITS`` times; a task that raises is stored as a failed
session at once (its error is the task's own: running it again gives the same). Then the drift tests run on the
whole history (``drift``, then the fleet-relative ``fleet_check``) and their findings replace the stored ones.

A robot's days after its baseline window are checked against the window's validation errors (``day_check``): the
client submits them once the window's days are written (at once when they are stored already; a first run of a robot
thus goes in two waves, robots in parallel), each with its robot's reference, so every day is judged against the
same window whatever the order in which the tasks finish.

By default the tasks run on an embedded ``distributed.LocalCluster`` (one single-threaded worker process per core,
or ``workers``); ``scheduler`` names an existing Dask cluster instead; ``serial`` runs them in this process (the
reference the Dask runs equal).
"""

from __future__ import annotations

import logging
import os
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from identification.calibration.calibrated_model import CalibratedModel
from identification.fleet.baseline import SharedModels, build_baseline
from identification.fleet.day_check import CheckOptions
from identification.fleet.day_report import day_report_path, write_day_report
from identification.fleet.drift import DriftOptions, detect_drift, validation_parameters
from identification.fleet.fleet_check import FleetCheckOptions, fleet_outliers
from identification.fleet.history import History
from identification.fleet.layout import Fleet
from identification.fleet.plan import plan_run
from identification.fleet.reidentify import ReidentifyResult, baseline_file, reidentify
from identification.fleet.schedule import RobotContext, Wave, robot_waves
from identification.fleet.session import SessionResult, SessionTask, process_session, software_version
from psdm_casadi.errors import ParameterError

__all__ = ["RunOptions", "RunSummary", "dask_client", "import_task_modules", "lost_to_the_cluster", "run_fleet"]

logger = logging.getLogger(__name__)

WRITE_INTERVAL = 0.25  # s: the shortest time between two writes of a Dask run (``_batches``)
RESUBMITS = 3  # times a task lost to the cluster (``lost_to_the_cluster``) is submitted again before it is failed


@dataclass(frozen=True)
class RunOptions:
    """Where the tasks run: ``serial`` here, else on ``scheduler`` or on a LocalCluster of ``workers`` processes
    (default: the number of cores). ``stop_after`` stops after that many written sessions (an interruption, for
    tests). ``reidentify_every`` N re-identifies each robot after every N recording days of its baseline, and the
    robots in ``reidentify`` after their new days (``schedule``)."""

    workers: int | None = None
    scheduler: str | None = None
    serial: bool = False
    stop_after: int | None = None
    drift: DriftOptions = DriftOptions()
    fleet: FleetCheckOptions = FleetCheckOptions()
    check: CheckOptions = CheckOptions()
    day_reports: bool = True
    reidentify_every: int | None = None
    reidentify: tuple = ()

    def __post_init__(self):
        if self.workers is not None and not (isinstance(self.workers, int) and self.workers >= 1):
            raise ParameterError(f"RunOptions.workers must be an integer >= 1; got {self.workers!r}.")
        every = self.reidentify_every
        if every is not None and not (isinstance(every, int) and every >= 2):
            raise ParameterError(f"RunOptions.reidentify_every must be an integer >= 2 [days]; got {every!r}.")


@dataclass(frozen=True)
class RunSummary:
    """What a run did: sessions planned, processed (ok + failed), failed, skipped as stored, duplicates dropped."""

    run_id: int
    planned: int
    processed: int
    failed: int
    skipped: int
    duplicates: int
    seconds: float
    where: str
    findings: int
    interrupted: bool = False
    reidentified: tuple = ()


@contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None):
    """A ``distributed.Client``: of the cluster at ``scheduler``, else of an embedded LocalCluster."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        client = Client(scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0")
    client = None
    try:
        client = Client(cluster)
        client.run(import_task_modules)  # each worker imports the task's modules once, at start-up
        yield client
    finally:
        _close_quietly(client, cluster)


SHUTDOWN_LOGGERS = ("distributed", "tornado", "asyncio")


def quiet_logs() -> None:
    """Run on each worker before the cluster closes: its Dask loggers say nothing below CRITICAL."""
    for name in SHUTDOWN_LOGGERS:
        logging.getLogger(name).setLevel(logging.CRITICAL)


def _close_quietly(client, cluster) -> None:
    """Close the client, then the cluster, with Dask's loggers (here and on the workers) silent: a worker closing
    while the scheduler goes (``CommClosedError``) or one slow to stop on a loaded machine ("still alive after 4
    seconds, killing") is the shutdown, not news, and the results are written by then."""
    if client is not None:
        try:
            client.run(quiet_logs)
        except Exception:  # a worker already gone: nothing to silence there
            pass
    levels = {name: logging.getLogger(name).level for name in SHUTDOWN_LOGGERS}
    quiet_logs()
    try:
        if client is not None:
            client.close()
        cluster.close()
    finally:
        for name, level in levels.items():
            logging.getLogger(name).setLevel(level)


def import_task_modules() -> None:
    """Import what a robot-day task needs (CasADi, Pinocchio, SciPy, the readers): run on a worker at start-up."""
    import identification.fleet.session  # noqa: F401


def _contexts(fleet: Fleet, history: History, todo, derive, options: RunOptions) -> dict:
    """{robot_id: RobotContext} of the robots with work to do: their layout baseline and the re-identifications the
    history records (each loaded from its model file), sharing one PSDM model per distinct robot structure."""
    robot_ids = {t.robot_id for t in todo} | set(options.reidentify)
    derive = SharedModels(derive)
    recorded: dict = {}
    for robot_id, since, source in history.baselines():
        recorded.setdefault(robot_id, []).append((str(since), Path(source)))
    contexts, models = {}, {}
    for entry in fleet.robots:
        if entry.robot_id in robot_ids:
            baseline, model = build_baseline(entry, fleet.track, derive)
            models.setdefault(baseline.model_key, model)
            ctx = RobotContext(entry, {None: baseline}, fleet.baseline_days, options.reidentify_every,
                               entry.robot_id in options.reidentify, options.check, history, fleet.track, derive,
                               models)  # fmt: skip
            for since, source in recorded.get(entry.robot_id, []):
                ctx.add_baseline(since, source)
            contexts[entry.robot_id] = ctx
    return contexts


def _failed(task, exc) -> SessionResult:
    return SessionResult(task, "failed", None, f"{type(exc).__name__}: {exc}", 0.0, software_version())


def _run_item(item, wave: Wave, ctx: RobotContext):
    """One robot-day or a re-identification, in this process with one BLAS thread (as in a Dask worker)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        if wave.reidentify is not None:
            return reidentify(wave.reidentify, wave.baseline, ctx.models[wave.baseline.model_key], ctx.track)
        task, baseline, reference = item
        return process_session(task, baseline, ctx.models[baseline.model_key], reference)


def _results_serial(plan, todo, contexts):
    """Robot after robot, wave after wave, in this process: batches of one result."""
    for robot_id, ctx in contexts.items():
        for wave in robot_waves(ctx, _days(plan, robot_id), [t for t in todo if t.robot_id == robot_id]):
            for item in wave.sessions or (None,):
                yield [_run_item(item, wave, ctx)]


def _days(plan, robot_id: str) -> list:
    return sorted(t.day for t in plan.tasks if t.robot_id == robot_id)


def lost_to_the_cluster(future) -> bool:
    """True when Dask gave up on a done future for the cluster's sake, not for the task's: ``KilledWorker`` (workers
    died while running it, ``distributed.scheduler.allowed-failures`` + 1 times) or cancelled (its shared data were
    lost with the workers holding them). The task itself may be fine: it deserves another try."""
    from distributed import KilledWorker

    if future.status == "cancelled":
        return True
    return future.status == "error" and isinstance(future.exception(), KilledWorker)


def _outcomes(client, batch: list, tasks: dict) -> list:
    """The batch's results, fetched in one call (one round trip per worker, not per future), each task that raised
    (or that Dask gave up on ``RESUBMITS`` + 1 times) as a failed session or re-identification."""
    finished = [f for f in batch if f.status == "finished"]
    values = dict(zip(finished, client.gather(finished)))
    out = []
    for future in batch:
        if future in values:
            out.append(values[future])
            continue
        try:
            out.append(future.result())
        except Exception as exc:
            task = tasks[future]
            out.append(_failed(task, exc) if isinstance(task, SessionTask) else ReidentifyResult(task, None, str(exc)))
    return out


def _scatter_all(client, contexts) -> dict:
    """{id: future} of every baseline and PSDM model known now, scattered in one call with a copy on every worker
    (``broadcast``), so that a task usually finds its shared data where it runs and the scheduler sends it nothing
    with the task. Not a guarantee of one copy per worker for the run: Dask's active memory manager (on by default,
    its ``ReduceReplicas`` policy) drops copies it finds redundant, and a worker that then runs a task needing one
    fetches it from a peer and unpickles it again; a worker that dies takes its copies with it, and where it held the
    last one the future is lost (the tasks waiting for it are cancelled). ``_results_dask`` scatters such a value
    again before its next submission (``shared``) and submits the lost tasks again (``lost_to_the_cluster``)."""
    values = {id(m): m for ctx in contexts.values() for m in ctx.models.values()}
    values.update({id(b): b for ctx in contexts.values() for b in ctx.segments.values()})
    # hash=False: keys of their own, not the content's: a run right after an interrupted one scatters the same models,
    # and a content key the scheduler was still releasing from the first run made scatter wait forever
    futures = client.scatter(list(values.values()), broadcast=True, hash=False) if values else []
    return dict(zip(values, futures))


def _batches(completed):
    """The finished futures in batches: at least one, and those that finish within ``WRITE_INTERVAL`` of the last
    batch (each batch is one transaction, whose fixed cost, a few ms, would otherwise take a core's share from the
    workers when they finish a task every few tens of ms)."""
    last = time.perf_counter()
    while not completed.is_empty():
        batch = completed.next_batch(block=True)
        wait = WRITE_INTERVAL - (time.perf_counter() - last)
        if wait > 0 and completed.count():
            time.sleep(wait)
            batch += completed.next_batch(block=False)
        last = time.perf_counter()
        yield batch


def _results_dask(client, plan, todo, contexts):
    """Robots in parallel on Dask, each robot's waves in turn: its next wave is submitted once the last is written.
    Yields batches: every result finished since the last batch (fetched together), written together. A task lost to
    the cluster (``lost_to_the_cluster``) is submitted again (``RESUBMITS``) and written once it is done."""
    from dask.distributed import as_completed

    scattered = _scatter_all(client, contexts)

    def shared(value):
        future = scattered.get(id(value))
        if future is None or future.status != "finished":  # a baseline this run re-identified, or data lost
            scattered[id(value)] = client.scatter(value, broadcast=True, hash=False)
        return scattered[id(value)]

    futures, outstanding, generators, again = {}, {}, {}, {}

    def submit(robot_id, task, key, function, *args, attempt=0):
        """Submit ``function(*args)`` (the shared values scattered, again if they were lost) as the ``attempt``th
        try of ``task``; ``again`` remembers how to submit it once more."""
        values = [shared(a.value) if isinstance(a, _Shared) else a for a in args]
        future = client.submit(function, *values, key=key if not attempt else f"{key}-again{attempt}", pure=False)
        futures[future] = (robot_id, task)
        again[future] = (robot_id, task, key, function, args, attempt)
        return future

    def advance(robot_id):
        ctx = contexts[robot_id]
        wave = next(generators[robot_id], None)
        if wave is None:
            return []
        submitted = []
        for item in wave.sessions:
            task, baseline, reference = item
            key = f"fleet-session-{task.robot_id}-{task.day}-{task.content_hash[:16]}"
            submitted.append(submit(robot_id, task, key, process_session, task, _Shared(baseline),
                                    _Shared(ctx.models[baseline.model_key]), reference))  # fmt: skip
        if wave.reidentify is not None:
            key = f"fleet-reidentify-{robot_id}-{wave.reidentify.since}"
            model = _Shared(ctx.models[wave.baseline.model_key])
            submitted.append(submit(robot_id, wave.reidentify, key, reidentify, wave.reidentify,
                                    _Shared(wave.baseline), model, ctx.track))  # fmt: skip
        outstanding[robot_id] = len(submitted)
        return submitted or advance(robot_id)

    first = []
    for robot_id, ctx in contexts.items():
        generators[robot_id] = robot_waves(ctx, _days(plan, robot_id), [t for t in todo if t.robot_id == robot_id])
        first += advance(robot_id)
    completed = as_completed(first)
    try:
        for batch in _batches(completed):
            retry = [f for f in batch if again[f][-1] < RESUBMITS and lost_to_the_cluster(f)]
            for future in retry:
                robot_id, task, key, function, args, attempt = again[future]
                logger.warning("%s: %s; submitted again (%d of %d)", key, _why(future), attempt + 1, RESUBMITS)
                completed.add(submit(robot_id, task, key, function, *args, attempt=attempt + 1))
            batch = [f for f in batch if f not in retry]
            if not batch:
                continue
            yield _outcomes(client, batch, {f: futures[f][1] for f in batch})
            for future in batch:  # the batch is written: the robots whose wave is done go on
                robot_id = futures[future][0]
                outstanding[robot_id] -= 1
                if outstanding[robot_id] == 0:
                    completed.update(advance(robot_id))
    finally:
        client.cancel(list(futures))


@dataclass(frozen=True, eq=False)
class _Shared:
    """An argument of a task sent to the workers once (``_results_dask``'s ``shared``), not with each task."""

    value: object


def _why(future) -> str:
    return "cancelled" if future.status == "cancelled" else f"{type(future.exception()).__name__}"


def _write(history: History, run_id: int, batch: list, db_path, options: RunOptions, contexts) -> list:
    """Store a batch: its sessions in one transaction (then their day pages), each re-identification (its model
    file, its baselines row); returns the sessions."""
    sessions = [r for r in batch if not isinstance(r, ReidentifyResult)]
    for result in batch:
        if isinstance(result, ReidentifyResult):
            task = result.task
            if result.document is not None:
                path = baseline_file(db_path, task.robot_id, task.since)
                path.parent.mkdir(parents=True, exist_ok=True)
                CalibratedModel(result.document).save(path, allow_inconsistent=True, overwrite=True)
                history.record_baseline(task.robot_id, task.since, str(path), run_id)
                contexts[task.robot_id].add_baseline(task.since, path)
                logger.info("%s re-identified from %s (days %s)", task.robot_id, task.since, ", ".join(task.days))
    history.write_sessions(run_id, sessions)
    if options.day_reports:
        for result in sessions:
            write_day_report(result, day_report_path(db_path, result.task.robot_id, result.task.day))
    return sessions


def run_fleet(fleet: Fleet, db_path, options: RunOptions | None = None, derive=None, client=None) -> RunSummary:
    """Process the new robot-days of ``fleet`` into the history ``db_path`` and update the drift findings.

    ``derive(robot) -> PSDMModel`` (default: the model cache); ``client`` an open ``distributed.Client`` (else one
    is made from ``options``).
    """
    options = options or RunOptions()
    if derive is None:
        from psdm_casadi.model_cache import ModelCache

        derive = ModelCache().derive
    start = time.perf_counter()
    plan = plan_run(fleet)
    with History(db_path) as history:
        done = history.done_keys()
        todo = [task for task in plan.tasks if task.key not in done]
        where = (
            "serial" if options.serial else (options.scheduler or f"LocalCluster({options.workers or os.cpu_count()})")
        )
        if client is not None and not options.serial:
            where = f"client {client.scheduler.address}"
        run_id = history.start_run(str(fleet.source), software_version(), where, len(plan.tasks))
        history.record_recordings(plan.hashes, plan.tasks, plan.duplicates)
        logger.info("%d robot-days, %d new, %d stored; running on %s", len(plan.tasks), len(todo), len(done), where)
        processed = failed = 0
        reidentified = ()
        interrupted = False
        status = "interrupted"
        try:
            if todo or options.reidentify:
                contexts = _contexts(fleet, history, todo, derive, options)
                with _executor(options, client) as run_client:
                    results = (_results_serial(plan, todo, contexts) if run_client is None
                               else _results_dask(run_client, plan, todo, contexts))  # fmt: skip
                    for batch in results:
                        if options.stop_after is not None:  # an interruption after that many sessions (tests)
                            batch = _truncated(batch, options.stop_after - processed)
                        sessions = _write(history, run_id, batch, db_path, options, contexts)
                        reidentified += tuple(_reidentified(r) for r in batch if isinstance(r, ReidentifyResult))
                        processed += len(sessions)
                        failed += sum(r.status == "failed" for r in sessions)
                        if options.stop_after is not None and processed >= options.stop_after:
                            interrupted = True
                            break
                    if hasattr(results, "close"):
                        results.close()
            findings = [] if interrupted else _findings(history, options, fleet.baseline_days)
            if not interrupted:
                history.replace_findings(run_id, findings)
                status = "done"
        finally:
            history.finish_run(run_id, processed, failed, len(plan.tasks) - len(todo), status)
    seconds = time.perf_counter() - start
    return RunSummary(run_id, len(plan.tasks), processed, failed, len(plan.tasks) - len(todo), len(plan.duplicates),
                      seconds, where, len(findings), interrupted, reidentified)  # fmt: skip


def _truncated(batch: list, sessions: int) -> list:
    """The batch up to its first ``sessions`` sessions (re-identifications before them kept)."""
    out = []
    for result in batch:
        if not isinstance(result, ReidentifyResult):
            if sessions <= 0:
                break
            sessions -= 1
        out.append(result)
    return out


def _reidentified(result: ReidentifyResult) -> str:
    task = result.task
    return f"{task.robot_id} from {task.since}" if result.document else f"{task.robot_id} failed: {result.error}"


def _findings(history: History, options: RunOptions, baseline_days: int) -> list:
    """The drift findings of each robot (parameters and validation error) against its baseline window, then the
    fleet-relative ones (parameters only: the error's level differs from robot to robot by design)."""
    since: dict = {}
    for robot_id, day, _ in history.baselines():  # a re-identification restarts the robot's window
        since[robot_id] = day
    rows = [r for r in history.parameter_rows() if r.day >= since.get(r.robot_id, r.day)]
    validation = [r for r in history.validation_rows() if r[1] >= since.get(r[0], r[1])]
    tested = rows + validation_parameters(validation)
    return detect_drift(tested, options.drift, baseline_days) + fleet_outliers(rows, options.fleet)


@contextmanager
def _executor(options: RunOptions, client):
    """None for a serial run, the given client, or a client of a new cluster for this run."""
    if options.serial:
        yield None
    elif client is not None:
        yield client
    else:
        with dask_client(options.workers, options.scheduler) as own:
            yield own
