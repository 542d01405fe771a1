"""A fleet on disk: robots, their baseline (robot file or calibrated model) and their dated recordings.

Two ways to state a fleet, read by :func:`read_fleet`:

- **a folder** ``FLEET/ROBOT_ID/YYYY-MM-DD/*.csv|npz|mat|mcap|db3`` (or ROS 2 bag folders), where each robot
  folder holds its baseline: ``baseline.json`` (a calibrated-model file of ``psdm identify``) or a robot file
  ``robot.toml`` / ``robot.urdf`` (its nominal parameters are the baseline). An optional ``FLEET/fleet.toml``
  holds the settings (the ``[fleet]`` and ``[track]`` tables below);
- **a TOML manifest** listing them::

      [fleet]
      name = "cell 3"
      baseline_days = 7            # the first recording days of each robot are its baseline window

      [track]                      # terms refitted every day besides Coulomb and viscous friction
      spring = [2]                 # a spring (counterbalance) on joint 2: stiffness and preload
      ripple = [[4, 12]]           # torque ripple on joint 4, 12 periods per revolution
      offset = [1, 3]              # a torque offset on joints 1 and 3
      payload_com = [0.0, 0.0, 0.05]   # a payload mass at this flange point [m]

      [[robot]]
      id = "r01"
      robot = "r01/robot.toml"     # or baseline = "r01/baseline.json"
      recordings = "r01"           # a folder of YYYY-MM-DD folders, or a list of {day, path} tables

Paths in a manifest are relative to it. A layout that does not parse raises :class:`FleetLayoutError` naming the
path and the fix (the CLI exits 2).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from pathlib import Path

import tomllib

from psdm_casadi.errors import ParameterError

__all__ = ["DayRecordings", "Fleet", "FleetLayoutError", "RobotEntry", "TrackedTerms", "read_fleet"]

RECORDING_SUFFIXES = (".csv", ".npz", ".mat", ".mcap", ".db3")
BASELINE_NAMES = ("baseline.json", "robot.toml", "robot.urdf")
SETTINGS_FILE = "fleet.toml"
LAYOUT_FIX = (
    "Lay the fleet out as FLEET/ROBOT_ID/YYYY-MM-DD/<recordings> with FLEET/ROBOT_ID/baseline.json, robot.toml or "
    "robot.urdf, or pass a TOML manifest (see 'psdm fleet run --help')."
)


class FleetLayoutError(ParameterError):
    """A fleet folder or manifest that does not describe robots with a baseline and dated recordings."""


@dataclass(frozen=True)
class TrackedTerms:
    """Terms refitted every day on top of Coulomb and viscous friction (joints 1-based, as in the manifest)."""

    spring: tuple = ()
    ripple: tuple = ()  # (joint, harmonic) pairs
    offset: tuple = ()
    payload_com: tuple | None = None

    def __post_init__(self):
        joints = [*self.spring, *self.offset, *(j for j, _ in self.ripple)]
        if any(not (isinstance(j, int) and j >= 1) for j in joints):
            raise FleetLayoutError(f"[track] joints must be 1-based integers; got {joints!r}.")
        clash = set(self.spring) & set(self.offset)
        if clash:
            raise FleetLayoutError(
                f"[track] offset on joints {sorted(clash)} repeats the preload of their spring; drop them from offset."
            )
        if self.payload_com is not None and len(self.payload_com) != 3:
            raise FleetLayoutError(f"[track] payload_com must be 3 numbers [m]; got {self.payload_com!r}.")


@dataclass(frozen=True)
class DayRecordings:
    """The recordings of one robot on one day (ISO date ``YYYY-MM-DD``)."""

    day: str
    paths: tuple


@dataclass(frozen=True)
class RobotEntry:
    """One robot: its id, its baseline file (calibrated model or robot file) and its recording days in order."""

    robot_id: str
    baseline: Path
    days: tuple

    @property
    def baseline_kind(self) -> str:
        """``"calibrated"`` for a calibrated-model file (.json), else ``"robot"``."""
        return "calibrated" if self.baseline.suffix == ".json" else "robot"


@dataclass(frozen=True)
class Fleet:
    """A parsed fleet: where it came from, its robots in id order, the tracked terms and the baseline window."""

    source: Path
    name: str
    robots: tuple
    track: TrackedTerms = TrackedTerms()
    baseline_days: int = 7

    @property
    def n_sessions(self) -> int:
        return sum(len(robot.days) for robot in self.robots)


def _day(text: str, where) -> str:
    try:
        return dt.date.fromisoformat(str(text)).isoformat()
    except ValueError:
        raise FleetLayoutError(f"{where}: {text!r} is not a date YYYY-MM-DD. {LAYOUT_FIX}") from None


def _is_recording(path: Path) -> bool:
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix.lower() in RECORDING_SUFFIXES and not path.name.startswith(".")


def _days_in(folder: Path) -> tuple:
    """The ``YYYY-MM-DD`` folders of a robot folder with their recordings, in date order."""
    if not folder.is_dir():
        raise FleetLayoutError(f"{folder}: no such recordings folder. {LAYOUT_FIX}")
    days = []
    for sub in sorted(p for p in folder.iterdir() if p.is_dir()):
        paths = tuple(sorted(str(p) for p in sub.iterdir() if _is_recording(p)))
        if not paths:
            continue
        days.append(DayRecordings(_day(sub.name, sub), paths))
    if not days:
        raise FleetLayoutError(
            f"{folder}: holds no YYYY-MM-DD folder with recordings {RECORDING_SUFFIXES}. {LAYOUT_FIX}"
        )
    return tuple(days)


def _baseline_in(folder: Path) -> Path:
    for name in BASELINE_NAMES:
        if (folder / name).is_file():
            return folder / name
    raise FleetLayoutError(f"{folder}: holds no baseline ({', '.join(BASELINE_NAMES)}). {LAYOUT_FIX}")


def _track(table: dict, where) -> TrackedTerms:
    unknown = set(table) - {"spring", "ripple", "offset", "payload_com"}
    if unknown:
        raise FleetLayoutError(
            f"{where} [track]: unknown keys {sorted(unknown)}; use spring, ripple, offset, payload_com."
        )
    try:
        ripple = tuple((int(j), int(h)) for j, h in table.get("ripple", ()))
        com = table.get("payload_com")
        return TrackedTerms(
            spring=tuple(int(j) for j in table.get("spring", ())),
            ripple=ripple,
            offset=tuple(int(j) for j in table.get("offset", ())),
            payload_com=None if com is None else tuple(float(c) for c in com),
        )
    except (TypeError, ValueError) as exc:
        raise FleetLayoutError(f"{where} [track]: {exc}; e.g. ripple = [[4, 12]], spring = [2].") from None


def _read_toml(path: Path) -> dict:
    try:
        return tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise FleetLayoutError(f"{path}: not a TOML file ({exc}). Fix the syntax.") from None


def _manifest_robot(entry: dict, root: Path, k: int) -> RobotEntry:
    where = f"{root} [[robot]] #{k + 1}"
    if not isinstance(entry, dict) or "id" not in entry:
        raise FleetLayoutError(f'{where}: needs id = "...". {LAYOUT_FIX}')
    base = entry.get("baseline") or entry.get("robot")
    if base is None:
        raise FleetLayoutError(f'{where}: needs baseline = "model.json" or robot = "robot.toml".')
    baseline = (root / base).resolve()
    if not baseline.is_file():
        raise FleetLayoutError(
            f"{where}: baseline file {baseline} does not exist. Fix the path (relative to the manifest)."
        )
    recordings = entry.get("recordings", str(entry["id"]))
    if isinstance(recordings, str):
        days = _days_in(root / recordings)
    else:
        by_day: dict = {}
        for item in recordings:
            path = root / str(item.get("path", ""))
            if not path.exists():
                raise FleetLayoutError(f"{where}: recording {path} does not exist. Fix the path.")
            by_day.setdefault(_day(item.get("day"), where), []).append(str(path))
        days = tuple(DayRecordings(d, tuple(sorted(p))) for d, p in sorted(by_day.items()))
    return RobotEntry(str(entry["id"]), baseline, days)


def _settings(document: dict, where) -> tuple:
    fleet = document.get("fleet", {})
    baseline_days = fleet.get("baseline_days", 7)
    if not (isinstance(baseline_days, int) and baseline_days >= 2):
        raise FleetLayoutError(f"{where} [fleet] baseline_days must be an integer >= 2; got {baseline_days!r}.")
    return str(fleet.get("name", "")), _track(document.get("track", {}), where), baseline_days


def read_fleet(path) -> Fleet:
    """The fleet of a folder or a TOML manifest (module docstring).

    Raises
    ------
    FleetLayoutError
        Naming the path and the fix: no robot folder, a robot without a baseline or without dated recordings, a
        folder name that is not a date, a manifest entry without id or with a missing file.
    """
    path = Path(path)
    if not path.exists():
        raise FleetLayoutError(f"{path}: no such fleet folder or manifest. {LAYOUT_FIX}")
    if path.is_file():
        document = _read_toml(path)
        name, track, baseline_days = _settings(document, path)
        entries = document.get("robot")
        if not entries:
            raise FleetLayoutError(f"{path}: the manifest lists no [[robot]]. {LAYOUT_FIX}")
        robots = [_manifest_robot(entry, path.parent, k) for k, entry in enumerate(entries)]
        name = name or path.stem
    else:
        settings = path / SETTINGS_FILE
        document = _read_toml(settings) if settings.is_file() else {}
        name, track, baseline_days = _settings(document, settings)
        folders = sorted(p for p in path.iterdir() if p.is_dir() and not p.name.startswith("."))
        if not folders:
            raise FleetLayoutError(f"{path}: holds no robot folder. {LAYOUT_FIX}")
        robots = [RobotEntry(f.name, _baseline_in(f), _days_in(f)) for f in folders]
        name = name or path.name
    ids = [r.robot_id for r in robots]
    if len(set(ids)) != len(ids):
        raise FleetLayoutError(f"{path}: robot ids must be unique; got {ids}.")
    return Fleet(path.resolve(), name, tuple(sorted(robots, key=lambda r: r.robot_id)), track, baseline_days)
