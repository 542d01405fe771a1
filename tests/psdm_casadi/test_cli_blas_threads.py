"""A psdm command runs with one BLAS thread unless the user chose a number (psdm_casadi.cli.blas_threads)."""

import json

import pytest
from threadpoolctl import threadpool_info

from psdm_casadi.cli.blas_threads import blas_thread_limit


def blas_threads() -> list:
    return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]


def test_one_blas_thread_by_default_and_restored_after():
    before = blas_threads()
    if not before:
        pytest.skip("numpy reports no BLAS thread pool")
    with blas_thread_limit(environ={}):
        assert set(blas_threads()) == {1}
    assert blas_threads() == before


@pytest.mark.parametrize("variable", ["OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"])
def test_a_thread_count_the_user_set_is_left_alone(variable):
    before = blas_threads()
    with blas_thread_limit(environ={variable: "2"}):
        assert blas_threads() == before


def test_the_command_line_runs_its_handler_inside_the_limit(monkeypatch, capsys):
    # `psdm derive --json` on the built-in SCARA: the handler sees one BLAS thread.
    import psdm_casadi.cli.derive as derive_command

    for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(variable, raising=False)
    seen, original = [], derive_command.run_derive

    def observing(args):
        seen.append(blas_threads())
        return original(args)

    monkeypatch.setattr(derive_command, "run_derive", observing)
    from psdm_casadi.cli import main

    assert main(["--no-cache", "derive", "scara", "--json"]) == 0
    json.loads(capsys.readouterr().out)
    assert seen and set(seen[0]) <= {1}
