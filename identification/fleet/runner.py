"""A fleet run: plan the robot-days, skip those stored, process the rest as Dask tasks, write as they finish.

The client plans (``plan``), loads each robot's baseline and PSDM model once (one model per distinct robot file),
sends them to the workers (``Client.scatter``) and submits one :func:`~identification.fleet.session.process_session`
task per new robot-day; it writes each result as it completes (``as_completed``), with the day's own page
(``day_report``), so an interrupted run (Ctrl-C, a killed client, a power cut) keeps every session written and the
next run resumes with the rest. A worker that dies has its tasks rerun by Dask; a task that still fails is stored as
a failed session. Then the drift tests run on the whole history (``drift``, then the fleet-relative ``fleet_check``)
and their findings replace the stored ones.

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

from identification.fleet.baseline import SharedModels, build_baseline
from identification.fleet.day_check import CheckOptions, error_reference
from identification.fleet.day_report import day_report_path, write_day_report
from identification.fleet.drift import DriftOptions, detect_drift, validation_parameters
from identification.fleet.fleet_check import FleetCheckOptions, fleet_outliers
from identification.fleet.history import History
from identification.fleet.layout import Fleet
from identification.fleet.plan import plan_run
from identification.fleet.session import SessionResult, process_session, software_version
from psdm_casadi.errors import ParameterError

__all__ = ["RunOptions", "RunSummary", "dask_client", "import_task_modules", "run_fleet"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class RunOptions:
    """Where the tasks run: ``serial`` here, else on ``scheduler`` or on a LocalCluster of ``workers`` processes
    (default: the number of cores). ``stop_after`` stops after that many written sessions (an interruption, for
    tests)."""

    workers: int | None = None
    scheduler: str | None = None
    serial: bool = False
    stop_after: int | None = None
    drift: DriftOptions = DriftOptions()
    fleet: FleetCheckOptions = FleetCheckOptions()
    check: CheckOptions = CheckOptions()
    day_reports: bool = True

    def __post_init__(self):
        if self.workers is not None and not (isinstance(self.workers, int) and self.workers >= 1):
            raise ParameterError(f"RunOptions.workers must be an integer >= 1; got {self.workers!r}.")


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
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        with Client(cluster) as client:
            client.run(import_task_modules)  # each worker imports the task's modules once, at start-up
            yield client


def import_task_modules() -> None:
    """Import what a robot-day task needs (CasADi, Pinocchio, SciPy, the readers): run on a worker at start-up."""
    import identification.fleet.session  # noqa: F401


def _baselines(fleet: Fleet, robot_ids: set, derive) -> tuple:
    """({robot_id: Baseline}, {model_key: PSDMModel}) of the robots with work to do."""
    baselines, models = {}, {}
    derive = SharedModels(derive)
    for entry in fleet.robots:
        if entry.robot_id in robot_ids:
            baseline, model = build_baseline(entry, fleet.track, derive)
            baselines[entry.robot_id] = baseline
            models.setdefault(baseline.model_key, model)
    return baselines, models


def _failed(task, exc) -> SessionResult:
    return SessionResult(task, "failed", None, f"{type(exc).__name__}: {exc}", 0.0, software_version())


class References:
    """Per robot: the days of its baseline window still to be written and, once none is, its error reference
    (``day_check.error_reference`` of the window as the history holds it)."""

    def __init__(self, history: History, tasks, todo, window: int, options: CheckOptions):
        self.history, self.window, self.options = history, window, options
        days: dict = {}
        for task in tasks:
            days.setdefault(task.robot_id, []).append(task.day)
        self.window_days = {robot: set(sorted(d)[:window]) for robot, d in days.items()}
        self.pending = {robot: set() for robot in days}
        for task in todo:
            if self.in_window(task):
                self.pending[task.robot_id].add(task.key)
        self.cache: dict = {}

    def in_window(self, task) -> bool:
        return task.day in self.window_days[task.robot_id]

    def ready(self, task) -> bool:
        """Whether the task can be submitted: a window day, or its robot's window is written."""
        return self.in_window(task) or not self.pending[task.robot_id]

    def written(self, task) -> bool:
        """Mark a task written; True when that completes its robot's window."""
        pending = self.pending[task.robot_id]
        if task.key not in pending:
            return False
        pending.discard(task.key)
        return not pending

    def reference(self, task):
        """None for a window day, else the robot's reference (None when its window has too few ok days)."""
        if self.in_window(task):
            return None
        if task.robot_id not in self.cache:
            rows = self.history.window_rows(task.robot_id, self.window)
            self.cache[task.robot_id] = error_reference(task.robot_id, rows, self.options)
        return self.cache[task.robot_id]


def _results_serial(todo, baselines, models, references: References):
    """The tasks in this process, with one BLAS thread as in a Dask worker (the same sums: the same bits); in plan
    order (robot, day), so each robot's window is written before its later days need their reference."""
    from threadpoolctl import threadpool_limits

    for task in todo:
        baseline = baselines[task.robot_id]
        reference = references.reference(task)
        with threadpool_limits(limits=1, user_api="blas"):
            result = process_session(task, baseline, models[baseline.model_key], reference)
        yield result
        references.written(task)


def _results_dask(client, todo, baselines, models, references: References):
    """The tasks on Dask, as they finish: window days first, a robot's later days once its window is written."""
    from dask.distributed import as_completed

    scattered_models = {key: client.scatter(model, broadcast=True) for key, model in models.items()}
    scattered = {rid: client.scatter(b, broadcast=True) for rid, b in baselines.items()}
    futures, held = {}, {}

    def submit(task):
        key = f"fleet-session-{task.robot_id}-{task.day}-{task.content_hash[:16]}"
        model = scattered_models[baselines[task.robot_id].model_key]
        future = client.submit(process_session, task, scattered[task.robot_id], model, references.reference(task),
                               key=key, pure=False)  # fmt: skip
        futures[future] = task
        return future

    for task in todo:
        if references.ready(task):
            submit(task)
        else:
            held.setdefault(task.robot_id, []).append(task)
    completed = as_completed(list(futures))
    try:
        for future in completed:
            task = futures[future]
            try:
                yield future.result()
            except Exception as exc:  # a task Dask gave up on (a worker killed too often): stored as failed
                yield _failed(task, exc)
            if references.written(task):
                for later in held.pop(task.robot_id, []):
                    completed.add(submit(later))
    finally:
        client.cancel(list(futures))


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
        interrupted = False
        status = "interrupted"
        try:
            if todo:
                baselines, models = _baselines(fleet, {t.robot_id for t in todo}, derive)
                references = References(history, plan.tasks, todo, fleet.baseline_days, options.check)
                with _executor(options, client) as run_client:
                    results = (_results_serial(todo, baselines, models, references) if run_client is None
                               else _results_dask(run_client, todo, baselines, models, references))  # fmt: skip
                    for result in results:
                        history.write_session(run_id, result)
                        if options.day_reports:
                            write_day_report(result, day_report_path(db_path, result.task.robot_id, result.task.day))
                        processed += 1
                        failed += result.status == "failed"
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
                      seconds, where, len(findings), interrupted)  # fmt: skip


def _findings(history: History, options: RunOptions, baseline_days: int) -> list:
    """The drift findings of each robot (parameters and validation error) against its baseline window, then the
    fleet-relative ones (parameters only: the error's level differs from robot to robot by design)."""
    rows = history.parameter_rows()
    tested = rows + validation_parameters(history.validation_rows())
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
