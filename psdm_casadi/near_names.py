"""The files beside a path that does not exist whose names are close to it: a typo'd recording or model file
(``pandaa.csv`` for ``panda.csv``) is answered with the name the user most likely meant, not only 'check the path'."""

from __future__ import annotations

import difflib
from pathlib import Path

__all__ = ["did_you_mean"]

#: How close a name must be (``difflib``'s ratio) to be offered.
CUTOFF = 0.75
#: The most names offered.
MOST = 3


def did_you_mean(path) -> str:
    """``" Did you mean 'panda.csv'?"`` (with the folder as given) for the closest names in ``path``'s folder, or
    ``""`` when the folder is missing or holds no close name."""
    path = Path(path)
    folder = path.parent
    try:
        names = sorted(p.name for p in folder.iterdir())
    except OSError:
        return ""
    close = difflib.get_close_matches(path.name, names, n=MOST, cutoff=CUTOFF)
    if not close:
        return ""
    shown = [str(folder / name) if str(path.parent) != "." else name for name in close]
    return " Did you mean " + " or ".join(repr(name) for name in shown) + "?"
