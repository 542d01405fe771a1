"""Checks of ``psdm`` options, run by every command before any work: one line naming the option and the fix.

Values are printed as plain numbers (``0``, ``-1``, ``1e+09``), never as numpy reprs. The outputs of a
command are checked here too (:func:`output_file`, :func:`output_folder`) and written through
:func:`staged`, so that a refusal, a failure or Ctrl-C leaves no partial file.
"""

from __future__ import annotations

import math
from contextlib import ExitStack, contextmanager
from numbers import Integral, Real

from psdm_casadi.errors import ParameterError
from psdm_casadi.fileio import OutputFile, OutputFolder

__all__ = [
    "MAX_SAMPLES",
    "check_count",
    "check_positive",
    "check_samples",
    "check_seed",
    "output_file",
    "output_folder",
    "parse_joints",
    "plain",
    "staged",
]

#: Most samples a command writes or simulates per recording (memory and time stay within a workstation's).
MAX_SAMPLES = 2_000_000


def plain(value) -> str:
    """A number as a user typed it: ``0``, ``-2``, ``0.5``, ``1e+09`` (numpy scalars included)."""
    if isinstance(value, bool) or not isinstance(value, Real):
        return repr(value)
    if isinstance(value, Integral):
        return str(int(value))
    return f"{float(value):g}"


def check_positive(value, option: str, fix: str, unit: str = "") -> None:
    """``value`` (None allowed: the default applies) must be a finite number > 0."""
    if value is None:
        return
    if not (math.isfinite(value) and value > 0):
        raise ParameterError(f"{option} must be a positive number{unit}; got {plain(value)}. {fix}")


def check_count(value, option: str, fix: str, minimum: int = 1) -> None:
    """``value`` (None allowed) must be an integer >= ``minimum``."""
    if value is None:
        return
    if value < minimum:
        raise ParameterError(f"{option} must be an integer >= {minimum}; got {plain(value)}. {fix}")


def check_seed(value) -> None:
    """``--seed`` must be >= 0 (numpy's generators take no negative seed)."""
    if value is not None and value < 0:
        raise ParameterError(f"--seed must be an integer >= 0; got {plain(value)}. Pass e.g. --seed 0.")


def check_samples(duration: float, rate: float, option: str, subject: str, fix: str) -> None:
    """``duration * rate`` samples must stay within :data:`MAX_SAMPLES` (memory and time of one recording)."""
    n_samples = duration * rate
    if n_samples > MAX_SAMPLES:
        raise ParameterError(
            f"{option} must give at most {MAX_SAMPLES} samples {subject} ({plain(MAX_SAMPLES / rate)} s at "
            f"{plain(rate)} Hz); got {plain(duration)} s at {plain(rate)} Hz = {plain(n_samples)} samples. {fix}"
        )


def parse_joints(text: str | None, n_dof: int, option: str = "--joints") -> list:
    """0-based joints from a comma-separated list of 1-based joint numbers (None: every joint)."""
    if text is None:
        return list(range(n_dof))
    joints = []
    for item in text.split(","):
        try:
            number = int(item.strip())
        except ValueError:
            raise ParameterError(
                f"{option} must be comma-separated joint numbers 1..{n_dof}; got {text!r}. Pass e.g. {option} 1,3."
            ) from None
        if not 1 <= number <= n_dof:
            raise ParameterError(
                f"{option} must hold joint numbers 1..{n_dof} (the robot has {n_dof} joints); got {number}. "
                f"Pass e.g. {option} 1,{n_dof}."
            )
        if number - 1 not in joints:
            joints.append(number - 1)
    return joints


def output_file(path, option: str, overwrite: bool, overwrite_option: str = "--overwrite") -> OutputFile | None:
    """The checked output file of ``option`` (None when the option was not given)."""
    if path is None:
        return None
    output = OutputFile(path, option, overwrite_option)
    output.check(overwrite)
    return output


def output_folder(path, names, force: bool, force_option: str = "--overwrite", shared: bool = False) -> OutputFolder:
    """The checked ``--out`` folder of a command that writes ``names`` (see ``OutputFolder``)."""
    folder = OutputFolder(path, names, option=force_option, shared=shared)
    folder.check(force)
    return folder


@contextmanager
def staged(*outputs):
    """Staging paths of several outputs (None entries give None), all moved into place only at the end.

    A failure or interrupt inside the block removes every staged output and leaves the targets as they were.
    """
    with ExitStack() as stack:
        yield [None if output is None else stack.enter_context(output.staging()) for output in outputs]
