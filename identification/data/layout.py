"""Column layouts: which columns of a file are a recording's signals, and its time base, for logs as robots write them.

A recording file names its columns ``t, q1..qn, qd1..qdn, tau1..taun, i1..in`` (``io``). A controller's log
names them its own way and holds more: Kinova's Gen3 logs ``Time`` (a sample index, not seconds),
``Position1..7``, ``Velocity1..7``, a model torque ``Torque1..7``, the joint-torque sensors
``TorqueSm1..7``, ``Cur1..7`` and reference columns that hold NaN where the controller left them unset.
Which torque column is the measurement cannot be guessed from its name, so the user states it:

    --columns q=Position,tau=TorqueSm --rate 1000     (``ColumnLayout.parse``)

maps each signal to the prefix of its numbered columns and the time column to ``t`` [s] (a group numbered from 0,
as UR's RTDE logs ``actual_q_0..5``, is joints 1..n in that order); the joints' temperature columns
(``temperature.TEMPERATURE_COLUMN``: ``Temp1..7``) are read as ``temp1..tempn``; every other
column is left unread, so its NaN or text never blocks the file. ``--rate`` [Hz] (or the robot file's
``[recording].sample_rate``) gives the time base when the time column counts samples (0, 1, 2, ...) or
there is none; a column of times is kept as it is. Without a layout, a file whose
header has no ``q1`` but numbered groups of its own is refused with the groups it has and the
``--columns`` that reads it (:func:`check_standard_header`); a time column of row indices is refused
without ``--rate`` (:func:`seconds`).
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass

import numpy as np

from identification.data.temperature import TEMPERATURE_PREFIX, temperature_joints
from identification.data.units import PERCENT, si_factor
from psdm_casadi.errors import ParameterError, RecordingError

logger = logging.getLogger(__name__)

#: signal -> the standard column prefix (``io.COLUMN_PREFIXES``) and the time column's name.
SIGNAL_PREFIXES = {"q": "q", "qd": "qd", "qdd": "qdd", "tau": "tau", "i": "i"}
TIME = "t"
_POSITION = re.compile(r"^q[1-9][0-9]*$")
_NUMBERED = re.compile(r"^(.*?[^0-9])([0-9]+)$")
#: Fewest rows for a time column of consecutive integers to count as a sample index rather than seconds.
MIN_INDEX_ROWS = 20
#: [s] A first time stamp beyond this (about 3 years) is a wall clock (Unix time), not time from the start.
CLOCK_SECONDS = 1e8


@dataclass(frozen=True)
class ColumnLayout:
    """Which columns of a file hold which signal, and the time base.

    Parameters
    ----------
    prefixes : tuple of (str, str)
        ``(signal, prefix)`` pairs, signal among ``q, qd, qdd, tau, i``: columns ``<prefix>1..<prefix>n``
        hold that signal of joints 1..n. Must include ``q``; signals not named keep their standard names.
    time : str or None
        The time column (default ``t`` when the file has one).
    rate : float or None
        [Hz] Samples per second when the time column counts samples or there is none.
    units : tuple of (str, str)
        ``(signal, unit)`` pairs of signals the log does not hold in SI (``q=AxisPos_A:deg``): ``units.UNITS``.
    """

    prefixes: tuple = ()
    time: str | None = None
    rate: float | None = None
    units: tuple = ()

    def __post_init__(self):
        prefixes = tuple((str(s), str(p)) for s, p in self.prefixes)
        for signal, prefix in prefixes:
            if signal not in SIGNAL_PREFIXES:
                raise ParameterError(
                    f"--columns names signal {signal!r}; signals are t, {', '.join(SIGNAL_PREFIXES)}. "
                    "Write e.g. --columns q=Position,tau=TorqueSm."
                )
            if not prefix:
                raise ParameterError(f"--columns {signal}= needs a column prefix; e.g. {signal}=Position.")
        if len({s for s, _ in prefixes}) != len(prefixes):
            raise ParameterError(f"--columns names a signal twice: {prefixes}. Name each signal once.")
        if self.rate is not None and not (math.isfinite(self.rate) and self.rate > 0):
            raise ParameterError(f"--rate must be a sample rate > 0 [Hz]; got {self.rate!r}. Pass e.g. --rate 1000.")
        object.__setattr__(self, "prefixes", prefixes)
        units = tuple((str(s), str(u)) for s, u in self.units)
        for signal, unit in units:
            si_factor(signal, unit)  # refuses a unit that is not the signal's
        object.__setattr__(self, "units", units)

    @property
    def percent_current(self) -> bool:
        """Whether the currents are logged in per cent of each motor's rated current (``i=CurrAct_A:%``)."""
        return any(s == "i" and u.replace(" ", "") == PERCENT for s, u in self.units)

    @classmethod
    def parse(cls, text: str | None, rate: float | None = None) -> ColumnLayout | None:
        """The layout of ``--columns SIGNAL=PREFIX[:UNIT][,SIGNAL=PREFIX[:UNIT]...]`` (``t=NAME`` names the time
        column; ``:deg``, ``:mNm``, ``:ms``... state a unit other than SI)."""
        if text is None and rate is None:
            return None
        prefixes, time, units = [], None, []
        for item in (text or "").replace(" ", ",").split(","):
            if not item:
                continue
            signal, sep, prefix = item.partition("=")
            if not sep:
                raise ParameterError(
                    f"--columns items must be SIGNAL=PREFIX; got {item!r}. Write e.g. "
                    "--columns q=Position,tau=TorqueSm."
                )
            prefix, colon, unit = prefix.partition(":")
            if colon:
                units.append((signal.strip(), unit.strip()))
            if signal.strip() == TIME:
                time = prefix.strip()
            else:
                prefixes.append((signal.strip(), prefix.strip()))
        return cls(prefixes=tuple(prefixes), time=time, rate=rate, units=tuple(units))

    def columns(self, source: str, names: tuple) -> dict:
        """``{file column: standard name}`` of the columns this layout reads from a file with header ``names``.

        Raises
        ------
        RecordingError
            When a stated prefix or time column is not in the file (naming the groups it has); a file of a
            controller's own column groups read without a q prefix (``--rate`` alone) is refused as
            :func:`check_standard_header` refuses it, naming all its groups, not only those this layout would read.
        """
        if "q" not in dict(self.prefixes):
            check_standard_header(source, names)
        chosen = dict(self.prefixes)
        chosen.setdefault("q", "q")
        mapping = {}
        for signal, prefix in chosen.items():
            found = {int(m.group(2)): n for n in names if (m := _NUMBERED.match(n)) and m.group(1) == prefix}
            if 0 in found:  # numbered from 0 (actual_q_0..5): joint k + 1
                found = {k + 1: n for k, n in found.items()}
            if not found and prefix != SIGNAL_PREFIXES[signal]:
                raise RecordingError(
                    f"{source}: --columns {signal}={prefix} names no column of the file (no {prefix}1, {prefix}2, "
                    f"...); its numbered columns are {numbered_groups(names) or 'none'}. Check the prefix."
                )
            mapping.update({name: f"{SIGNAL_PREFIXES[signal]}{k}" for k, name in found.items()})
        for signal in SIGNAL_PREFIXES:  # signals the layout does not name keep their standard columns
            if signal not in chosen:
                mapping.update({n: n for n in names if re.fullmatch(rf"{signal}[1-9][0-9]*", n)})
        temperatures = temperature_joints(names)  # kept with the recording: NaN-tolerant, never a fitted signal
        mapping.update({name: f"{TEMPERATURE_PREFIX}{joint}" for name, joint in temperatures.items()})
        time = self.time or (TIME if TIME in names else _time_named(source, names))
        if time is not None and time not in names:
            raise RecordingError(f"{source}: --columns t={time} names no column of the file. Check the name.")
        if time is None and self.rate is None:
            raise RecordingError(
                f"{source}: no time column t. Name it (--columns t=NAME) or state the sample rate (--rate HZ)."
            )
        return {**({time: TIME} if time else {}), **mapping}


