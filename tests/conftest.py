"""Shared fixtures: sample robots, derived models, a seeded rng, and paths to third-party data."""

from __future__ import annotations

import sysconfig
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
REFERENCE_PSDM = SHARED / "reference" / "psdm"
DATASETS = SHARED / "datasets"
DENSO_FILE = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"


@pytest.fixture
def benchmark_modules(monkeypatch):
    """``benchmarks/`` importable for this test (tests that run a benchmark's own case import its module)."""
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))


@pytest.fixture
def tx40_benchmark(benchmark_modules):
    """``benchmarks/real_data_diagnosis`` (the TX40's loader and splits); skipped without ../shared's TX40 recording."""
    if not (DATASETS / "staubli_tx40_figaroh").exists():
        pytest.skip("the TX40 recording (../shared/datasets/staubli_tx40_figaroh) is absent")
    import real_data_diagnosis

    return real_data_diagnosis


def example_robot_urdf(relative: str) -> Path:
    """A URDF from the example-robot-data wheel (cmeel prefix), or skip the test."""
    for base in {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}:
        path = Path(base) / "cmeel.prefix" / "share" / "example-robot-data" / "robots" / relative
        if path.exists():
            return path
    pytest.skip(f"example-robot-data URDF {relative} is not installed")


@pytest.fixture(scope="session", autouse=True)
def session_model_cache(tmp_path_factory):
    """The model cache of the session's module- and session-scoped fixtures (set up before any function-scoped
    fixture runs): they derive into an empty folder of the session, never the user's cache."""
    folder = tmp_path_factory.mktemp("psdm-session-model-cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PSDM_CACHE_DIR", str(folder))
        yield folder


@pytest.fixture(autouse=True)
def model_cache_folder(tmp_path_factory, monkeypatch):
    """Every test derives into its own empty model cache: none writes the user's cache or reads a warm one."""
    folder = tmp_path_factory.mktemp("psdm-model-cache")
    monkeypatch.setenv("PSDM_CACHE_DIR", str(folder))
    return folder


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="session")
def denso():
    return load_robot(DENSO_FILE)


@pytest.fixture(scope="session")
def denso_model(denso):
    return derive_psdm(denso)


@pytest.fixture(scope="session")
def denso_merged_rotors(denso):
    """(robot, model): the Denso with the rotor inertias of its file but a rigid-body model (no drive inertia in the
    derivation), as identify sees it on motor currents where the rotors merge into links (the merged-rotor tests)."""
    robot = replace(denso, drive_inertia=(False,) * denso.n_dof)
    return robot, derive_psdm(robot)


@pytest.fixture(scope="session")
def denso_functions(denso_model):
    from psdm_casadi.symbolic import build_functions

    return build_functions(denso_model)
