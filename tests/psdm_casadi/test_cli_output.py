"""The command line's log handler: plain lines in files and pipes, a bar redrawn in place on a terminal."""

import io
import logging

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
