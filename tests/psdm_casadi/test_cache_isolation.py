"""The tests never touch the user's model cache: a module-scoped fixture (set up before any function-scoped one)
derives into a folder of the test session, and each test into its own (``tests/conftest.py``)."""

from __future__ import annotations

import platformdirs
import pytest

from psdm_casadi.model_cache import default_cache_folder, robot_cache_folder


@pytest.fixture(scope="module")
def module_cache():
    return default_cache_folder(), robot_cache_folder()


def test_a_module_fixture_derives_into_the_sessions_folder_not_the_users(module_cache, tmp_path_factory):
    models, robots = module_cache
    assert models.is_relative_to(tmp_path_factory.getbasetemp()) and robots == models / "robots"
    assert not models.is_relative_to(platformdirs.user_cache_dir("psdm-casadi"))


def test_each_test_derives_into_its_own_folder(module_cache, model_cache_folder):
    assert default_cache_folder() == model_cache_folder != module_cache[0]
