"""What every ``psdm`` subcommand shares: exit codes, the ``--json`` printer and the log handler.

Library code reports progress through :mod:`logging` (one logger per module); the command line
decides what reaches the terminal: progress lines at INFO on stderr, so that stdout stays
machine-readable, fewer with ``--quiet`` or ``--json``, more with ``--verbose``.
"""

from __future__ import annotations

import json
import logging
import os
import sys
from pathlib import Path

from psdm_casadi.log_context import PACKAGES, install
from psdm_casadi.said_once import SAID

EXIT_OK, EXIT_CHECK_FAILED, EXIT_BAD_INPUT, EXIT_SOLVER, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
#: A closed stdout (``psdm ... | head -1``): the code a shell gives a process ended by SIGPIPE (128 + 13).
EXIT_BROKEN_PIPE = 141

#: The packages whose loggers the command line shows.
LOGGED_PACKAGES = PACKAGES

_HANDLER_NAME = "psdm-cli"


class _JsonState:
    """Whether the running command has printed its JSON object (an error then prints none of its own)."""

    printed = False


def print_json(payload) -> None:
    """Print one JSON object on stdout (the ``--json`` contract of every subcommand)."""
    print(json.dumps(payload, sort_keys=False, default=float))
    _JsonState.printed = True


def reset_json() -> None:
    """Start a command: no JSON object printed yet."""
    _JsonState.printed = False


def json_printed() -> bool:
    """True once the running command has printed its JSON object."""
    return _JsonState.printed


def model_warnings(calibrated) -> list:
    """The warnings ``psdm identify`` stored in a calibrated model (its document's ``warnings``), as strings."""
    return [str(w) for w in calibrated.document.get("warnings") or []]


def report_model_warnings(command: str, source, calibrated, judged=()) -> list:
    """Print on stderr the warnings stored in a calibrated-model file; return them (for ``--json``).

    ``psdm identify`` and ``psdm diagnose --apply`` store the warnings of their fit: they point at a wrong
    recording behind the model (a friction held at zero, masses an order of magnitude off the robot file's, a
    joint its own training data did not explain: ``trajectory_checks.fit_warnings``). Every command that reads
    a model file repeats them rather than leave them in the file; ``--quiet`` keeps them. Identify's sentence on a
    load nothing states on one of its held-out recordings is left out where the command judges that recording again
    (``judged``: the paths whose load it checks and names in its own line, as ``psdm validate`` and ``psdm diagnose
    MODEL`` do): one line per load, the command's, which says what it found now.
    """
    again = {Path(str(path)).name for path in judged}
    repeated = {sentence for recording, sentence in stored_load_sentences(calibrated.document)
                if Path(recording).name in again}  # fmt: skip
    warnings = [w for w in model_warnings(calibrated) if not any(w.startswith(s) for s in repeated)]  # s + the judges
    for warning in (w for w in warnings if w not in SAID):  # one its robot's loading printed already: said once
        print(f"psdm {command}: warning: {Path(source).name} (stored in the model file): {warning}", file=sys.stderr)
    return warnings


def stored_load_sentences(document: dict) -> list:
    """``[(recording, sentence), ...]``: the loads nothing states that identify found on its held-out recordings, as
    the model file stores them (``validation.recordings[].unstated_payload``, ``held_out_load.UnstatedLoad``)."""
    entries = (document.get("validation") or {}).get("recordings") or ()
    found = [(entry, entry.get("unstated_payload")) for entry in entries if isinstance(entry, dict)]
    return [(str(entry.get("recording", "")), str(load["sentence"]))
            for entry, load in found if isinstance(load, dict) and load.get("sentence")]  # fmt: skip


