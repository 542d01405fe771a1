"""The model cache: a cached model computes what a fresh derivation computes, is read without deriving, is keyed
by the robot's content, survives a corrupt entry, an unwritable folder and two writers at once."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import psdm_casadi.model_cache as model_cache
from psdm_casadi.cli import main
from psdm_casadi.derive import DeriveOptions, derive_psdm
from psdm_casadi.errors import ParameterError
from psdm_casadi.model import load_model
from psdm_casadi.model_cache import ModelCache, default_cache_folder, model_key
from psdm_casadi.robot import from_dh, load_robot
from psdm_casadi.robot_writer import write_robot_file
from tests.conftest import example_robot_urdf

ROOT = Path(__file__).resolve().parents[2]
PANDA = "panda_description/urdf/panda.urdf"


def small_robot(a2=0.3):
    return from_dh([(0.0, np.pi / 2, 0.3, 0.0), (a2, 0.0, 0.0, 0.0), (0.2, 0.0, 0.0, 0.0)], name="arm3")


@pytest.fixture
def derivations(monkeypatch):
    """Count the derivations the cache runs."""
    calls = []

    def counted(robot, options=None):
        calls.append(robot.name)
        return derive_psdm(robot, options)

    monkeypatch.setattr(model_cache, "derive_psdm", counted)
    return calls


def test_cached_model_computes_what_a_fresh_derivation_computes(tmp_path, derivations):
    robot = load_robot("denso_vs6556g")
    cache = ModelCache(tmp_path)
    first = cache.derive(robot)
    second = cache.derive(robot)
    assert derivations == [robot.name]  # the second call read the entry
    fresh = derive_psdm(robot)
    rng = np.random.default_rng(7)
    q, qd, qdd = (rng.uniform(-2, 2, size=(20, robot.n_dof)) for _ in range(3))
    theta = rng.normal(size=fresh.n_base)
    for model in (first, second):
        np.testing.assert_allclose(model.regressor(q, qd, qdd), fresh.regressor(q, qd, qdd), rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(
            model.inverse_dynamics(q, qd, qdd, theta), fresh.inverse_dynamics(q, qd, qdd, theta), rtol=1e-12
        )
    assert second.base_names == fresh.base_names and second.robot_name == robot.name


def test_default_folder_follows_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("PSDM_CACHE_DIR", str(tmp_path / "here"))
    assert default_cache_folder() == tmp_path / "here"
    assert ModelCache().folder == tmp_path / "here"
    monkeypatch.delenv("PSDM_CACHE_DIR")
    assert default_cache_folder().parts[-2:] == ("psdm-casadi", "models")


def test_key_follows_the_robot_content_the_lock_and_the_options(tmp_path):
    urdf = example_robot_urdf(PANDA)
    fingers = ["panda_finger_joint1", "panda_finger_joint2"]
    free = load_robot(urdf)
    locked = load_robot(urdf, locked_joints=fingers)
    other_value = load_robot(urdf, locked_joints={"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.0})
    keys = {model_key(r) for r in (free, locked, other_value)}
    assert len(keys) == 3
    assert model_key(locked) == model_key(load_robot(urdf, locked_joints=fingers))
    # the same URDF name with other content (a link mass edited) is another key
    copy = tmp_path / "panda.urdf"
    text = urdf.read_text()
    copy.write_text(text)
    same = load_robot(copy, locked_joints=fingers)
    edited_text = text.replace('<mass value="4.970684"/>', '<mass value="5.0"/>', 1)
    assert edited_text != text
    copy.write_text(edited_text)
    edited = load_robot(copy, locked_joints=fingers)
    assert model_key(same) != model_key(edited)
    assert model_key(small_robot()) != model_key(small_robot(a2=0.31))
    assert model_key(small_robot()) != model_key(small_robot(), DeriveOptions(seed=1))


def test_corrupt_entry_is_logged_and_derived_again(tmp_path, derivations, caplog):
    robot = small_robot()
    cache = ModelCache(tmp_path)
    entry = cache.path(model_key(robot))
    for damage in (b"not a zip file", None):
        cache.derive(robot)
        entry.write_bytes(damage if damage is not None else entry.read_bytes()[:200])  # garbage, then truncated
        with caplog.at_level(logging.WARNING, logger="psdm_casadi.model_cache"):
            model = cache.derive(robot)
        assert "unreadable model cache entry" in caplog.text
        caplog.clear()
        assert load_model(entry) == model  # rebuilt whole
    assert len(derivations) == 3  # the first, then one rebuild per damage


def test_unwritable_folder_derives_without_caching(tmp_path, derivations, caplog):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    cache = ModelCache(blocker / "models")  # a folder that cannot be made (works as root too)
    with caplog.at_level(logging.WARNING, logger="psdm_casadi.model_cache"):
        model = cache.derive(small_robot())
    assert model.n_dof == 3 and "could not write the model cache" in caplog.text
    ModelCache(tmp_path, enabled=False).derive(small_robot())
    assert len(derivations) == 2 and not list(tmp_path.glob("*.npz"))


def test_cli_second_command_reads_the_cache_and_no_cache_derives(tmp_path, derivations, capsys):
    robot_file = write_robot_file(small_robot(), tmp_path / "arm3.toml")
    assert main(["derive", str(robot_file), "--json"]) == 0
    assert main(["derive", str(robot_file), "--json"]) == 0
    assert len(derivations) == 1
    assert main(["--no-cache", "derive", str(robot_file), "--json"]) == 0
    assert len(derivations) == 2
    assert len(list(Path(os.environ["PSDM_CACHE_DIR"]).glob("*.npz"))) == 1


def test_two_processes_writing_at_once_leave_a_valid_entry(tmp_path):
    robot_file = write_robot_file(small_robot(), tmp_path / "arm3.toml")
    folder = tmp_path / "cache"
    env = {**os.environ, "PSDM_CACHE_DIR": str(folder), "PYTHONPATH": str(ROOT)}
    command = [sys.executable, "-c", "import sys; from psdm_casadi.cli import main; sys.exit(main())"]
    runs = [subprocess.Popen([*command[:3], "derive", str(robot_file)], env=env) for _ in range(2)]
    assert [run.wait(timeout=120) for run in runs] == [0, 0]
    entries = sorted(p.name for p in folder.iterdir())
    assert len(entries) == 1 and entries[0].endswith(".npz")  # no temporary file left
    assert load_model(folder / entries[0]) == derive_psdm(load_robot(robot_file))


def test_the_least_recently_used_entries_beyond_the_limit_are_removed(tmp_path, derivations):
    import os
    import time

    cache = ModelCache(tmp_path, max_entries=2)
    robots = [small_robot(a2) for a2 in (0.30, 0.31, 0.32)]
    first, second, third = (cache.path(model_key(r)) for r in robots)
    cache.derive(robots[0])
    cache.derive(robots[1])
    os.utime(first, (time.time() - 100, time.time() - 100))
    os.utime(second, (time.time() - 50, time.time() - 50))
    cache.derive(robots[0])  # read: now the most recently used
    cache.derive(robots[2])  # written: the oldest (robot 2) goes
    assert first.exists() and third.exists() and not second.exists()
    assert len(derivations) == 3
    assert load_model(first).parameter_map.shape[1] == 33  # entries are whole, compressed npz files
    with pytest.raises(ParameterError, match="max_entries"):
        ModelCache(tmp_path, max_entries=0)
