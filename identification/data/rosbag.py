"""Reading ``sensor_msgs/msg/JointState`` messages of a ROS 2 bag into a ColumnTable, with the ``rosbags`` package.

A bag is a folder with ``metadata.yaml`` (sqlite3 or mcap storage) or a single ``.mcap`` or ``.db3``
file; ROS itself is not needed. The topic is the one given, else the bag's only JointState topic
(several are refused, listing them). Columns:

- ``t`` [s] from each message's ``header.stamp``, or from the bag's log time when any stamp is zero,
  counted from the first message;
- ``q1..qn`` from ``position``, ``qd1..qdn`` from ``velocity`` when every message carries finite
  velocities, ``tau1..taun`` from ``effort`` (required in every message).

Joint ``j`` is found by name: with ``joint_names`` (the robot's, ``RobotDescription.joint_names``)
column ``q{j}`` holds the joint of that name wherever it sits in the message, and messages missing
one of them are skipped (a gripper publishing on the same topic); without it the first message's
order is kept. A message without names is taken in its own order.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from identification.data.table import ColumnTable
from psdm_casadi.errors import RecordingError

logger = logging.getLogger(__name__)

JOINT_STATE = "sensor_msgs/msg/JointState"
#: File suffixes read as a ROS 2 bag (besides a folder holding ``metadata.yaml``).
BAG_SUFFIXES = (".mcap", ".db3")


def is_rosbag(path) -> bool:
    """Whether ``path`` is a ROS 2 bag: a folder with ``metadata.yaml``, or a ``.mcap``/``.db3`` file."""
    path = Path(path)
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix.lower() in BAG_SUFFIXES


def _reader(path: Path):
    """A ``rosbags.highlevel.AnyReader`` of the bag (the ROS 2 Humble types stand in for a bag without definitions)."""
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise RecordingError(
            f"{path.name} is a ROS 2 bag, which needs the rosbags package. Install it: pip install rosbags."
        ) from None
    return AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))


def _joint_state_connections(source: str, reader, topic: str | None) -> tuple:
    """(topic, its connections): the requested JointState topic or the only one, else a refusal listing them."""
    types = {}
    for connection in reader.connections:
        types.setdefault(connection.topic, connection.msgtype)
    states = sorted(name for name, msgtype in types.items() if msgtype == JOINT_STATE)
    if topic is None:
        if not states:
            listing = ", ".join(f"{name} ({msgtype})" for name, msgtype in sorted(types.items())) or "none"
            raise RecordingError(
                f"{source}: holds no {JOINT_STATE} topic (topics: {listing}). Record the robot's joint states "
                "(ros2 bag record /joint_states)."
            )
        if len(states) > 1:
            raise RecordingError(
                f"{source}: holds {len(states)} {JOINT_STATE} topics ({', '.join(states)}). Choose one with "
                f"topic= (psdm: --topic {states[0]})."
            )
        topic = states[0]
    elif topic not in states:
        raise RecordingError(
            f"{source}: topic {topic!r} must be a {JOINT_STATE} topic of the bag; its JointState topics are "
            f"{', '.join(states) or 'none'}. Check the topic name."
        )
    return topic, [c for c in reader.connections if c.topic == topic]


def _read_messages(reader, connections) -> list:
    """(header stamp [ns], log time [ns], names, position, velocity, effort) of every message, in log-time order."""
    rows = []
    for connection, log_time, raw in reader.messages(connections=connections):
        msg = reader.deserialize(raw, connection.msgtype)
        stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
        rows.append((stamp, int(log_time), tuple(msg.name), msg.position, msg.velocity, msg.effort))
    return rows


def _column_index(names: tuple, size: int, wanted):
    """Indices of the wanted joints in a message, or None when one is missing.

    ``wanted`` is a tuple of joint names, or a count when the joints go by position (no names).
    """
    if isinstance(wanted, int) or not names:
        count = wanted if isinstance(wanted, int) else len(wanted)
        return np.arange(count) if size == count else None
    position = {name: k for k, name in enumerate(names)}
    if any(name not in position for name in wanted):
        return _prefixed_index(names, wanted)
    return np.array([position[name] for name in wanted], dtype=int)


def _prefixed_index(names, wanted) -> np.ndarray | None:
    """Joints named with a driver's prefix (``arm_joint1``, ``ur/shoulder_pan_joint`` for ``joint1``,
    ``shoulder_pan_joint``: a tf_prefix or namespace): each robot joint matched by the one message name that ends
    in it after ``_``, ``/`` or ``:``; None when a joint has no such name or several."""
    index = []
    for name in wanted:
        found = [k for k, n in enumerate(names) if n == name or n.endswith(("_" + name, "/" + name, ":" + name))]
        if len(found) != 1:
            return None
        index.append(found[0])
    return np.array(index, dtype=int) if len(set(index)) == len(index) else None


def _select(source: str, topic: str, rows: list, joint_names) -> tuple:
    """The kept messages with their joint indices, and the joint count; refuses a topic where none has every joint."""
    first_names, first_size = rows[0][2], len(rows[0][3])
    wanted = tuple(joint_names) if joint_names is not None else (first_names or first_size)
    kept, index_of = [], {}
    for row in rows:
        key = (row[2], len(row[3]))
        if key not in index_of:
            index_of[key] = _column_index(row[2], len(row[3]), wanted)
        if index_of[key] is not None:
            kept.append((row, index_of[key]))
    if not kept:
        missing = [name for name in wanted if name not in first_names] if first_names else list(wanted)
        listing = (
            f"its messages name {', '.join(first_names)}"
            if first_names
            else f"its messages carry no joint names and {first_size} positions"
        )
        raise RecordingError(
            f"{source}: topic {topic} must hold the robot's joints {', '.join(wanted)}; {', '.join(missing)} "
            f"{'is' if len(missing) == 1 else 'are'} missing ({listing}). Load it with the robot it was recorded "
            "on, with its joint names (a driver's prefix, arm_joint1 for joint1, is matched), or lock the joints the "
            "bag does not have (--lock)."
        )
    named = kept[0][0][2] if kept else ()
    if named and not isinstance(wanted, int) and any(named[k] != n for k, n in zip(kept[0][1], wanted)):
        pairs = ", ".join(f"{named[k]} as {n}" for k, n in zip(kept[0][1], wanted) if named[k] != n)
        logger.warning("%s: the joints of %s carry a prefix; read %s", source, topic, pairs)
    if len(kept) < len(rows):
        skipped = len(rows) - len(kept)
        logger.info("%s: %d of %d messages on %s lack a joint and are skipped", source, skipped, len(rows), topic)
    return kept, (wanted if isinstance(wanted, int) else len(wanted))


_FIELDS = {"position": (3, "joint positions [rad or m]"), "effort": (5, "joint torques [N m]"), "velocity": (4, "")}


def _signal(source: str, topic: str, kept: list, label: str, required: bool):
    """``(n_messages, n_dof)`` values of one JointState field (None when a message lacks the optional one)."""
    field, meaning = _FIELDS[label]
    values = []
    for number, (row, index) in enumerate(kept):
        data = row[field]
        if index.size and len(data) <= int(index.max()):
            if not required:
                logger.info("%s: JointState.%s missing from message %d of %s; not used", source, label, number, topic)
                return None
            raise RecordingError(
                f"{source}: JointState.{label} of topic {topic} must hold every joint in every message; message "
                f"{number} has {len(data)} values. Record the {meaning} of every joint."
            )
        values.append(np.asarray(data, dtype=float)[index])
    return np.array(values)


def _time(source: str, kept: list) -> np.ndarray:
    """Seconds from the first message: the header stamps, or the log times when a stamp is zero."""
    stamps = np.array([row[0] for row, _ in kept], dtype=np.int64)
    if np.any(stamps == 0):
        logger.info("%s: header stamps are zero; using the bag's log time", source)
        stamps = np.array([row[1] for row, _ in kept], dtype=np.int64)
    return (stamps - stamps[0]) * 1e-9


def read_rosbag_table(path, topic: str | None = None, joint_names=None) -> ColumnTable:
    """Read the JointState messages of a ROS 2 bag (folder, ``.mcap`` or ``.db3``) into a :class:`ColumnTable`.

    Parameters
    ----------
    path : str or Path
        A bag folder with ``metadata.yaml``, or a single ``.mcap`` or ``.db3`` file.
    topic : str, optional
        The JointState topic; by default the bag's only one.
    joint_names : sequence of str, optional
        The robot's joints in its order (``RobotDescription.joint_names``): column ``q{j}`` holds the
        joint named ``joint_names[j-1]``. By default the first message's order.

    Returns
    -------
    ColumnTable
        ``t``, ``q1..qn``, ``qd1..qdn`` (when recorded), ``tau1..taun``; rows located as ``message k``.

    Raises
    ------
    RecordingError
        Naming the bag and the fix: not a readable bag, no JointState topic (listing the topics),
        several without ``topic``, an unknown ``topic``, no message holding every joint of
        ``joint_names``, a message without efforts, NaN, infinite or implausibly large values.

    Examples
    --------
    >>> table = read_rosbag_table("run1", joint_names=robot.joint_names)   # doctest: +SKIP
    >>> table.names[:3]
    ('t', 'q1', 'q2')
    """
    path = Path(path)
    source = path.name
    try:
        with _reader(path) as reader:
            chosen, connections = _joint_state_connections(source, reader, topic)
            rows = _read_messages(reader, connections)
    except RecordingError:
        raise
    except Exception as exc:  # rosbags', sqlite's, the YAML parser's and the decoder's errors, with their own text
        raise RecordingError(f"{source}: not a readable ROS 2 bag ({exc}). Check that recording finished.") from None
    if not rows:
        raise RecordingError(f"{source}: topic {chosen} holds no messages. Record the robot's joint states.")
    kept, n = _select(source, chosen, rows, joint_names)
    q = _signal(source, chosen, kept, "position", required=True)
    qd = _signal(source, chosen, kept, "velocity", required=False)
    if qd is not None and not np.all(np.isfinite(qd)):
        logger.info("%s: JointState.velocity of %s holds non-finite values; it is not used", source, chosen)
        qd = None
    tau = _signal(source, chosen, kept, "effort", required=True)
    blocks, names = [_time(source, kept)[:, None], q], ["t"] + [f"q{j + 1}" for j in range(n)]
    if qd is not None:
        blocks.append(qd)
        names += [f"qd{j + 1}" for j in range(n)]
    blocks.append(tau)
    names += [f"tau{j + 1}" for j in range(n)]
    data = np.hstack(blocks)
    data.setflags(write=False)  # handed over to the table without a copy
    return ColumnTable(source=source, names=tuple(names), data=data, locate=lambda row: f"message {row} of {chosen}")
