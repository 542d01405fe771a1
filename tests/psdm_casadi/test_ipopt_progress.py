"""Ipopt's iterations as a progress bar (``psdm_casadi.ipopt_progress``): one step per iteration on a terminal, the
objective and the primal infeasibility in its postfix, nothing in a file, a pipe or ``--json`` mode.

The reference is Ipopt's own iteration count (``solver.stats()["iter_count"]``; its intermediate callback is
also called once for the starting point).
"""

from __future__ import annotations

import io
import logging

import casadi as ca
import numpy as np
import pytest

from psdm_casadi.ipopt_progress import progress_options
from tests.psdm_casadi.progress_terminal import PACKAGES, FakeTerminal, install_counting_handler


@pytest.fixture
def logger():
    saved = {name: (logging.getLogger(name).handlers[:], logging.getLogger(name).level,
                    logging.getLogger(name).propagate) for name in PACKAGES}  # fmt: skip
    yield logging.getLogger("identification.test_ipopt_progress")
    for name, (handlers, level, propagate) in saved.items():
        parent = logging.getLogger(name)
        parent.handlers[:], parent.level, parent.propagate = handlers, level, propagate


def _solve(logger):
    """Rosenbrock's valley with a circle constraint: a few dozen Ipopt iterations."""
    x = ca.SX.sym("x", 2)
    problem = {"x": x, "f": (1 - x[0]) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2, "g": x[0] ** 2 + x[1] ** 2}
    bar, callback = progress_options("test_progress", (2, 1, 0), 200, "test: Ipopt", logger, -np.inf, 1.5)
    solver = ca.nlpsol("test", "ipopt", problem, {"ipopt.print_level": 0, "print_time": False,
                                                  "ipopt.max_iter": 200, **bar})  # fmt: skip
    solver(x0=[-1.2, 1.0], lbg=-np.inf, ubg=1.5)
    if callback is not None:
        callback.close()
    return solver.stats()["iter_count"], callback


def test_the_bar_advances_once_per_iteration_on_a_terminal(logger):
    stream = FakeTerminal()
    handler = install_counting_handler(stream)
    iterations, callback = _solve(logger)
    assert callback is not None and iterations > 10
    steps = handler.counts[:-1]  # the last record ends the bar
    assert steps == list(range(1, iterations + 2))  # Ipopt's iterations and its starting point, one step each
    assert handler.counts[-1] is None and handler._inner is None
    text = stream.getvalue()  # drawn at most ten times a second: the description and the cap at least
    assert "test: Ipopt" in text and "/200" in text
    assert all(p.startswith("obj ") and ", inf_pr " in p for p in handler.postfixes[:-1])
    assert callback.seconds >= 0


def test_inside_a_loop_the_solve_draws_a_second_bar_and_leaves_the_loops(logger):
    handler = install_counting_handler(FakeTerminal())
    logger.info("test: joint 1 of 3", extra={"progress": (1, 3)})
    outer = handler._bar
    iterations, _ = _solve(logger)
    assert handler._bar is outer and outer.n == 1 and handler._inner is None  # the loop's bar stays, at its count
    assert handler.counts[1:-1] == list(range(1, iterations + 2))


@pytest.mark.parametrize("stream, level", [(io.StringIO(), logging.INFO), (FakeTerminal(), logging.WARNING)],
                         ids=["not a terminal", "--json or --quiet"])  # fmt: skip
def test_nothing_is_drawn_or_paid_elsewhere(logger, stream, level):
    install_counting_handler(stream, level)
    iterations, callback = _solve(logger)
    assert iterations > 10 and callback is None and stream.getvalue() == ""


def test_the_consistent_fit_shows_its_iterations(logger, denso, denso_model):
    from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
    from tests.identification.diagnosis_data import rigid_recording

    stream = FakeTerminal()
    install_counting_handler(stream)
    identify_trajectories(denso, denso_model, [rigid_recording(denso, [])], TrajectoryOptions())
    assert "identify: consistent fit (Ipopt)" in stream.getvalue()


def test_the_lugre_fit_shows_its_iterations(logger):
    from identification.friction.shooting import fit_lugre_multiple_shooting
    from identification.friction.simulation import simulate_lugre
    from tests.identification.friction_signal import denso_truth, sine_series

    handler = install_counting_handler(FakeTerminal())
    truth, qd_max = denso_truth(3)
    t, qd = sine_series(truth, qd_max, frequency_scale=2.0)
    tau, _ = simulate_lugre(truth, t, qd)
    start = truth.as_array() * np.array([1.1, 0.9, 1.3, 0.95, 1.05, 0.6, 2.0])
    fit_lugre_multiple_shooting(t, qd, tau, type(truth).from_array(start))
    assert "LuGre friction fit (Ipopt)" in handler.stream.getvalue() and max(c or 0 for c in handler.counts) >= 1
    assert handler._inner is None
