"""The XML nodes the URDF and MJCF exports build alike: exact numbers, comments and elements (``xml.dom.minidom``).

Numbers are written by ``exact_text`` (the shortest text that reads back to the same float), so a file read back
gives the model's values to the bit.
"""

from __future__ import annotations

from psdm_casadi.values import exact_text

__all__ = ["comment", "element", "numbers"]


def numbers(values) -> str:
    """``values`` as one attribute text, exact floats separated by spaces."""
    return " ".join(exact_text(v) for v in values)


def comment(document, text: str):
    """A comment node of ``text`` on one line (``--``, which XML forbids in a comment, split)."""
    return document.createComment(" " + " ".join(str(text).replace("--", "- -").split()) + " ")


def element(document, tag: str, attributes=(), children=()):
    """An element ``tag`` with ``attributes`` ((name, text) pairs, in order) and ``children``."""
    node = document.createElement(tag)
    for key, value in attributes:
        node.setAttribute(key, value)
    for child in children:
        node.appendChild(child)
    return node
