"""The bad-input catalogue for the recording formats users have (ROS 2 bags, MATLAB files), through ``psdm``.

Every case runs ``psdm diagnose denso_vs6556g --train X --validate validate.csv``, which reads both
recordings, joint names matched to the robot's (J1..J6), before it derives anything. A bag is written
into the case's folder with rosbags' writer before the run. Each refusal must exit with 2, print no
traceback, name the recording and the fix, and leave every file as it was.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest
from scipy.io import savemat

from tests.catalogue.harness import BadInput, check_refusal
from tests.catalogue.test_bad_recordings import GOOD
from tests.identification.recording_formats import joint_state_bag, matlab_v73_bytes, smooth_signals

DENSO = tuple(f"J{j}" for j in range(1, 7))


def diagnose(name: str, train: str, *expect, options=()) -> BadInput:
    return BadInput(
        name,
        ("diagnose", "denso_vs6556g", "--train", train, "--validate", "validate.csv", *options),
        expect=(train, *expect),
        files={"validate.csv": GOOD},
    )


def bag(**options):
    """A builder writing ``train_bag`` in the case's folder (joint_state_bag's options; J1..J6 by default)."""
    names = options.pop("names", DENSO)

    def build(folder):
        joint_state_bag(folder / "train_bag", names, smooth_signals(names), **options)

    return build


def mat(content):
    """A builder writing ``train.mat`` from ``content(t, q, tau)``."""

    def build(folder):
        n = 40
        t = np.arange(n) / 100.0
        q, tau = np.sin(np.outer(t, np.arange(1, 7))), np.ones((n, 6))
        savemat(folder / "train.mat", content(t, q, tau))

    return build


CASES = [
    (
        diagnose("bag without a JointState topic", "train_bag", "no sensor_msgs/msg/JointState topic", "/tool/force"),
        bag(topics=(), extra_topic="/tool/force"),
    ),
    (
        diagnose("bag with two JointState topics", "train_bag", "2 sensor_msgs/msg/JointState topics", "--topic"),
        bag(topics=("/arm/joint_states", "/joint_states")),
    ),
    (
        diagnose("unknown --topic", "train_bag", "'/nope'", "/joint_states", options=("--topic", "/nope")),
        bag(),
    ),
    (
        diagnose("bag joint names not the robot's", "train_bag", "J1", "missing", "joint_1", "--lock"),
        bag(names=tuple(f"joint_{j}" for j in range(1, 7))),
    ),
    (diagnose("bag without efforts", "train_bag", "JointState.effort", "torques"), bag(effort=False)),
    (
        diagnose("not an mcap file", "train.mcap", "not a readable ROS 2 bag"),
        lambda folder: (folder / "train.mcap").write_text(GOOD),
    ),
    (
        diagnose("MATLAB matrix with one joint per row", "train.mat", "(6, 40)", "transpose"),
        mat(lambda t, q, tau: {"t": t, "q": q.T, "tau": tau}),
    ),
    (
        diagnose("MATLAB struct", "train.mat", "'tau' is a struct", "save"),
        mat(lambda t, q, tau: {"t": t, "q": q, "tau": {"values": tau}}),
    ),
    (
        diagnose("MATLAB layouts mixed", "train.mat", "matrix variables", "one layout"),
        mat(lambda t, q, tau: {"t": t, "q": q, **{f"tau{j + 1}": tau[:, j] for j in range(6)}}),
    ),
    (
        diagnose("MATLAB v7.3 without h5py", "train.mat", "v7.3", "h5py", "-v7"),
        lambda folder: (folder / "train.mat").write_bytes(matlab_v73_bytes()),
    ),
]


@pytest.mark.parametrize("case, build", CASES, ids=[case.name for case, _ in CASES])
def test_refused(case, build, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "h5py", None)  # v7.3 is refused the same where h5py is installed
    build(tmp_path)
    check_refusal(case, tmp_path, capsys, monkeypatch)