#: Names a file gives its time column (compared in lower case), read as ``t`` when the file has no ``t``.
TIME_NAMES = ("time", "timestamp", "stamp", "times", "time_s", "t_s", "sec", "seconds")


def _time_named(source: str, names) -> str | None:
    """The file's one time-like column (``time``, ``Timestamp``, ...) when ``--columns`` names none, or None: a
    layout that states the signals' groups only still reads the file's own clock, as the standard layout does."""
    found = [n for n in names if n.lower() in TIME_NAMES]
    if len(found) != 1:
        return None
    logger.info("%s: column %s read as the time t [s]", source, found[0])
    return found[0]


def model_file_layout(document) -> ColumnLayout | None:
    """The layout identify read a model file's recordings with (its ``provenance.columns``: ``--columns`` and
    ``--rate``), so every later command reads them alike; None for the standard columns (older files store none)."""
    stored = (document or {}).get("provenance", {}).get("columns")
    return ColumnLayout.parse(stored.get("columns"), stored.get("rate")) if stored else None


def _groups(names) -> dict:
    """``{prefix: [joint numbers]}`` of the numbered columns among ``names``, in file order."""
    groups: dict = {}
    for name in names:
        if m := _NUMBERED.match(name):
            groups.setdefault(m.group(1), []).append(int(m.group(2)))
    return groups


