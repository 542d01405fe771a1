"""The work of a fleet run: one task per robot-day, named by the content of its recordings.

Every recording is hashed (sha256 of its bytes; of every file of a ROS 2 bag folder, by relative name), and a
day's content hash is the sha256 of its recordings' hashes in sorted order, so renaming or moving a recording does
not make it new, and changing one does. A recording whose content an earlier day of the same robot (or the same
day, under another name) already holds is dropped from the later one and listed in :attr:`RunPlan.duplicates`:
the same recording under two names is counted once.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

from identification.data.holdout import recording_digest
from identification.fleet.layout import Fleet
from identification.fleet.session import SessionTask

__all__ = ["Duplicate", "RunPlan", "plan_run"]


@dataclass(frozen=True)
class Duplicate:
    """A recording dropped because ``original`` (of ``original_day``) holds the same content."""

    robot_id: str
    day: str
    path: str
    original: str
    original_day: str


@dataclass(frozen=True)
class RunPlan:
    """Tasks in (robot, day) order, the recordings dropped as duplicates, and each used recording's hash."""

    tasks: tuple
    duplicates: tuple
    hashes: dict


def plan_run(fleet: Fleet) -> RunPlan:
    """Hash every recording of ``fleet`` and make one task per robot-day that keeps at least one recording."""
    tasks, duplicates, hashes = [], [], {}
    for robot in fleet.robots:
        seen: dict = {}
        for day in robot.days:
            kept = []
            for path in day.paths:
                digest = recording_digest(path)
                if digest in seen:
                    original, original_day = seen[digest]
                    duplicates.append(Duplicate(robot.robot_id, day.day, path, original, original_day))
                    continue
                seen[digest] = (path, day.day)
                hashes[path] = digest
                kept.append(path)
            if kept:
                joint = hashlib.sha256("".join(sorted(hashes[p] for p in kept)).encode()).hexdigest()
                tasks.append(SessionTask(robot.robot_id, day.day, tuple(kept), joint))
    return RunPlan(tuple(tasks), tuple(duplicates), hashes)
