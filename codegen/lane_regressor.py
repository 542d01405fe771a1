"""The regressor Y(q, qd, qdd) as vectorised C: joint rows in SIMD lanes, four at a time.

CasADi's generated regressor is scalar code, and on a 7-DOF arm its time is bound by instruction
throughput, not latency (two states evaluated in one call take as long per state as one). Written
from a ``RegressorStructure`` instead, most of the work runs four joint rows per instruction:

- a CasADi function (``<name>_parts``, scalar) computes the forward pass and the distinct scalars the
  rest needs: the entries of each joint rotation and the unit-parameter wrench of every kept standard
  parameter;
- the vector code (GCC/Clang vector extensions, 4 doubles) carries the unit motions of all ancestor
  joints of frame j in lanes (one lane per joint row), takes their dot product with each unit wrench,
  and writes each column of Y as ``sum_r T[r, c] y_r``, one vector per four rows.

Compilers without vector extensions, or ``-DPSDM_NO_LANES``, keep CasADi's scalar code. The two agree
to rounding (checked by the tests against the Python model).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import casadi as ca
import numpy as np

from codegen.operation_count import OperationCount, count_operations
from psdm_casadi.errors import SolverError
from psdm_casadi.newton_euler import ROTOR_INERTIA
from psdm_casadi.oracle import N_PARAMETERS_PER_JOINT

# Four doubles, one AVX2 register (the lane widths compared are in the README's results).
LANES = 4
# (component of a, component of p, sign) of each component of the cross product a x p.
_CROSS = (((1, 2, 1.0), (2, 1, -1.0)), ((2, 0, 1.0), (0, 2, -1.0)), ((0, 1, 1.0), (1, 0, -1.0)))
_GUARD = "PSDM_LANES"


@dataclass(frozen=True)
class LaneCount:
    """Size of a vectorised regressor (``CExport.lane_regressor``): its scalar parts and its vector code.

    Attributes
    ----------
    name : str
        C symbol of the regressor.
    n_scalars : int
        Scalars computed by ``<name>_parts`` and read by the vector code.
    parts : OperationCount
        Of ``<name>_parts``.
    n_vector_operations : int
        Multiplications, additions and negations written in the vector code (each on four lanes).
    """

    name: str
    n_scalars: int
    parts: OperationCount
    n_vector_operations: int

    @property
    def n_operations(self) -> int:
        """Scalar plus vector operations: what ``export_c(lanes="auto")`` compares with the scalar regressor."""
        return self.parts.n_operations + self.n_vector_operations


@dataclass(frozen=True)
class LaneKernel:
    """The vectorised regressor of one structure.

    Attributes
    ----------
    parts : casadi.Function
        (q, qd, qdd) -> the scalars the vector code reads; exported as ``<name>_parts``.
    source : str
        C code of ``static int <name>_lanes(const casadi_real** arg, casadi_real** res)``.
    count : LaneCount
    """

    parts: ca.Function
    source: str
    count: LaneCount


class _Scalars:
    """The distinct non-constant SX scalars the vector code reads, as ``P[k]``; constants become literals."""

    def __init__(self):
        self.values, self._index = [], {}

    def ref(self, expr) -> str | None:
        """C expression of a scalar SX, None for an exact zero."""
        expr = ca.SX(expr)
        if expr.is_zero():
            return None
        if expr.is_constant():
            return repr(float(expr))
        key = expr.element_hash()
        if key not in self._index:
            self._index[key] = len(self.values)
            self.values.append(expr)
        return f"P[{self._index[key]}]"


def _ancestors(parents, joint) -> list:
    """Joint itself and every ancestor, tip to base."""
    chain = []
    while joint >= 0:
        chain.append(joint)
        joint = parents[joint]
    return chain


def _sum(terms) -> str:
    return " + ".join(terms) if terms else "zero"


def _vector(kind: str, joint: int, axis: int, block: int) -> str:
    """C name of component ``axis`` of vector ``kind`` (a, b, t) at frame ``joint``, rows of lane block ``block``."""
    return f"{kind}{joint}_{axis}_{block}"


def _motion_code(chain, blocks, scalars) -> list:
    """Unit motion of every ancestor joint i at frame j, one lane per row i: a (angular), b (linear at the origin)."""
    code = []
    for j in range(chain.n_dof):
        parent, rotation, shift = chain.parents[j], chain.rotations[j], chain.translations[j]
        for block in blocks[j]:
            if parent < 0 or block not in blocks[parent]:
                code += [
                    f"  v4 {_vector('a', j, d, block)} = zero, {_vector('b', j, d, block)} = zero;" for d in range(3)
                ]
            else:
                for d in range(3):  # t = b_parent + a_parent x p, then a = R^T a_parent, b = R^T t
                    terms = [_vector("b", parent, d, block)]
                    for a_axis, p_axis, sign in _CROSS[d]:
                        factor = scalars.ref(sign * shift[p_axis])
                        if factor is not None:
                            terms.append(f"{_vector('a', parent, a_axis, block)} * {factor}")
                    code.append(f"  const v4 {_vector('t', j, d, block)} = {_sum(terms)};")
                for d in range(3):
                    a_terms, b_terms = [], []
                    for e in range(3):
                        factor = scalars.ref(rotation[e, d])
                        if factor is not None:
                            a_terms.append(f"{_vector('a', parent, e, block)} * {factor}")
                            b_terms.append(f"{_vector('t', j, e, block)} * {factor}")
                    code.append(f"  v4 {_vector('a', j, d, block)} = {_sum(a_terms)};")
                    code.append(f"  v4 {_vector('b', j, d, block)} = {_sum(b_terms)};")
            if j // LANES == block:  # joint j's own row: its axis
                axis = np.asarray(ca.DM(chain.axes[j])).ravel()
                target = "a" if chain.revolute[j] else "b"
                code += [
                    f"  {_vector(target, j, d, block)}[{j % LANES}] += {float(axis[d])!r};"
                    for d in np.flatnonzero(axis)
                ]
    return code


def _dot_code(structure, blocks, scalars) -> list:
    """y_r = a . moment_r + b . force_r, lanes = rows, for each link parameter the preimage uses."""
    code = []
    for row in np.flatnonzero(np.any(np.asarray(structure.preimage) != 0, axis=1)):
        joint, kind = divmod(int(row), N_PARAMETERS_PER_JOINT)
        if kind == ROTOR_INERTIA:
            continue
        if row not in structure.unit_wrenches:
            raise SolverError(f"lane_kernel: the structure has no unit wrench for preimage row {row}; rebuild it.")
        force, moment = structure.unit_wrenches[row]
        for block in blocks[joint]:
            terms = []
            for kind_name, part in (("a", moment), ("b", force)):
                for d in range(3):
                    factor = scalars.ref(part[d])
                    if factor is not None:
                        terms.append(f"{_vector(kind_name, joint, d, block)} * {factor}")
            code.append(f"  const v4 y{row}_{block} = {_sum(terms)};")
    return code


def _column_code(structure, blocks, scalars) -> list:
    """Each column of Y as sum_r T[r, c] y_r, stored four rows at a time.

    A block's spare lanes run into the next column, which is stored after it; the last store is cut to
    the end of Y.
    """
    preimage, qdd = np.asarray(structure.preimage), structure.inputs[2]
    n, n_base = structure.chain.n_dof, preimage.shape[1]
    code = []
    for column in range(n_base):
        for block in range((n + LANES - 1) // LANES):
            terms = []
            for row in np.flatnonzero(preimage[:, column]):
                joint, kind = divmod(int(row), N_PARAMETERS_PER_JOINT)
                coefficient = float(preimage[row, column])
                if kind == ROTOR_INERTIA:  # rotor inertia: qdd_j on row j only
                    if joint // LANES == block:
                        terms.append(f"lane{joint % LANES} * ({coefficient!r} * {scalars.ref(qdd[joint])})")
                elif block in blocks[joint]:
                    y = f"y{row}_{block}"
                    terms.append(
                        y if coefficient == 1.0 else f"(-{y})" if coefficient == -1.0 else f"{y} * {coefficient!r}"
                    )
            offset = column * n + LANES * block
            code.append(
                f"  {{ const v4 column = {_sum(terms)}; memcpy(Y + {offset}, &column, "
                f"{min(LANES, n * n_base - offset)} * sizeof(casadi_real)); }}"
            )
    return code


def lane_kernel(structure, name: str) -> LaneKernel:
    """Vector code and scalar parts of the regressor described by ``structure``.

    Parameters
    ----------
    structure : psdm_casadi.recursive.RegressorStructure
    name : str
        C name of the regressor; the code defines ``<name>_lanes`` and calls ``<name>_parts``.
    """
    chain = structure.chain
    blocks = {j: sorted({i // LANES for i in _ancestors(chain.parents, j)}) for j in range(chain.n_dof)}
    scalars = _Scalars()
    code = (
        _motion_code(chain, blocks, scalars)
        + _dot_code(structure, blocks, scalars)
        + _column_code(structure, blocks, scalars)
    )
    parts = ca.Function(
        f"{name}_parts",
        list(structure.inputs),
        [ca.vertcat(*scalars.values)],
        ["q", "qd", "qdd"],
        ["scalars"],
        {"cse": True},
    )
    head = [
        f"/* {name}: Y with the joint rows in vector lanes (codegen.lane_regressor); scalars from {name}_parts. */",
        f"static int {name}_lanes(const casadi_real** arg, casadi_real** res) {{",
        f"  typedef casadi_real v4 __attribute__((vector_size({LANES} * sizeof(casadi_real))));",
        f"  casadi_real P[{max(len(scalars.values), 1)}];",
        "  casadi_real* parts_res[1] = {P};",
        "  casadi_real* Y = res[0];",
        "  const v4 zero = {0};",
        *[f"  const v4 lane{k} = {{{', '.join('1' if m == k else '0' for m in range(LANES))}}};" for k in range(LANES)],
        "  if (!Y) return 0;",
        f"  if ({name}_parts(arg, parts_res, 0, 0, 0)) return 1;",
    ]
    n_vector_operations = sum(line.count(" * ") + line.count(" + ") + line.count("(-") for line in code)
    count = LaneCount(
        name=name, n_scalars=len(scalars.values), parts=count_operations(parts), n_vector_operations=n_vector_operations
    )
    return LaneKernel(parts=parts, source="\n".join(head + code + ["  return 0;", "}", ""]), count=count)


def splice(source_text: str, kernel: LaneKernel, name: str) -> str:
    """Generated C with ``<name>`` calling ``<name>_lanes`` where vector extensions are available.

    The exported ``<name>`` keeps CasADi's metadata functions and its scalar code as the fallback;
    ``<name>_lanes_enabled()`` says which one a build uses.
    """
    wrapper = re.compile(
        r"(CASADI_SYMBOL_EXPORT int " + re.escape(name) + r"\(const casadi_real\*\* arg, casadi_real\*\* res, "
        r"casadi_int\* iw, casadi_real\* w, int mem\)\{\n)(  return (casadi_f\d+)\(arg, res, iw, w, mem\);\n)(\})"
    )
    match = wrapper.search(source_text)
    if match is None:
        raise SolverError(f"CasADi's generated code has no wrapper for {name}; export with lanes=False.")
    guard = (
        f"#if !defined(PSDM_NO_LANES) && (defined(__GNUC__) || defined(__clang__))\n#define {_GUARD}\n"
        "#include <string.h>\n"
        f"int {name}_parts(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem);\n"
        f"{kernel.source}#endif\n\n"
    )
    body = (
        f"#ifdef {_GUARD}\n  (void)iw; (void)w; (void)mem; (void){match.group(3)};\n"
        f"  return {name}_lanes(arg, res);\n#else\n"
        f"{match.group(2)}#endif\n"
    )
    marker = (
        f"\n\n/* 1 when {name} runs the vector code, 0 when CasADi's scalar code. */\n"
        f"CASADI_SYMBOL_EXPORT int {name}_lanes_enabled(void) {{\n#ifdef {_GUARD}\n  return 1;\n#else\n"
        "  return 0;\n#endif\n}"
    )
    return (
        source_text[: match.start()]
        + guard
        + match.group(1)
        + body
        + match.group(4)
        + marker
        + source_text[match.end() :]
    )


def splice_header(header_text: str, name: str) -> str:
    """The generated header with the prototype of ``<name>_lanes_enabled``."""
    closing = '#ifdef __cplusplus\n} /* extern "C" */'
    if closing not in header_text:
        raise SolverError('CasADi\'s generated header has no extern "C" block; export with lanes=False.')
    head, _, tail = header_text.rpartition(closing)
    return f"{head}int {name}_lanes_enabled(void);\n{closing}{tail}"
