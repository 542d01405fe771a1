"""The command line's log handler: plain lines in files and pipes, a bar redrawn in place on a terminal."""

import io
import logging
import sys

import pytest

from psdm_casadi.cli import main
from psdm_casadi.cli.output import ProgressHandler


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def _logger(stream):
    logger = logging.getLogger("psdm_casadi.tests.progress")
    logger.handlers[:] = [ProgressHandler(stream)]
    logger.setLevel(logging.INFO)
    logger.propagate = False
    return logger


BAR_MARKS = ("\r", "%|", "\u2588")  # tqdm redraws in place, "NN%|" starts its bar, full blocks fill it


def test_progress_records_draw_one_tqdm_bar_on_a_terminal_and_plain_lines_elsewhere():
    terminal, pipe = _Terminal(), io.StringIO()
    for stream in (terminal, pipe):
        logger = _logger(stream)
        for k in range(1, 4):
            logger.info("start %d", k, extra={"progress": (k, 3)})
        for k in range(1, 6):
            logger.info("step %d", k, extra={"progress": (k, 5), "tick": True})
        logger.info("done")
    assert pipe.getvalue() == "start 1\nstart 2\nstart 3\ndone\n"  # ticks are not log lines
    screen = terminal.getvalue()
    assert "start 1:  33%|" in screen and "start 3: 100%|" in screen and "| 3/3 " in screen
    assert "step 5: 100%|" in screen and "| 5/5 " in screen
    assert screen.count("\n") == 2 and screen.endswith("done\n")  # the starts' bar stays, the ticks' bar goes
    assert "start 1\n" not in screen  # no plain progress line on a terminal


def test_a_line_during_a_bar_prints_above_it_and_verbose_shows_ticks_as_lines():
    terminal = _Terminal()
    logger = _logger(terminal)
    logger.info("step 1", extra={"progress": (1, 4), "tick": True})
    logger.info("a finding")
    logger.info("step 2", extra={"progress": (2, 4), "tick": True})
    screen = terminal.getvalue()
    assert "a finding\n" in screen and screen.rindex("step 2") > screen.index("a finding")
    pipe = io.StringIO()
    logger.handlers[:] = [ProgressHandler(pipe, ticks_as_lines=True)]
    logger.info("step 1", extra={"progress": (1, 4), "tick": True})
    assert pipe.getvalue() == "step 1\n"


def test_derivation_draws_a_bar_on_a_terminal_and_none_in_a_pipe_or_with_json(monkeypatch, capsys):
    assert main(["--no-cache", "derive", "scara"]) == 0  # stderr is captured: not a terminal
    err = capsys.readouterr().err
    assert "deriving" in err and not any(mark in err for mark in BAR_MARKS)
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(["--no-cache", "derive", "scara", "--json"]) == 0
    assert main(["--no-cache", "--quiet", "derive", "scara"]) == 0
    assert terminal.getvalue() == ""
    assert main(["--no-cache", "derive", "scara"]) == 0
    screen = terminal.getvalue()
    assert "deriving: gravity" in screen and "%|" in screen and "\r" in screen


def test_quiet_hides_progress_lines_and_verbose_is_accepted(capsys):
    assert main(["derive", "scara"]) == 0
    assert "deriving" in capsys.readouterr().err
    assert main(["--quiet", "derive", "scara"]) == 0
    assert "deriving" not in capsys.readouterr().err
    assert main(["--verbose", "derive", "scara"]) == 0
    assert "deriving" in capsys.readouterr().err


def test_built_in_robots_are_found_by_name_by_every_command(tmp_path, capsys):
    from psdm_casadi.errors import RobotFileError
    from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, load_robot

    by_name, by_path = load_robot("scara"), load_robot(BUILTIN_ROBOTS_DIR / "scara.toml")
    assert (by_name.name, by_name.n_dof) == (by_path.name, by_path.n_dof) == ("SCARA RRPR", 4)
    with pytest.raises(RobotFileError, match="name a built-in robot: denso_vs6556g, scara"):
        load_robot("no_such_robot")
    assert main(["codegen", "scara", "--out", str(tmp_path / "c"), "--json"]) == 0
    assert (tmp_path / "c" / "psdm_dynamics.c").exists()
    capsys.readouterr()
    assert main(["derive", "no_such_robot"]) == 2
    assert "built-in robot" in capsys.readouterr().err


def test_library_logging_after_a_command_does_not_write_to_its_closed_stderr(caplog):
    stream = io.StringIO()
    logger = _logger(stream)
    stream.close()
    logger.info("after the command", extra={"progress": (1, 2)})  # handled by logging, not raised
    assert main(["derive", "scara"]) == 0
    with caplog.at_level("INFO", logger="psdm_casadi.cli"):
        logging.getLogger("psdm_casadi.cli").info("library line")
    assert "library line" in caplog.text  # the command's handler is gone, records propagate again
