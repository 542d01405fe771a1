"""The warnings this command has already printed while loading its robot, so that a command does not print them twice.

A URDF's unusable inertia is logged when the robot is loaded (``urdf``, ``robot_file``) and stored with the fit in the
model file, whose warnings every later command repeats (``cli.output.report_model_warnings``): the Kinova's vendor
URDF had each of its two inertias printed twice by identify, validate, diagnose and the exports. The set is emptied
at the start of each command (``cli.output.configure_logging``), so a robot loaded from a cache in a later command of
the same process leaves the stored warning to be said.
"""

from __future__ import annotations

__all__ = ["SAID", "say"]

#: The messages logged in this command.
SAID: set = set()


def say(logger, message: str) -> None:
    """Log ``message`` as a warning and remember it for this command."""
    SAID.add(message)
    logger.warning("%s", message)
