"""Ctrl-C for the ``psdm`` command: the first interrupt stops the command promptly, exit code 130.

Python turns SIGINT into ``KeyboardInterrupt``, but a solver may catch it: CasADi's Ipopt interface
ends the running solve with a failure status and returns, and the command would go on (the next
start, the next step). :class:`InterruptGuard` therefore repeats the interrupt every
:data:`REPEAT_SECONDS` after the first one, until the command has ended; a repeat is held back while
an exception is being handled, so that the clean-up of partial outputs (``OutputFolder``,
``atomic_write``) runs to its end. An exception that ends the command after an interrupt (a solver's
failure status, turned into ``SolverError`` before the next repeat) is reported as the interrupt.
"""

from __future__ import annotations

import signal
import sys
import threading

__all__ = ["InterruptGuard", "REPEAT_SECONDS"]

#: Seconds between the repeats of an interrupt that a solver swallowed.
REPEAT_SECONDS = 0.1


class InterruptGuard:
    """Context manager around one command: SIGINT raises KeyboardInterrupt, and keeps raising it.

    Installed only in the main thread (signal handlers cannot be set elsewhere); the previous SIGINT
    and SIGALRM handlers and the interval timer are restored on exit.

    Attributes
    ----------
    interrupted : bool
        True once a SIGINT arrived.
    """

    def __init__(self):
        self.interrupted = False
        self._active = False
        self._previous = {}

    def __enter__(self) -> InterruptGuard:
        if threading.current_thread() is not threading.main_thread():
            return self
        if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:  # e.g. a background job: keep ignoring it
            return self
        self._previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGALRM)}
        self._active = True
        signal.signal(signal.SIGINT, self._on_interrupt)
        return self

    def _on_interrupt(self, signum, frame):
        self.interrupted = True
        if self._active and signal.getsignal(signal.SIGALRM) is not self._on_repeat:
            signal.signal(signal.SIGALRM, self._on_repeat)
            signal.setitimer(signal.ITIMER_REAL, REPEAT_SECONDS, REPEAT_SECONDS)
        raise KeyboardInterrupt

    def _on_repeat(self, signum, frame):
        if self._active and sys.exc_info()[1] is None:
            raise KeyboardInterrupt

    def __exit__(self, exc_type, exc, tb) -> bool:
        if not self._previous:
            return False
        self._active = False
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        for sig, handler in self._previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        self._previous = {}
        if self.interrupted and exc is not None and not isinstance(exc, KeyboardInterrupt):
            # the failure a swallowed interrupt caused (Ipopt's NonIpopt_Exception_Thrown, raised as a
            # SolverError before the next repeat): the command was interrupted, not failed
            raise KeyboardInterrupt from exc
        return False
