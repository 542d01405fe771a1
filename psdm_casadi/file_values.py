"""Numbers and lists of numbers as robot files write them: finite floats, or small expressions of ``pi``.

Shared by the robot-file reader (``robot_file``) and the reader of its transmission and recording
tables (``transmission_file``), so that ``"-pi/2"`` reads, and a bad value is refused, the same way.
"""

from __future__ import annotations

import ast
import math
import operator

import numpy as np

from psdm_casadi.errors import RobotFileError
from psdm_casadi.values import format_value, is_real_number

__all__ = ["file_number", "file_vector"]

_NUMBER_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv}
_MAX_EXPRESSION = 200  # characters of a number written as an expression


def file_number(value, where: str, fix: str = "Give a finite value.") -> float:
    """A finite float from a TOML number or a small expression like ``"-pi/2"``.

    Raises
    ------
    RobotFileError
        Naming ``where`` and the fix, for a value that is not a number, an expression or finite.
    """
    number = None
    if is_real_number(value):
        try:
            number = float(value)
        except OverflowError:  # an integer beyond the float range
            number = math.inf if value > 0 else -math.inf
    elif isinstance(value, str) and len(value) <= _MAX_EXPRESSION:
        try:
            number = float(_eval_expression(ast.parse(value, mode="eval").body))
        except (SyntaxError, ValueError, ZeroDivisionError, OverflowError, RecursionError):
            number = None
    if number is None:
        raise RobotFileError(
            f'{where} must be a number or an expression of numbers and pi such as "-pi/2"; '
            f"got {format_value(value)}. Fix the value."
        )
    if not math.isfinite(number):
        shown = f"{value!r} (= {number!r})" if isinstance(value, str) else format_value(number)
        raise RobotFileError(f"{where} must be a finite number; got {shown}. {fix}")
    return number


def _eval_expression(node):
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return node.value
    if isinstance(node, ast.Name) and node.id == "pi":
        return math.pi
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _eval_expression(node.operand)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.BinOp) and type(node.op) in _NUMBER_OPS:
        return _NUMBER_OPS[type(node.op)](_eval_expression(node.left), _eval_expression(node.right))
    raise ValueError("unsupported expression")


def file_vector(value, length: int, where: str) -> np.ndarray:
    """``length`` finite floats from a TOML list (each a number or an expression), refused with the fix."""
    if not isinstance(value, list) or len(value) != length:
        raise RobotFileError(f"{where} must be a list of {length} numbers; got {format_value(value)}. Fix the list.")
    return np.array([file_number(v, f"{where}[{k}]") for k, v in enumerate(value)])
