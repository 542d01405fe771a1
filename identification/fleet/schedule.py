"""The order of a run's work per robot: waves of robot-days that can run in parallel, and re-identifications.

A robot's days fall into segments, each judged against one baseline: the first against the layout's (its robot
file or calibrated model), each later one from a re-identification's ``since`` day on (the history's ``baselines``
table, or one this run makes). Within a segment, the days of its window (its first ``baseline_days`` recording
days) go first; the later days follow once the window is written, each with the robot's error reference of that
window (``day_check``). With ``every`` N, a segment ends at its N-th recording day: the robot is re-identified on
the last window's worth of ok days up to there (``reidentify``) and the next segment starts the day after. With
``demand``, the robot is re-identified after its new days, on its latest ok days.

:func:`robot_waves` yields a robot's :class:`Wave` one at a time and reads the history between them (the client
has written the previous wave by then), so a serial run and a Dask run (robots in parallel, ``run_waves``) do the
same work with the same inputs: the same results.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from identification.fleet.baseline import Baseline, build_baseline
from identification.fleet.day_check import CheckOptions, error_reference
from identification.fleet.layout import RobotEntry
from identification.fleet.reidentify import ReidentifyTask, next_day

__all__ = ["RobotContext", "Wave", "robot_waves"]


@dataclass(frozen=True)
class Wave:
    """Robot-days to run in parallel, as ``(task, baseline, reference)``, or one re-identification."""

    sessions: tuple = ()
    reidentify: ReidentifyTask | None = None
    baseline: Baseline | None = None


@dataclass
class RobotContext:
    """What a robot's schedule needs: its entry, its segments ``{since: Baseline}`` (None: the layout's), the
    options, the history, ``derive`` (to load a new baseline file) and the run's PSDM models by key."""

    entry: RobotEntry
    segments: dict
    window: int
    every: int | None
    demand: bool
    check: CheckOptions
    history: object
    track: object
    derive: object
    models: dict
    failed: set = field(default_factory=set)

    def add_baseline(self, since: str, path) -> Baseline:
        """Load a re-identification's model file as the baseline of the days from ``since`` on."""
        entry = RobotEntry(self.entry.robot_id, path, ())
        baseline, model = build_baseline(entry, self.track, self.derive)
        self.models.setdefault(baseline.model_key, model)
        self.segments[since] = baseline
        return baseline

    def segment_of(self, day: str) -> tuple:
        """(since, baseline, next since or None) of the segment holding ``day``."""
        starts = sorted((s for s in self.segments if s is not None), reverse=True)
        since = next((s for s in starts if s <= day), None)
        later = [s for s in starts if since is None or s > since]
        return since, self.segments[since], (min(later) if later else None)

    def ok_days(self, since, until) -> list:
        """``(day, paths)`` of the robot's ok stored days in ``[since, until]``, in order."""
        rows = self.history.connection.execute(
            "SELECT CAST(s.day AS VARCHAR), list(r.path ORDER BY r.path) FROM sessions s JOIN recordings r "
            "ON r.robot_id = s.robot_id AND r.day = s.day AND r.duplicate_of IS NULL WHERE s.robot_id = ? AND "
            "s.status = 'ok' AND s.day >= coalesce(CAST(? AS DATE), DATE '0001-01-01') AND s.day <= CAST(? AS DATE) "
            "GROUP BY s.day ORDER BY s.day",
            [self.entry.robot_id, since, until],
        ).fetchall()
        return [(day, tuple(paths)) for day, paths in rows]


def _reidentification(ctx: RobotContext, since, until: str, new_since: str, baseline: Baseline) -> Wave | None:
    days = ctx.ok_days(since, until)[-ctx.window :]
    if not days:
        return None
    paths = tuple(p for _, ps in days for p in ps)
    task = ReidentifyTask(ctx.entry.robot_id, new_since, tuple(d for d, _ in days), paths)
    return Wave(reidentify=task, baseline=baseline)


def robot_waves(ctx: RobotContext, planned: list, todo: list):
    """The waves of one robot (module docstring): ``planned`` its days of the plan, ``todo`` its new tasks, both
    in day order."""
    remaining = list(todo)
    while remaining:
        since, baseline, upcoming = ctx.segment_of(remaining[0].day)
        days = [d for d in planned if (since is None or d >= since) and (upcoming is None or d < upcoming)]
        due = ctx.every is not None and upcoming is None and len(days) >= ctx.every and since not in ctx.failed
        end = days[ctx.every - 1] if due else None
        mine = [t for t in remaining if t.day in days and (end is None or t.day <= end)]
        window = set(days[: ctx.window])
        first = tuple((t, baseline, None) for t in mine if t.day in window)
        if first:
            yield Wave(sessions=first)
        rest = [t for t in mine if t.day not in window]
        if rest:
            rows = ctx.history.window_rows(ctx.entry.robot_id, ctx.window, since)
            friction = ctx.history.window_parameters(ctx.entry.robot_id, ctx.window, since, "fc")
            reference = error_reference(ctx.entry.robot_id, rows, ctx.check, friction)
            yield Wave(sessions=tuple((t, baseline, reference) for t in rest))
        remaining = [t for t in remaining if t not in mine]
        if end is not None:
            wave = _reidentification(ctx, since, end, next_day(end), baseline)
            if wave is not None:
                yield wave
            if wave is None or wave.reidentify.since not in ctx.segments:
                ctx.failed.add(since)  # no new baseline: the segment goes on with its own
    if ctx.demand and planned:
        since, baseline, _ = ctx.segment_of(planned[-1])
        wave = _reidentification(ctx, since, planned[-1], next_day(planned[-1]), baseline)
        if wave is not None:
            yield wave