def numbered_groups(names) -> str:
    """The file's numbered column groups as ``Position1..7, Cur1..7`` (for messages)."""
    return ", ".join(f"{p}{min(k)}..{max(k)}" if len(k) > 1 else f"{p}{k[0]}" for p, k in _groups(names).items())


#: Words in a numbered group's name (lower case) that say it holds positions, torques, or a motor's signal.
POSITION_WORDS, TORQUE_WORDS, MOTOR_WORDS = ("pos", "angle"), ("tau", "torque", "effort", "trq"), ("motor", "mot_")


def _is_position(group: str) -> bool:
    """Positions: ``q``, ``Position``, ``joint_pos_``, ``motor_pos_``, ``actual_q_``, ``AxisAngle``."""
    g = group.lower()
    return (g.startswith("q") and not g.startswith("qd")) or g.endswith("_q_") or any(w in g for w in POSITION_WORDS)


def _is_motor(group: str) -> bool:
    return any(w in group.lower() for w in MOTOR_WORDS)


def _example(groups, time) -> str:
    """A ``--columns`` value built from the file's own groups: its likeliest position group (the joint side's; a
    motor-side one where the file has none, ``motor_note``) and torque group."""
    positions = [g for g in groups if _is_position(g)]
    joint = [g for g in positions if not _is_motor(g)]
    torque = [g for g in groups if any(w in g.lower() for w in TORQUE_WORDS)]
    torque = [g for g in torque if not _is_motor(g)] or torque
    items = [f"t={time}"] if time and time != TIME else []
    tau = torque[0] if len(torque) == 1 else f"<one of {', '.join(torque)}>" if torque else "<torque group>"
    items += [f"q={(joint or positions or ['<position group>'])[0]}", f"tau={tau}"]
    return ",".join(items)


def motor_note(groups) -> str:
    """The sentence on a file's motor-side position groups (``motor_pos_1..6``; empty: none): read as ``q`` only
    with the robot file's ``[recording] side`` and ``[transmission]`` (``motor_side.to_joint_side``), which map
    encoder angles before the gear to the joint side; left unread where the file has joint positions too."""
    motor = [g for g in groups if _is_position(g) and _is_motor(g)]
    if not motor:
        return ""
    joint = [g for g in groups if _is_position(g) and not _is_motor(g)]
    names = ", ".join(f"{g}1.." for g in motor)
    how = ('with the robot file\'s [recording] side = { q = "motor" } and its [transmission] gear_ratios (and '
           "joint_offsets), which map them to the joint side")  # fmt: skip
    if joint:
        return (f" {names} hold motor-side positions (before the gear) and are left unread; to read them instead of "
                f"{joint[0]}: q={motor[0]} {how}.")  # fmt: skip
    return f" {names} hold motor-side positions (before the gear): read them as q={motor[0]} {how}."


