"""Benchmarks that read third-party data take ``--data-root PATH`` instead of only ../shared beside the checkout."""

from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def benchmarks(benchmark_modules):
    import bench_support

    return bench_support


@pytest.mark.parametrize("script", ["real_identification", "tx40_motor_side", "real_data_diagnosis", "kinova_gen3"])
def test_an_empty_data_root_is_looked_in_and_named(benchmarks, script, tmp_path, capsys):
    import importlib

    module = importlib.import_module(script)
    argv = [str(tmp_path / "out")] if script == "real_data_diagnosis" else []
    code = module.main([*argv, "--data-root", str(tmp_path / "elsewhere"), "--json"])
    err = capsys.readouterr().err
    assert str(tmp_path / "elsewhere" / "datasets") in err and str(benchmarks.DEFAULT_DATA_ROOT) not in err
    assert code == (0 if script == "real_data_diagnosis" else 2)  # the diagnosis skips absent robots


def test_the_loaders_read_the_dataset_under_the_data_root(benchmarks, tmp_path):
    from real_data_diagnosis import PANDA, load_panda_real

    if not PANDA.exists():
        pytest.skip(f"dataset absent in {PANDA}")
    (tmp_path / "datasets").mkdir()
    (tmp_path / "datasets" / PANDA.name).symlink_to(PANDA, target_is_directory=True)
    moved = benchmarks.at_data_root(PANDA, tmp_path)
    assert moved == tmp_path / "datasets" / "panda_gaz2019"
    _, here = load_panda_real(moved)
    _, default = load_panda_real()
    np.testing.assert_array_equal(here.q, default.q)
    (tmp_path / "datasets" / PANDA.name).unlink()
    with pytest.raises(OSError):
        load_panda_real(moved)
