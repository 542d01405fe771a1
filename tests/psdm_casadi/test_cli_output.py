"""The command line's log handler: plain lines in files and pipes, a bar redrawn in place on a terminal."""

import io
import logging

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


def test_progress_records_draw_one_bar_on_a_terminal_and_plain_lines_elsewhere():
    terminal, pipe = _Terminal(), io.StringIO()
    for stream in (terminal, pipe):
        logger = _logger(stream)
        for k in range(1, 4):
            logger.info("start %d", k, extra={"progress": (k, 3)})
        logger.info("done")
    assert pipe.getvalue() == "start 1\nstart 2\nstart 3\ndone\n"
    screen = terminal.getvalue()
    assert screen.count("\r[") == 3 and "[########----------------] 1/3 start 1" in screen
    assert screen.endswith("3/3 start 3\x1b[K\ndone\n")


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