#: Where currents' torque constants go, for a file read without a robot (``UnreadColumnGroups.naming`` says where
#: the robot file at hand states them).
TORQUE_CONSTANTS = (
    "with torque constants in the robot file ([[drive]] kt at the joint, or [transmission] motor_kt with gear_ratios)"
)


class UnreadColumnGroups(RecordingError):
    """:func:`check_standard_header`'s refusal. ``naming(constants)`` is the same refusal naming where the robot file
    at hand states its torque constants (``robot_recordings`` knows the robot; the readers do not)."""

    def __init__(self, source: str, names, because: str = "", constants: str = TORQUE_CONSTANTS):
        self.source, self.names, self.because = source, tuple(names), because
        groups = _groups(n for n in self.names if n != TIME)
        time = next((n for n in self.names if n.lower() in ("t", "time", "timestamp", "stamp")), None)
        super().__init__(
            f"{source}: the columns are not t, q1..qn, tau1..taun or i1..in; the file has {numbered_groups(self.names)}"
            + (f" and {time}" if time else "")
            + f". Say which group is which signal, e.g. --columns {_example(groups, time)} (the torque group that is "
            f"measured, not a model's or a reference's; or i=<current group> for motor currents, {constants}); add "
            "--rate HZ when the time column counts samples. The other columns are then not read"
            + (f" (as it is: {because})." if because else ".")
            + motor_note(groups)
        )

    def naming(self, constants: str) -> UnreadColumnGroups:
        """The refusal with ``constants`` (e.g. "with the torque constants of the robot file's [transmission]
        motor_kt") in place of the general wording."""
        return UnreadColumnGroups(self.source, self.names, self.because, constants)


def check_standard_header(source: str, names, because: str = "") -> None:
    """Refuse a header without ``q1`` whose columns come in numbered groups of other names, naming the fix.

    A controller's log (``Position1..7``, ``TorqueSm1..7``, ...) is read with ``--columns``; which of its torque-like
    groups is the measurement is the user's to say; a motor-side position group (``motor_pos_1..6``) is named as such,
    with the robot file's ``[recording] side`` that reads it (``motor_note``). Files with ``q1`` (or only standard names
    in any case, which ``io`` explains) are left to ``io``; a file of standard torques beside positions of other names
    (``tau1..6``, ``motor_pos_1..6``) is refused here, naming its position group. ``because`` (a refused value of a
    column the layout would leave unread) is quoted. Raises :class:`UnreadColumnGroups`.
    """
    names = tuple(names)
    groups = _groups(n for n in names if n != TIME)
    if not groups or any(_POSITION.match(n) for n in names) or all(g.lower() in SIGNAL_PREFIXES for g in groups):
        return
    raise UnreadColumnGroups(source, names, because)


def seconds(source: str, t: np.ndarray, rate: float | None) -> np.ndarray:
    """The time column in seconds (a new array): a sample index divided by ``rate`` [Hz], times as they are.

    Wall-clock stamps (Unix time, as RTDE, ROS and most loggers write) become seconds from the first sample,
    as a bag's header stamps do: terms of time (a friction warm-up ``t sign(qd)``, ``1 - exp(-t / T)``) are
    otherwise a constant of 1.7e9 that the Coulomb friction absorbs, and reports quote times of ten digits.

    Raises
    ------
    RecordingError
        When the column counts samples (at least ``MIN_INDEX_ROWS`` consecutive integers) and no rate is stated.
    """
    t = np.array(t, dtype=float)
    if t.size and np.isfinite(t[0]) and t[0] > CLOCK_SECONDS:
        logger.info("%s: the time column is a wall clock (first stamp %.6f s); times from its first sample", source,
                    t[0])  # fmt: skip
        return t - t[0]
    index = t.size >= MIN_INDEX_ROWS and bool(np.all(t == np.round(t)) and np.all(np.diff(t) == 1.0))
    if not index:
        return t
    if rate is None:
        raise RecordingError(
            f"{source}: the time column counts samples ({t[0]:g}, {t[1]:g}, {t[2]:g}, ..., {t[-1]:g}), not "
            "seconds. State the sample rate: --rate HZ (e.g. --rate 1000 for a 1 kHz log), or sample_rate = HZ in "
            "the robot file's [recording] table."
        )
    return t / rate
