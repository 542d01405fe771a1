"""The ``--overwrite`` option of every ``psdm`` command that writes files, with ``--force`` as its deprecated old name.

``psdm identify``, ``validate``, ``diagnose`` and the exports always said ``--overwrite``; ``codegen``, ``derive`` and
``demo`` said ``--force`` (a new user who typed ``--overwrite`` for codegen was told to pass ``--force``). They all say
``--overwrite`` now; ``--force`` still works on those three, says once that it is ``--overwrite``, and is no longer
listed in their help.
"""

from __future__ import annotations

import argparse

__all__ = ["DEPRECATED_FORCE_NOTE", "add_overwrite_argument", "used_deprecated_force"]

#: What the command line says (once, before the command runs) when ``--force`` was given.
DEPRECATED_FORCE_NOTE = "--force is the old name of --overwrite; it still works, but write --overwrite"
_USED = "used_deprecated_force"


class _DeprecatedForce(argparse.Action):
    """``--force``: sets the same destination as ``--overwrite`` and marks that the old name was used."""

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, True)
        setattr(namespace, _USED, True)


def used_deprecated_force(args) -> bool:
    """Whether the parsed ``args`` of a command got ``--force`` (the command line then prints the note)."""
    return bool(getattr(args, _USED, False))


def add_overwrite_argument(parser, help: str, dest: str = "overwrite", deprecated_force: bool = True) -> None:
    """``--overwrite`` (into ``dest``) on ``parser``, and with ``deprecated_force`` the hidden ``--force`` beside it."""
    parser.add_argument("--overwrite", dest=dest, action="store_true", help=help)
    if deprecated_force:
        parser.add_argument("--force", dest=dest, action=_DeprecatedForce, nargs=0, default=False,
                            help=argparse.SUPPRESS)  # fmt: skip