def silence_stdout() -> None:
    """After a closed stdout: point its descriptor at /dev/null, so that Python's flush at exit stays quiet."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # a replaced stdout (tests): nothing to redirect
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)


def progress(message: str, *, quiet: bool = False) -> None:
    """A progress line of a command, through the command-line logger (shown on stderr at INFO)."""
    if not quiet:
        logging.getLogger("psdm_casadi.cli").info(message)


class ProgressHandler(logging.StreamHandler):
    """Log lines on stderr; a record with ``extra={"progress": (done, total)}`` draws a tqdm bar on a terminal.

    The libraries mark the steps of a long loop (the derivation's functions, the diagnosis' candidates, the
    LuGre fits per joint, the excitation's starts) with ``progress``. On a terminal those records move one bar
    (a new bar starts when the total changes or the count goes back); other lines print above it. Elsewhere (a
    file, a pipe, CI) a progress record is one plain line, unless it also carries ``"tick": True`` (a loop step
    worth a bar but not a log line), which prints only when ``ticks_as_lines`` (``--verbose``). With ``--quiet``
    and ``--json`` the level is WARNING: no progress record arrives, so no bar is drawn. A record with
    ``"bar_only": True`` (an Ipopt iteration, ``psdm_casadi.ipopt_progress``) is drawn on a terminal only, with its
    ``"postfix"`` text; one with ``"progress_end": True`` ends the bar of a loop that stopped before its total.
    """

    def __init__(self, stream=None, ticks_as_lines: bool = False):
        super().__init__(stream)
        self.ticks_as_lines = ticks_as_lines
        self._bar = self._inner = None

    def draws_progress_bars(self) -> bool:
        """True on a terminal at INFO: the loops that log only for a bar (``ipopt_progress``) then log."""
        try:
            return self.level <= logging.INFO and self.stream.isatty()
        except (AttributeError, ValueError):  # a closed or replaced stream
            return False

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self._draw(record)
        except Exception:  # a closed or broken stream: logging's own error report, never the caller's failure
            self._bar = self._inner = None
            self.handleError(record)

    def _draw(self, record: logging.LogRecord) -> None:
        done_total = getattr(record, "progress", None)
        if getattr(record, "bar_only", False):
            if self.stream.isatty():
                self._draw_inner(record, done_total)
            return
        if done_total is None or not self.stream.isatty():
            if done_total is not None and getattr(record, "tick", False) and not self.ticks_as_lines:
                return
            if self._bar is not None:  # a line between two steps: print it above the bar
                self._bar.clear()
                super().emit(record)
                self._bar.refresh()
            else:
                super().emit(record)
            return
        from tqdm import tqdm

        done, total = (int(x) for x in done_total)
        if self._bar is None or self._bar.total != total or done < self._bar.n:
            self.close_bar()
            leave = not getattr(record, "tick", False)
            self._bar = tqdm(total=total, desc=self.format(record), file=self.stream, leave=leave, mininterval=0)
        else:
            self._bar.set_description_str(self.format(record), refresh=False)
        self._bar.update(done - self._bar.n)
        if done >= total:
            self.close_bar()

    def _draw_inner(self, record: logging.LogRecord, done_total) -> None:
        """An Ipopt solve's iterations: a second bar under the loop's own bar (if one is open), drawn at most ten
        times a second (an iteration takes milliseconds), the record's ``postfix`` beside it; ``progress_end``
        (or a record without a count) removes it."""
        from tqdm import tqdm

        if getattr(record, "progress_end", False) or done_total is None:
            self._close_inner()
            return
        done, total = (int(x) for x in done_total)
        if self._inner is None or self._inner.total != total or done < self._inner.n:
            self._close_inner()
            self._inner = tqdm(total=total, desc=self.format(record), file=self.stream, leave=False,
                               mininterval=0.1, position=0 if self._bar is None else 1)  # fmt: skip
        if getattr(record, "postfix", None):
            self._inner.set_postfix_str(record.postfix, refresh=False)
        self._inner.update(done - self._inner.n)

    def _close_inner(self) -> None:
        inner, self._inner = self._inner, None
        if inner is not None:
            inner.close()

    def close_bar(self) -> None:
        """End the open bar (left on screen unless it was made of ticks)."""
        bar, self._bar = self._bar, None
        if bar is not None:
            bar.close()

    def close(self) -> None:
        try:
            self._close_inner()
            self.close_bar()
        except Exception:  # the stream closed before the command's handler: nothing left to draw on
            pass
        super().close()


def remove_logging() -> None:
    """Remove the handler :func:`configure_logging` installed; the packages' records propagate again."""
    for name in LOGGED_PACKAGES:
        logger = logging.getLogger(name)
        for old in [h for h in logger.handlers if h.get_name() == _HANDLER_NAME]:
            logger.removeHandler(old)
            old.close()
        logger.setLevel(logging.NOTSET)
        logger.propagate = True


def configure_logging(level: int) -> None:
    """Send the project's log records of ``level`` and above to the current stderr: plain lines, and a progress
    bar for long loops on a terminal (:class:`ProgressHandler`).

    Called once per command; a handler installed by an earlier call (tests run many commands in one
    process) is replaced, so that every line appears once and on the stderr of the current call.
    """
    SAID.clear()  # a new command: what the last one printed is to be said again
    handler = ProgressHandler(sys.stderr, ticks_as_lines=level <= logging.DEBUG)
    handler.set_name(_HANDLER_NAME)
    handler.setFormatter(logging.Formatter("%(message)s"))
    install(handler)  # what a context holds back or says once (``log_context``)
    for name in LOGGED_PACKAGES:
        logger = logging.getLogger(name)
        for old in [h for h in logger.handlers if h.get_name() == _HANDLER_NAME]:
            logger.removeHandler(old)
        logger.addHandler(handler)
        logger.setLevel(level)
        logger.propagate = False
