"""Which progress lines a context lets through (``psdm_casadi.log_context``), the one way the LuGre trial
(``lugre_trial.quiet_trial``) and diagnose's load check (``cli.diagnose_loads``) hold back a fit's lines.

References: a real fit (``trajectory_fit.identify_trajectories``, the Denso on a 3 s synthetic recording) logs its
preparation line outside the context and none inside it, on the command line's handler and on the root's (a library
user's); a thread that logs while another holds its lines back is shown (the state is the thread's, not the
logger's); a trial's Python warnings are recorded and yielded, not shown, and its warnings through logging pass.
"""

from __future__ import annotations

import logging
import threading
import warnings

import pytest

from identification.calibration.lugre_trial import quiet_trial
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from psdm_casadi.cli.output import configure_logging, remove_logging
from psdm_casadi.log_context import ONCE, held_back, once_per_run
from tests.identification.test_column_choice import synthetic

LINE = "identify: "  # the fit's preparation line: "identify: N samples of 1 recording(s), cutoff 10 Hz"


@pytest.fixture
def cli_log(capsys):
    """The captured stderr, with the command line's handler at INFO on it (``_cli``, at the start of the test body:
    the capture of the setup is not the test's) removed after the test."""
    yield capsys
    remove_logging()


def _cli():
    configure_logging(logging.INFO)


def _fit(robot, model, recording):
    return identify_trajectories(robot, model, [recording], TrajectoryOptions(consistency=False))


def test_a_fit_inside_the_context_prints_no_progress_line_and_outside_it_does(denso, denso_model, cli_log, caplog):
    _cli()
    recording = synthetic(denso, 0, duration=3.0)
    _fit(denso, denso_model, recording)
    shown = [line for line in cli_log.readouterr().err.splitlines() if line.startswith(LINE)]
    assert len(shown) == 1 and "samples of 1 recording(s)" in shown[0], shown
    for context in (held_back("identification.calibration"), quiet_trial()):
        with context:
            _fit(denso, denso_model, recording)
        assert not [line for line in cli_log.readouterr().err.splitlines() if line.startswith(LINE)]
    _fit(denso, denso_model, recording)  # the context left: shown again
    assert [line for line in cli_log.readouterr().err.splitlines() if line.startswith(LINE)] == shown
    remove_logging()  # a library user's handler (the root's, pytest's caplog): the same
    with caplog.at_level(logging.INFO):
        with held_back("identification.calibration"):
            _fit(denso, denso_model, recording)
        assert not [r for r in caplog.records if r.getMessage().startswith(LINE)]
        _fit(denso, denso_model, recording)
        assert len([r for r in caplog.records if r.getMessage().startswith(LINE)]) == 1


def test_another_thread_logs_on_while_one_holds_its_lines_back(cli_log):
    _cli()
    logger = logging.getLogger("identification.calibration.log_context_test")
    entered, logged = threading.Event(), threading.Event()

    def trial():
        with held_back("identification"):
            entered.set()
            logger.info("the trial's line")
            logger.warning("the trial's warning")
            logged.wait(10)

    thread = threading.Thread(target=trial)
    thread.start()
    entered.wait(10)
    logger.info("the other thread's line")  # while the trial holds its own back
    logged.set()
    thread.join(10)
    err = cli_log.readouterr().err.splitlines()
    assert "the other thread's line" in err and "the trial's warning" in err and "the trial's line" not in err, err
    assert logger.getEffectiveLevel() == logging.INFO  # no level was touched


def test_the_trial_records_its_warnings_and_its_warning_lines_pass(cli_log):
    _cli()
    logger = logging.getLogger("identification.calibration.log_context_test")
    with quiet_trial() as caught:
        warnings.warn("the LuGre model's warning", UserWarning, stacklevel=1)
        logger.info("a LuGre round's line")
        logger.warning("a warning through logging")
    assert [str(w.message) for w in caught] == ["the LuGre model's warning"]  # yielded to re-issue if kept
    err = cli_log.readouterr().err
    assert "a LuGre round's line" not in err and "a warning through logging" in err, err
    assert "the LuGre model's warning" not in err


def test_a_line_marked_once_is_said_once_per_run_on_every_handler(cli_log, caplog):
    _cli()
    logger = logging.getLogger("identification.calibration.log_context_test")
    with caplog.at_level(logging.INFO, logger="identification"):
        logging.getLogger("identification").propagate = True  # the root's handler (caplog) sees them as well
        with once_per_run():
            for _ in range(3):
                logger.info("identify: 461 samples", extra=ONCE)
            logger.info("identify: 300 samples", extra=ONCE)  # another recording set: said too
            with once_per_run():  # a nested run (the route inside the command) shares the command's
                logger.info("identify: 461 samples", extra=ONCE)
        logger.info("identify: 461 samples", extra=ONCE)  # a new run
    err = cli_log.readouterr().err.splitlines()
    assert err.count("identify: 461 samples") == 2 and err.count("identify: 300 samples") == 1, err
    assert [r.getMessage() for r in caplog.records] == ["identify: 461 samples", "identify: 300 samples",
                                                        "identify: 461 samples"]  # fmt: skip
