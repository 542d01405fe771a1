"""count_operations(): the size of an SX Function by kind of instruction (reported for every exported function)."""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

_NON_ARITHMETIC = {
    getattr(ca, op) for op in ("OP_INPUT", "OP_OUTPUT", "OP_CONST", "OP_PARAMETER", "OP_ASSIGN") if hasattr(ca, op)
}
_TRIG = {ca.OP_SIN, ca.OP_COS, ca.OP_TAN}


@dataclass(frozen=True)
class OperationCount:
    """Size of one exported Function.

    Attributes
    ----------
    name : str
        C symbol of the function.
    n_instructions : int
        CasADi instructions (inputs, outputs and constants included).
    n_operations : int
        Arithmetic and elementary-function instructions only.
    n_multiplications, n_additions, n_trig : int
        Multiplications/divisions, additions/subtractions/negations, and sin/cos/tan calls.
    """

    name: str
    n_instructions: int
    n_operations: int
    n_multiplications: int
    n_additions: int
    n_trig: int


def count_operations(function: ca.Function, name: str | None = None) -> OperationCount:
    """Count the instructions of an SX Function by kind.

    Parameters
    ----------
    function : casadi.Function
        An SX Function (an MX one is expanded first).
    name : str, optional
        Name to report; defaults to the Function's.

    Returns
    -------
    OperationCount
    """
    if not function.is_a("SXFunction"):
        function = function.expand()
    ids = [function.instruction_id(k) for k in range(function.n_instructions())]
    mul = sum(op in (ca.OP_MUL, ca.OP_DIV, ca.OP_SQ, ca.OP_TWICE) for op in ids)
    add = sum(op in (ca.OP_ADD, ca.OP_SUB, ca.OP_NEG) for op in ids)
    trig = sum(op in _TRIG for op in ids)
    ops = sum(op not in _NON_ARITHMETIC for op in ids)
    return OperationCount(name or function.name(), len(ids), ops, mul, add, trig)
