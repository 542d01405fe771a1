"""Which progress lines one context lets through: a nested fit's held back, a line every fit repeats said once.

Library code reports progress through :mod:`logging`; some of it is not the caller's to show. A trial fit beside
identify's own (``lugre_trial``) or the training fit behind diagnose's load check (``cli.diagnose_loads``) logs as
``psdm identify`` does, and the command states the result once in its own words (:func:`held_back`); every fit of one
identify run logs the same preparation line ("identify: N samples of K recording(s), cutoff ... Hz") and the run
should say it once (:func:`once_per_run`, for the records logged with ``extra=ONCE``).

The state is a :class:`contextvars.ContextVar`, read by one filter (:class:`ContextFilter`) on the handlers: a fleet
run's Dask threads share the loggers and handlers, and a logger's level raised for one thread's trial (or a filter added
to a handler and removed again) would hold back, or restore early, the lines of every other thread. The filter is
added once to a handler (the command line's at its creation, ``cli.output.configure_logging``; others when a context
is entered, on the handlers its loggers' records reach) and never removed: outside a context it lets every record
through. A handler's filter, not a logger's, because a logger's filter sees only the records of that very logger, not
its children's (``identification.calibration`` never logs itself; its modules do).
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
from dataclasses import dataclass, field

__all__ = ["ONCE", "PACKAGES", "ContextFilter", "held_back", "install", "once_per_run"]

#: The ``extra`` of a record the run says once (the same logger and message again in one :func:`once_per_run` are
#: not shown).
ONCE = {"once": True}
#: The packages whose loggers a context covers when it names none.
PACKAGES = ("psdm_casadi", "trajopt", "identification", "codegen")


@dataclass(frozen=True)
class _Context:
    held: tuple = ()  # (logger name, level): that logger's and its children's records below the level held back
    said: dict | None = field(default=None)  # (logger, message) -> the record shown, inside ``once_per_run``


_NONE = _Context()  # outside any context: every record through
_STATE: contextvars.ContextVar = contextvars.ContextVar("psdm_log_context", default=None)


def _state() -> _Context:
    return _STATE.get() or _NONE


def _under(name: str, parent: str) -> bool:
    return parent in ("", "root") or name == parent or name.startswith(parent + ".")


class ContextFilter(logging.Filter):
    """Lets a record through unless the context it was logged in holds its logger back below its level, or it is a
    ``ONCE`` record already shown in that run (the same record object passes every handler it reaches)."""

    def filter(self, record: logging.LogRecord) -> bool:
        state = _state()
        if any(record.levelno < level and _under(record.name, name) for name, level in state.held):
            return False
        if state.said is None or not getattr(record, "once", False):
            return True
        return state.said.setdefault((record.name, record.getMessage()), record) is record


_FILTER = ContextFilter()


def install(handler: logging.Handler) -> None:
    """Add the context filter to ``handler`` (once; inert outside a context)."""
    if _FILTER not in handler.filters:
        handler.addFilter(_FILTER)


def _install_reached(names) -> None:
    """The filter on every handler a record of the loggers ``names`` reaches (up the hierarchy, as propagation goes)."""
    for name in names:
        logger = logging.getLogger(name)
        while logger is not None:
            for handler in logger.handlers:
                install(handler)
            logger = logger.parent if logger.propagate else None


@contextlib.contextmanager
def held_back(*names: str, below: int = logging.WARNING):
    """In this context (this thread or task, not the others), the records below ``below`` (default: progress lines;
    warnings pass) of the loggers ``names`` and their children are not shown. Nested contexts add up."""
    names = names or PACKAGES
    _install_reached(names)
    state = _state()
    token = _STATE.set(_Context(state.held + tuple((name, below) for name in names), state.said))
    try:
        yield
    finally:
        _STATE.reset(token)


@contextlib.contextmanager
def once_per_run():
    """In this context, a record logged with ``extra=ONCE`` is shown the first time its logger logs its message, not
    again (a nested run shares the outer one's: the command's)."""
    _install_reached(PACKAGES)
    state = _state()
    token = None if state.said is not None else _STATE.set(_Context(state.held, {}))
    try:
        yield
    finally:
        if token is not None:
            _STATE.reset(token)
