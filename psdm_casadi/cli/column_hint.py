"""An error's ``--columns`` hint in the file's own column names: the library states a unit as ``SIGNAL=PREFIX:UNIT``
(it reads arrays, not the file's header); the command, which read the file with its ``--columns`` or the default
names (``t``, ``q1`` ..., ``tau1`` ...), gives the option to pass: the user's own items with the unit added.

A new user whose positions were in degrees was told ``--columns q=PREFIX:deg (e.g. t=Time,q=Position:deg,...)`` for a
file whose columns are ``t, q1..q6, tau1..tau6``, and ``--columns q=q:deg`` alone would have left its torques unread
(the items of ``--columns`` are the columns read).
"""

from __future__ import annotations

import re

__all__ = ["with_own_columns"]

_HINT = re.compile(r"--columns (t|q|qd|qdd|tau|i)=PREFIX:([^\s,;)]+)")


def _items(spec: str | None, signal: str) -> list:
    """``[[signal, prefix, unit or None], ...]`` of ``spec`` (default names without one: t, q and the hint's torque
    signal, ``tau`` or ``i``)."""
    if not spec:
        torque = "i" if signal == "i" else "tau"
        return [["t", "t", None], ["q", "q", None], [torque, torque, None]] + (
            [[signal, signal, None]] if signal not in ("t", "q", torque) else []
        )
    out = []
    for item in spec.split(","):
        name, _, rest = item.strip().partition("=")
        prefix, _, unit = rest.partition(":")
        out.append([name.strip(), prefix.strip(), unit.strip() or None])
    return out


def with_own_columns(message: str, spec: str | None) -> str:
    """``message`` with each ``--columns SIGNAL=PREFIX:UNIT`` replaced by the whole option for this file: ``spec`` (the
    command's ``--columns``, None for the default names) with ``UNIT`` on ``SIGNAL``'s item. A signal ``spec`` does not
    name keeps the generic hint."""

    def own(match) -> str:
        signal, unit = match.group(1), match.group(2)
        items = _items(spec, signal)
        if not any(item[0] == signal for item in items):
            return match.group(0)
        text = ",".join(f"{s}={p}" + (f":{unit}" if s == signal else (f":{u}" if u else "")) for s, p, u in items)
        return f"--columns {text}"

    return _HINT.sub(own, message)
