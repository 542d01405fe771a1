"""Recordings written in the formats users have: ROS 2 bags of JointState messages (rosbags' writer) and MATLAB files.

Shared by ``test_recording_formats.py`` and the bad-input catalogue. The bag helpers need the
``rosbags`` package (a dependency of the project); ROS itself is not needed.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

JOINT_STATE = "sensor_msgs/msg/JointState"


def smooth_signals(names, n_samples: int = 40, rate: float = 100.0) -> dict:
    """Known joint signals by joint name: ``t`` [s] and per joint (position, velocity, effort) arrays."""
    t = np.arange(n_samples) / rate
    signals = {"t": t}
    for k, name in enumerate(names):
        w = 1.0 + 0.5 * k
        signals[name] = (0.1 * (k + 1) * np.sin(w * t), 0.1 * (k + 1) * w * np.cos(w * t), 1.0 + k + 0.01 * t)
    return signals


def joint_state_bag(
    path: Path,
    names,
    signals: dict,
    storage: str = "sqlite3",
    topics=("/joint_states",),
    shuffle_seed: int | None = 0,
    stamps: bool = True,
    velocity: bool = True,
    effort: bool = True,
    extra_topic: str | None = None,
) -> Path:
    """Write a ROS 2 bag folder at ``path``: JointState messages of ``signals`` on each of ``topics``.

    ``shuffle_seed`` shuffles the joint order of every message (None keeps ``names``' order);
    ``stamps=False`` leaves the header stamps zero (the log time then counts); ``extra_topic`` adds a
    ``std_msgs/msg/Float64`` topic.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    joint_state, header, time = (
        types[JOINT_STATE],
        types["std_msgs/msg/Header"],
        types["builtin_interfaces/msg/Time"],
    )
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    rng = np.random.default_rng(shuffle_seed) if shuffle_seed is not None else None
    t = signals["t"]
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        connections = [writer.add_connection(topic, JOINT_STATE, typestore=store) for topic in topics]
        if extra_topic is not None:
            other = writer.add_connection(extra_topic, "std_msgs/msg/Float64", typestore=store)
            data = store.serialize_cdr(types["std_msgs/msg/Float64"](data=1.0), "std_msgs/msg/Float64")
            writer.write(other, 1_000, data)
        for k, seconds in enumerate(t):
            order = list(rng.permutation(len(names))) if rng is not None else list(range(len(names)))
            ordered = [names[j] for j in order]
            stamp_ns = 1_700_000_000_000_000_000 + int(round(seconds * 1e9))
            stamp = time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000) if stamps else time(0, 0)
            message = joint_state(
                header=header(stamp=stamp, frame_id=""),
                name=ordered,
                position=np.array([signals[n][0][k] for n in ordered]),
                velocity=np.array([signals[n][1][k] for n in ordered]) if velocity else np.array([], dtype=float),
                effort=np.array([signals[n][2][k] for n in ordered]) if effort else np.array([], dtype=float),
            )
            raw = store.serialize_cdr(message, JOINT_STATE)
            log_ns = 2_000_000_000 + int(round(seconds * 1e9)) + 5_000  # the recorder's clock: later, offset
            for connection in connections:
                writer.write(connection, log_ns, raw)
    return path


def mcap_file(folder: Path, target: Path) -> Path:
    """The ``.mcap`` file of an mcap bag folder, copied to ``target`` (a single file, as users share them)."""
    (source,) = sorted(Path(folder).glob("*.mcap"))
    shutil.copyfile(source, target)
    return target


def matlab_v73_bytes() -> bytes:
    """The first bytes of a MATLAB v7.3 file: the 128-byte MATLAB header (version 0x0200) and HDF5's signature."""
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    header = text.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM"
    return header.ljust(512, b"\x00") + b"\x89HDF\r\n\x1a\n" + b"\x00" * 64
