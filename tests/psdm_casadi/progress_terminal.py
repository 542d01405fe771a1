"""A terminal stand-in and the command line's progress handler installed on the packages' loggers, for the tests of
the progress bars (Ipopt's iterations, the excitation's starts)."""

from __future__ import annotations

import io
import logging

from psdm_casadi.cli.output import ProgressHandler


class FakeTerminal(io.StringIO):
    def isatty(self):
        return True


class CountingHandler(ProgressHandler):
    """The command line's handler, noting the Ipopt bar's count and postfix after every record."""

    def __init__(self, stream):
        super().__init__(stream)
        self.counts, self.postfixes = [], []

    def emit(self, record):
        super().emit(record)
        self.counts.append(None if self._inner is None else self._inner.n)
        self.postfixes.append(None if self._inner is None else self._inner.postfix)


PACKAGES = ("identification", "trajopt")


def install_counting_handler(stream, level=logging.INFO):
    """Route the packages' log records to one counting handler on ``stream`` (what the command line installs)."""
    handler = CountingHandler(stream)
    for name in PACKAGES:
        parent = logging.getLogger(name)
        parent.handlers[:] = [handler]
        parent.setLevel(level)
        parent.propagate = False
    return handler
