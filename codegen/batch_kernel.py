"""The vector rewrite behind ``codegen.batch``: CasADi's straight-line scalar C as the same statements on
vectors of states, and the C tables, prototypes and header of the batch functions.

CasADi writes the code of an SX Function as assignments to scalars ``aK``; replacing ``casadi_real aK`` by a
vector of lane-width doubles (GCC/Clang vector extensions) makes every arithmetic statement evaluate one
state per lane unchanged. Loads read an input entry of all lanes, stores write each lane into its state's
output row, constants are splatted, and the few libm calls run lane by lane. Any other statement is
refused (``SolverError``) rather than translated by guess.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import casadi as ca

from psdm_casadi.errors import SolverError

_COMMENT = re.compile(r"^/\* (\w+):\(.*\)->\(.*\) \*/$")
_START = re.compile(r"^static int (casadi_f\d+)\(const casadi_real\*\* arg, casadi_real\*\* res, .*\{$")
_VAR = r"a\d+"
_NUMBER = r"-?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?"
_FUNCTIONS = ("psdm_sin", "psdm_cos", "sin", "cos", "tan", "sqrt", "fabs", "exp", "log", "tanh", "atan")
# (pattern, replacement) of every statement the rewrite understands, W being the lane width; a replacement
# None keeps the statement (vector arithmetic reads the same), a callable builds it from the match and the
# dense column-major position of each output non-zero.
_RULES = (
    (rf"^  casadi_real ({_VAR}(?:, {_VAR})*);$", r"  psdm_v \1;"),
    (
        r"^  casadi_real psdm_x\[(\d+)\], psdm_s\[\1\], psdm_c\[\1\];$",
        r"  casadi_real psdm_x[\1 * W], psdm_s[\1 * W], psdm_c[\1 * W];",
    ),
    (
        r"^  psdm_x\[(\d+)\]=arg\[(\d+)\]\? arg\[\2\]\[(\d+)\] : 0;$",
        r"  memcpy(psdm_x + \1 * W, x[\2] + \3 * W, W * sizeof(casadi_real));",
    ),
    (r"^  psdm_sincos_n\(psdm_x, psdm_s, psdm_c, (\d+)\);$", r"  psdm_sincos_n(psdm_x, psdm_s, psdm_c, \1 * W);"),
    (rf"^  ({_VAR})=psdm_(s|c)\[(\d+)\];$", r"  memcpy(&\1, psdm_\2 + \3 * W, sizeof(psdm_v));"),
    (rf"^  ({_VAR})=arg\[(\d+)\]\? arg\[\2\]\[(\d+)\] : 0;$", r"  memcpy(&\1, x[\2] + \3 * W, sizeof(psdm_v));"),
    (rf"^  ({_VAR})=({_NUMBER});$", r"  \1=psdm_splat(\2);"),
    (rf"^  ({_VAR})=\(({_VAR})[-+*/]({_VAR})\);$", None),
    (rf"^  ({_VAR})=\(-({_VAR})\);$", None),
    (rf"^  ({_VAR})=({_VAR});$", None),
    (rf"^  ({_VAR})=casadi_sq\(({_VAR})\);$", r"  \1=(\2*\2);"),
    (rf"^  ({_VAR})=({'|'.join(_FUNCTIONS)})\(({_VAR})\);$", r"  \1=psdm_v_\2(\3);"),
    (
        rf"^  if \(res\[(\d+)\]!=0\) res\[\1\]\[(\d+)\]=({_VAR});$",
        lambda m, index: (
            f"  PSDM_STORE(y + {m.group(1)} * W, {index[int(m.group(1))][int(m.group(2))]}, {m.group(3)});"
        ),
    ),
    (r"^  return 0;$", ""),
)
_COMPILED_RULES = tuple((re.compile(pattern), replacement) for pattern, replacement in _RULES)


def function_bodies(source_text: str) -> dict:
    """``{exported name: lines of its casadi_f<k> body}`` of a CasADi-generated C file.

    CasADi writes ``/* <name>:(inputs)->(outputs) */`` right above the ``static int casadi_f<k>`` that
    computes the exported function ``<name>``.
    """
    lines, bodies, k = source_text.split("\n"), {}, 0
    while k < len(lines) - 1:
        comment, start = _COMMENT.match(lines[k]), _START.match(lines[k + 1])
        if comment and start:
            end = lines.index("}", k + 1)
            bodies[comment.group(1)] = lines[k + 2 : end]
            k = end
        k += 1
    return bodies


def vectorise_body(body: list, kernel_name: str, out_index) -> tuple:
    """(C source of ``static void <kernel_name>(x, y)``, scalar functions it calls lane by lane).

    Parameters
    ----------
    body : list of str
        Lines of a CasADi ``casadi_f<k>`` body (``function_bodies``).
    kernel_name : str
    out_index : sequence of sequence of int
        Per output, the dense column-major position of each non-zero (``dense_index``).

    Raises
    ------
    SolverError
        On a statement the rewrite does not understand (it then refuses the function).
    """
    out, lanewise = [], set()
    for line in body:
        for pattern, replacement in _COMPILED_RULES:
            match = pattern.match(line)
            if match is None:
                continue
            if callable(replacement):
                out.append(replacement(match, out_index))
            else:
                out.append(line if replacement is None else match.expand(replacement))
                lanewise |= {match.group(2)} if "psdm_v_" in (replacement or "") else set()
            break
        else:
            raise SolverError(
                f"export_batch cannot vectorise {kernel_name}: CasADi wrote the statement {line.strip()!r}, which "
                "the batch rewrite does not handle. Export this function with export_c and loop over states."
            )
    head = [
        f"static void {kernel_name}(const casadi_real* const* x, casadi_real* const* y) {{",
        "  enum { W = PSDM_BATCH_W };",
    ]
    return "\n".join(head + out + ["}", ""]), lanewise


@dataclass(frozen=True)
class Signature:
    """Names and sizes of one exported function (theta dropped when baked in)."""

    name: str
    in_names: tuple
    in_sizes: tuple
    out_names: tuple
    out_sparsity: tuple

    @classmethod
    def of(cls, name: str, function: ca.Function, drop: str | None):
        keep = [i for i in range(function.n_in()) if function.name_in(i) != drop]
        return cls(
            name=name,
            in_names=tuple(function.name_in(i) for i in keep),
            in_sizes=tuple(function.nnz_in(i) for i in keep),
            out_names=tuple(function.name_out()),
            out_sparsity=tuple(function.sparsity_out(i) for i in range(function.n_out())),
        )


def dense_index(sparsity: ca.Sparsity) -> list:
    """Column-major position in the dense (rows, columns) output of each non-zero."""
    rows, columns = sparsity.get_triplet()
    return [int(c) * sparsity.size1() + int(r) for r, c in zip(rows, columns)]


def spec_code(name: str, signature: Signature, state_lanes: bool) -> str:
    """C tables and the ``psdm_batch_spec`` of one batch function (its vector kernel, or its single call)."""
    n_in, n_out = len(signature.in_names), len(signature.out_names)
    nnz = [s.nnz() for s in signature.out_sparsity]
    numel = [s.numel() for s in signature.out_sparsity]
    return "\n".join(
        [
            f"static const int {name}_in_size[] = {{{', '.join(map(str, signature.in_sizes))}}};",
            f"static const int {name}_out_nnz[] = {{{', '.join(map(str, nnz))}}};",
            f"static const int {name}_out_numel[] = {{{', '.join(map(str, numel))}}};",
            f"static const psdm_batch_spec {name}_spec = {{{name + '_lanes' if state_lanes else 'NULL'}, "
            f"{signature.name}, {signature.name}_work, {n_in}, {n_out}, "
            f"{name}_in_size, {name}_out_nnz, {name}_out_numel}};",
        ]
    )


def prototype(name: str, signature: Signature) -> str:
    ins = ", ".join(f"const casadi_real* {n}" for n in signature.in_names)
    outs = ", ".join(f"casadi_real* {n}" for n in signature.out_names)
    return f"int {name}({ins}, {outs}, long n_states, int n_threads)"


def wrapper_code(name: str, signature: Signature) -> str:
    n_in, n_out = len(signature.in_names), len(signature.out_names)
    return "\n".join(
        [
            f"{prototype(name, signature)} {{",
            f"  const casadi_real* in[{n_in}] = {{{', '.join(signature.in_names)}}};",
            f"  casadi_real* out[{n_out}] = {{{', '.join(signature.out_names)}}};",
            f"  return psdm_batch_run(&{name}_spec, in, out, n_states, n_threads);",
            "}",
            "",
        ]
    )


def header_code(library: str, prototypes: list) -> str:
    guard = f"{library.upper()}_BATCH_H"
    doc = (
        f"/* Batched functions of lib{library}: each takes its inputs and outputs as row-major arrays of\n"
        "   n_states rows (one state per row, as the single-call function reads or writes it: a matrix\n"
        "   output column-major) and n_threads (0: OpenMP's default, all cores unless OMP_NUM_THREADS says\n"
        "   otherwise). Returns 0; 1 for a negative count or a null array; 2 when a single-call evaluation\n"
        "   failed. Generated by codegen.batch. */"
    )
    return "\n".join(
        [
            doc,
            f"#ifndef {guard}",
            f"#define {guard}",
            "#ifndef casadi_real",
            "#define casadi_real double",
            "#endif",
            "#ifdef __cplusplus",
            'extern "C" {',
            "#endif",
            f"int {library}_batch_threads(void); /* threads used when n_threads is 0 */",
            f"int {library}_batch_width(void);   /* states per vector instruction */",
            *[p + ";" for p in prototypes],
            "#ifdef __cplusplus",
            "}",
            "#endif",
            "#endif",
            "",
        ]
    )
