"""Jacobians of the dynamics as vectorised C: the reverse sweeps of all Jacobian rows in SIMD lanes.

Reverse-mode differentiation of tau(q, qd, qdd) takes one adjoint sweep per joint row; the sweeps run the
same instructions on different seeds (the unit vectors e_i), and the forward values they read are shared.
Written from an SX Function ``(q, qd, qdd, seed) -> (value, J_1^T seed, J_2^T seed, ...)`` whose first
output does not depend on the seed, the C code here computes everything that does not depend on the seed
once, in scalars, and every seed-dependent value as a vector whose lane holds one row's (GCC/Clang vector
extensions, ``width`` doubles, rows ``width * s ...`` in sweep s; the sweeps' statements are written side
by side). As the Jacobians are stored column-major, the lanes of one column are adjacent and each is
written with one copy.

A partial derivative that is not finite (NaN or inf in one row's sweep) spreads to the rows of the same
vector (0 * NaN), where CasADi's per-row code, which drops the zero seeds, keeps them finite; the dynamics'
partials are finite wherever the dynamics are.

The code is spliced beside CasADi's scalar code as ``codegen.lane_regressor.splice`` does for the
regressor: compilers without vector extensions, or ``-DPSDM_NO_LANES``, keep CasADi's code.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from psdm_casadi.errors import ParameterError

# Four doubles (one AVX2 register): two sweeps side by side for a 6- or 7-joint arm overlap better than one
# sweep of eight lanes, whose instructions wait on each other.
LANE_WIDTH = 4
_BINARY = {ca.OP_ADD: "+", ca.OP_SUB: "-", ca.OP_MUL: "*", ca.OP_DIV: "/"}
# Elementary functions of seed-independent values only (a Jacobian-vector product is linear in the seed).
_SCALAR_UNARY = {
    ca.OP_TANH: "tanh({})",
    ca.OP_EXP: "exp({})",
    ca.OP_LOG: "log({})",
    ca.OP_SQRT: "sqrt({})",
    ca.OP_FABS: "fabs({})",
    ca.OP_SIGN: "(({0}) > 0 ? 1.0 : (({0}) < 0 ? -1.0 : 0.0))",
    ca.OP_ATAN: "atan({})",
    ca.OP_TAN: "tan({})",
    ca.OP_INV: "1.0 / {}",
}
_SCALAR_BINARY = {ca.OP_POW: "pow({}, {})", ca.OP_CONSTPOW: "pow({}, {})", ca.OP_ATAN2: "atan2({}, {})",
                  ca.OP_FMIN: "fmin({}, {})", ca.OP_FMAX: "fmax({}, {})", ca.OP_LT: "(casadi_real)({} < {})",
                  ca.OP_LE: "(casadi_real)({} <= {})", ca.OP_EQ: "(casadi_real)({} == {})",
                  ca.OP_NE: "(casadi_real)({} != {})", ca.OP_IF_ELSE_ZERO: "({} ? {} : 0)"}  # fmt: skip


@dataclass(frozen=True)
class LaneJacobian:
    """The vectorised code of one Jacobian Function.

    Attributes
    ----------
    name : str
        C symbol it replaces; the code defines ``static int <name>_lanes(arg, res)``.
    source : str
    n_scalar_operations : int
        Arithmetic and trig instructions of the seed-independent part (computed once, in scalars).
    n_vector_operations : int
        Arithmetic instructions on lane vectors, all sweeps together (each on ``width`` rows at once).
    """

    name: str
    source: str
    n_scalar_operations: int
    n_vector_operations: int

    @property
    def n_operations(self) -> int:
        """Scalar plus vector instructions (what the sweep costs, counting a vector instruction once)."""
        return self.n_scalar_operations + self.n_vector_operations


class _Unsupported(Exception):
    """An instruction the lane writer does not translate (the caller keeps CasADi's scalar code)."""


def _unary(op, x: str, lane: bool, trig: str) -> str:
    if op == ca.OP_NEG:
        return f"-({x})"
    if op == ca.OP_SQ:
        return f"{x} * {x}"
    if op == ca.OP_TWICE:
        return f"{x} + {x}"
    if op in (ca.OP_SIN, ca.OP_COS) and not lane:
        return f"{trig}{'sin' if op == ca.OP_SIN else 'cos'}({x})"
    if op in _SCALAR_UNARY and not lane:
        return _SCALAR_UNARY[op].format(x)
    raise _Unsupported(op)


def _lane(name: str, lane: bool, sweep: int) -> str:
    return f"{name}_{sweep}" if lane else name


def _statements(function: ca.Function, seed_input: int, n_rows: int, width: int, trig: str) -> tuple:
    """(statements, {False: scalar operations, True: vector operations per sweep}) of the straight-line code.

    Every seed-dependent statement is written once per sweep (rows ``width * s ... width * s + width - 1``),
    the sweeps side by side so that the compiler and the processor overlap them.
    """
    sweeps = range(-(-n_rows // width))
    slots, code, n_operations = {}, [], {False: 0, True: 0}
    for k in range(function.n_instructions()):
        op, inputs, outputs = function.instruction_id(k), function.instruction_input(k), function.instruction_output(k)
        if op == ca.OP_OUTPUT:
            name, lane = slots[inputs[0]]
            index, nz = outputs
            if index == 0 and lane:
                raise _Unsupported("the value output depends on the seed")
            if index == 0:
                code.append(f"  if (res[0]) res[0][{nz}] = {name};")
            for s in sweeps if index > 0 else ():
                first, count = nz * n_rows + width * s, min(width, n_rows - width * s)
                if lane:
                    copy = f"memcpy(res[{index}] + {first}, &{name}_{s}, {count} * sizeof(casadi_real))"
                    code.append(f"  if (res[{index}]) {copy};")
                else:
                    code.append(
                        f"  if (res[{index}]) for (int i = 0; i < {count}; ++i) res[{index}][{first} + i] = {name};"
                    )
            continue
        target = f"x{k}"
        if op == ca.OP_INPUT:
            index, nz = inputs
            if index == seed_input:
                slots[outputs[0]] = (f"seed{nz}", True)
            else:
                code.append(f"  const casadi_real {target} = arg[{index}] ? arg[{index}][{nz}] : 0;")
                slots[outputs[0]] = (target, False)
            continue
        if op == ca.OP_CONST:
            slots[outputs[0]] = (f"({float(function.instruction_constant(k))!r})", False)
            continue
        binary = op in _BINARY or op in _SCALAR_BINARY
        operands = [slots[i] for i in inputs[: 2 if binary else 1]]
        lane = any(is_lane for _, is_lane in operands)
        if op in _SCALAR_BINARY and lane:
            raise _Unsupported(op)
        n_operations[lane] += 1
        for s in sweeps if lane else (0,):
            names = [_lane(name, is_lane, s) for name, is_lane in operands]
            if op in _BINARY:
                expr = f" {_BINARY[op]} ".join(names)
            else:
                expr = _SCALAR_BINARY[op].format(*names) if binary else _unary(op, names[0], lane, trig)
            code.append(f"  const {'vlane' if lane else 'casadi_real'} {_lane(target, lane, s)} = {expr};")
        slots[outputs[0]] = (target, lane)
    return code, n_operations


def lane_jacobian(
    function: ca.Function, name: str, seed_input: int, n_rows: int, *, width: int = LANE_WIDTH, fast_trig: bool = True
):
    """The vectorised C of ``function`` (seed input ``seed_input`` of ``n_rows`` entries), or None.

    Parameters
    ----------
    function : casadi.Function
        SX; output 0 does not depend on the seed, outputs 1... are linear in it (J^T seed), each of
        which is written column-major as the n_rows-row Jacobian.
    name : str
        C symbol of the exported function this code replaces.
    seed_input : int
        Index of the seed input; the other inputs are read as CasADi passes them.
    n_rows : int
        Rows of every Jacobian (entries of the seed).
    width : {2, 4, 8}
        Doubles per vector; ``ceil(n_rows / width)`` sweeps run side by side.
    fast_trig : bool
        Call ``psdm_sin``/``psdm_cos`` (the export's inlined trig) instead of libm.

    Returns
    -------
    LaneJacobian or None
        None when the function holds an instruction this writer does not translate.

    Raises
    ------
    ParameterError
        For a width other than 2, 4 or 8, or a sparse output.
    """
    if width not in (2, 4, 8):
        raise ParameterError(f"lane_jacobian width must be 2, 4 or 8; got {width!r}. Pass LANE_WIDTH.")
    sparse = [function.name_out(i) for i in range(function.n_out()) if not function.sparsity_out(i).is_dense()]
    if sparse:
        raise ParameterError(
            f"lane_jacobian function outputs must be dense (they are written entry by entry); got sparse {sparse}. "
            "Wrap them in casadi.densify."
        )
    trig = "psdm_" if fast_trig else ""
    try:
        code, n_operations = _statements(function, seed_input, n_rows, width, trig)
    except _Unsupported:
        return None
    seeds = [
        f"  const vlane seed{r}_{s} = {{{', '.join('1' if r == width * s + m else '0' for m in range(width))}}};"
        for s in range(-(-n_rows // width))
        for r in range(n_rows)
    ]
    head = [
        f"/* {name}: reverse sweeps with Jacobian row i in lane i % {width} of sweep i / {width} "
        "(codegen.lane_derivatives). */",
        f"static int {name}_lanes(const casadi_real** arg, casadi_real** res) {{",
        f"  typedef casadi_real vlane __attribute__((vector_size({width} * sizeof(casadi_real))));",
        *seeds,
    ]
    return LaneJacobian(
        name=name,
        source="\n".join(head + code + ["  return 0;", "}", ""]),
        n_scalar_operations=n_operations[False],
        n_vector_operations=n_operations[True] * -(-n_rows // width),
    )
