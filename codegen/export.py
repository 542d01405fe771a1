"""export_c(): write the dynamics Functions as a self-contained C folder (last step of the flow:
DynamicsFunctions -> CExport).

The folder holds the CasADi-generated ``<library>.c``/``.h``, a ``Makefile`` and an example
``main.c`` that calls every function. Functions with a ``theta`` input are exported twice: with
theta baked in as constants (CasADi folds them, drops the zero products; the fastest flavour,
named ``<prefix><name>``) and with theta as a runtime input (``<prefix><name>_theta``).
Compiling is a separate step (``codegen.build``).
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from codegen.lane_regressor import LaneCount, lane_kernel, splice, splice_header
from codegen.operation_count import OperationCount, count_operations
from psdm_casadi.errors import ParameterError, ShapeError, SolverError

# Attributes of a DynamicsFunctions-like object that are exported, in this order.
EXPORTED_ATTRIBUTES = ("inverse_dynamics", "forward_dynamics", "regressor", "mass_matrix", "motor_torque",
                       "inverse_dynamics_at_temperature")  # fmt: skip
THETA_INPUT = "theta"
RUNTIME_SUFFIX = "_theta"
JACOBIAN_SUFFIX = "_jac"
_EXAMPLE_SEED = 0


@dataclass(frozen=True)
class CExport:
    """A generated C folder.

    Attributes
    ----------
    folder : Path
    library : str
        Base name: ``<library>.c``, ``<library>.h``, ``lib<library>.so`` after ``make``.
    header, source, example, build_file : Path
        The ``.h``, the ``.c``, the example ``main.c`` and the ``Makefile``.
    function_names : tuple of str
        C symbols of the exported functions, in the order they appear in the source.
    operation_counts : tuple of OperationCount
        One per exported function, same order.
    theta_baked : bool
        Whether the baked-theta flavour was exported.
    lane_regressor : LaneCount or None
        Size of the vectorised regressor when it was written (``lanes``), else None.
    """

    folder: Path
    library: str
    header: Path
    source: Path
    example: Path
    build_file: Path
    function_names: tuple
    operation_counts: tuple
    theta_baked: bool
    lane_regressor: LaneCount | None = None

    def __post_init__(self):
        if len(self.function_names) != len(self.operation_counts):
            raise ShapeError(
                f"CExport.operation_counts must have one entry per function ({len(self.function_names)}); "
                f"got {len(self.operation_counts)}. Build it with export_c."
            )

    @property
    def n_instructions(self) -> dict:
        """``{function name: n_instructions}`` (for reports and JSON)."""
        return {count.name: count.n_instructions for count in self.operation_counts}

    def operation_count(self, name: str) -> OperationCount:
        """The OperationCount of one exported function."""
        for count in self.operation_counts:
            if count.name == name:
                return count
        raise ParameterError(f"CExport.function_names must contain {name!r}; got {list(self.function_names)}.")


def _collect(functions) -> list:
    """The casadi Functions to export, from a Function, a sequence or a DynamicsFunctions-like object."""
    if isinstance(functions, ca.Function):
        found = [functions]
    elif isinstance(functions, (list, tuple)):
        found = list(functions)
    else:
        found = [getattr(functions, attr) for attr in EXPORTED_ATTRIBUTES if getattr(functions, attr, None) is not None]
    if not found:
        raise ParameterError(
            "export_c functions must be a casadi.Function, a non-empty sequence of them, or an object with "
            f"attributes {EXPORTED_ATTRIBUTES}; got {type(functions).__name__}. Pass build_functions(model)."
        )
    out = []
    for f in found:
        if not isinstance(f, ca.Function):
            raise ParameterError(
                f"export_c functions must contain only casadi.Function objects; got {type(f).__name__}. "
                "Pass the Functions of build_functions(model)."
            )
        out.append(f if f.is_a("SXFunction") else f.expand())
    names = [f.name() for f in out]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ParameterError(f"export_c functions must have distinct names; got duplicates {duplicates}. Rename them.")
    return out


def _symbolic_io(function):
    inputs = function.sx_in()
    outputs = function.call(inputs)
    return inputs, outputs


def _rebuild(name, function, inputs, outputs, drop_theta, cse):
    in_names = function.name_in()
    keep = [i for i, n in enumerate(in_names) if not (drop_theta and n == THETA_INPUT)]
    return ca.Function(
        name, [inputs[i] for i in keep], outputs, [in_names[i] for i in keep], function.name_out(), {"cse": bool(cse)}
    )


def _bake(function, theta, name, cse):
    """The Function with its theta input replaced by constants, so CasADi folds them."""
    inputs, _ = _symbolic_io(function)
    index = function.name_in().index(THETA_INPUT)
    expected = function.size_in(index)
    if theta.size != expected[0] * expected[1]:
        raise ShapeError(
            f"export_c theta must have {expected[0] * expected[1]} entries to match {function.name()}.theta; "
            f"got {theta.size}. Pass the base parameters of this model (model.base_parameters(...))."
        )
    args = list(inputs)
    args[index] = ca.DM(theta.reshape(expected, order="F"))
    outputs = function.call(args)
    return _rebuild(name, function, inputs, outputs, True, cse)


def _jacobian(function, name, cse):
    """Jacobians of every output with respect to every input except theta: outputs ``d<out>_d<in>``."""
    inputs, outputs = _symbolic_io(function)
    in_names, out_names = function.name_in(), function.name_out()
    jac, jac_names = [], []
    for o, oname in zip(outputs, out_names):
        for i, iname in zip(inputs, in_names):
            if iname == THETA_INPUT:
                continue
            jac.append(ca.jacobian(ca.vec(o), i))
            jac_names.append(f"d{oname}_d{iname}")
    return ca.Function(name, inputs, jac, in_names, jac_names, {"cse": bool(cse)})


def _check_name(value, field_name):
    if not isinstance(value, str) or not value.replace("_", "a").isalnum() or value[:1].isdigit():
        raise ParameterError(
            f"export_c {field_name} must be a C identifier (letters, digits, underscores, not starting with a digit); "
            f"got {value!r}. Use e.g. 'psdm_'."
        )


def _c_array(name, values):
    body = ", ".join(repr(float(v)) for v in values) if len(values) else "0.0"
    return f"static const casadi_real {name}[] = {{{body}}};"


def _example_code(functions, theta, rng):
    """C declarations of the example inputs and the calls of main()."""
    inputs, calls = [], []
    for k, f in enumerate(functions):
        names = []
        for i in range(f.n_in()):
            n = f.nnz_in(i)
            if f.name_in(i) == THETA_INPUT and theta is not None and theta.size == n:
                values = theta
            else:
                values = rng.uniform(-1.0, 1.0, n)
            var = f"input_{k}_{i}"
            inputs.append(_c_array(var, values))
            names.append(var)
        inputs.append(f"static const casadi_real* const inputs_{k}[] = {{{', '.join(names) or '0'}}};")
        calls.append(
            f"  {{ const function_t f = FUNCTION({f.name()}); failures += run(&f, inputs_{k}, timing) != 0; }}"
        )
    return "\n".join(inputs), "\n".join(calls)


_MATH_INCLUDE = "#include <math.h>\n"
_LIBM_TRIG_CALL = re.compile(r"(?<![A-Za-z0-9_])(sin|cos)\(")
_FUNCTION_START = re.compile(r"^static int casadi_f\d+\(.*\{$")
_DECLARATION = re.compile(r"^  (const )?casadi_(real|int)\b")
_INPUT_LOAD = re.compile(r"^  (a\d+)=arg\[(\d+)\]\? arg\[\2\]\[(\d+)\] : 0;$")
_TRIG_OF_VARIABLE = re.compile(r"^  (a\d+)=psdm_(sin|cos)\((a\d+)\);$")
_ASSIGNMENT = re.compile(r"^  (a\d+)=")
# Statements of CasADi's straight-line SX code other than assignments: outputs, return, end.
_OTHER_STATEMENT = re.compile(r"^(  if \(res\[\d+\]!=0\) res\[\d+\]\[\d+\]=a\d+;|  return 0;|}|)$")


def _hoist_input_trig(lines: list) -> list:
    """In one generated function, compute the sin/cos of input entries together at the top (psdm_sincos_n).

    CasADi writes straight-line code: ``aK=arg[i]? arg[i][m] : 0;`` loads an input entry and
    ``aJ=psdm_sin(aK);`` uses it. Following which variable holds which entry (until it is assigned
    again), every such call becomes a read of the precomputed ``psdm_s``/``psdm_c`` arrays.
    """
    holds, angles, out = {}, [], []
    body_start = 1
    while body_start < len(lines) and _DECLARATION.match(lines[body_start]):
        body_start += 1
    if any(not (_ASSIGNMENT.match(line) or _OTHER_STATEMENT.match(line)) for line in lines[body_start:]):
        return lines  # not the plain form this rewrite understands: keep the per-call psdm_sin/psdm_cos
    for line in lines:
        trig = _TRIG_OF_VARIABLE.match(line)
        if trig and trig.group(3) in holds:
            entry = holds[trig.group(3)]
            if entry not in angles:
                angles.append(entry)
            line = f"  {trig.group(1)}=psdm_{trig.group(2)[0]}[{angles.index(entry)}];"
        load = _INPUT_LOAD.match(line)
        assigned = _ASSIGNMENT.match(line)
        if assigned:
            holds.pop(assigned.group(1), None)
        if load:
            holds[load.group(1)] = (int(load.group(2)), int(load.group(3)))
        out.append(line)
    if not angles:
        return lines
    k = len(angles)
    setup = [f"  casadi_real psdm_x[{k}], psdm_s[{k}], psdm_c[{k}];"]
    setup += [f"  psdm_x[{index}]=arg[{i}]? arg[{i}][{m}] : 0;" for index, (i, m) in enumerate(angles)]
    setup.append(f"  psdm_sincos_n(psdm_x, psdm_s, psdm_c, {k});")
    return out[:body_start] + setup + out[body_start:]


def _inline_trig(source: Path) -> None:
    """Make a generated C file use the inlined sin/cos (psdm_sincos_n for input angles, psdm_sin/psdm_cos else)."""
    text = source.read_text()
    if _MATH_INCLUDE not in text:
        raise SolverError(f"CasADi's generated {source.name} has no '#include <math.h>'; export with fast_trig=False.")
    lines, out, function = _LIBM_TRIG_CALL.sub(r"psdm_\1(", text).split("\n"), [], None
    for line in lines:
        if function is None and _FUNCTION_START.match(line):
            function = [line]
        elif function is not None:
            function.append(line)
            if line == "}":
                out += _hoist_input_trig(function)
                function = None
        else:
            out.append(line)
    head, _, tail = "\n".join(out).partition(_MATH_INCLUDE)
    source.write_text(head + _MATH_INCLUDE + _template("fast_trig.c.in") + tail)


def _template(name):
    return (Path(__file__).parent / "templates" / name).read_text()


def _lane_kernel(sources, structure, lanes, name):
    """The LaneKernel of the regressor to splice in, or None: no structure, no regressor, lanes off, or
    (``"auto"``) not fewer operations than CasADi's scalar regressor."""
    if lanes not in ("auto", True, False):
        raise ParameterError(f"export_c lanes must be 'auto', True or False; got {lanes!r}.")
    regressors = [f for f in sources if f.name() == "regressor"]
    if not lanes or structure is None or not regressors:
        return None
    n_rows, n_columns = structure.chain.n_dof, structure.preimage.shape[1]
    if regressors[0].size_out(0) != (n_rows, n_columns):
        raise ParameterError(
            f"export_c regressor_structure describes a {n_rows}x{n_columns} regressor but the regressor Function "
            f"returns {regressors[0].size_out(0)}. Pass the structure of the same build_recursive_functions call."
        )
    kernel = lane_kernel(structure, name)
    if lanes == "auto" and kernel.count.n_operations >= count_operations(regressors[0]).n_operations:
        return None
    return kernel


def _splice_kernels(source: Path, header: Path, kernels) -> None:
    """Splice each (vector code, C symbol) beside CasADi's scalar code of that symbol (``lane_regressor.splice``)."""
    for kernel, name in kernels:
        source.write_text(splice(source.read_text(), kernel, name))
        header.write_text(splice_header(header.read_text(), name))


def export_c(
    functions,
    folder,
    *,
    theta=None,
    runtime_theta=True,
    jacobians=False,
    library="psdm_dynamics",
    prefix="psdm_",
    cse=True,
    fast_trig=True,
    lanes="auto",
    regressor_structure=None,
    kernels=(),
    overwrite=False,
) -> CExport:
    """Generate a self-contained C folder for the dynamics Functions.

    Parameters
    ----------
    functions : DynamicsFunctions-like, casadi.Function or sequence of casadi.Function
        With a DynamicsFunctions (``build_functions(model)``) the exported ones are
        ``inverse_dynamics, forward_dynamics, regressor, mass_matrix`` (and ``motor_torque`` when set).
    folder : str or Path
        Output folder; created if missing.
    theta : array, shape (n_base,), optional
        Base parameters to bake in as constants. Without it only the runtime flavour is written.
    runtime_theta : bool
        Also export the flavour with theta as a runtime input (``<prefix><name>_theta``).
    jacobians : bool
        Also export ``<function>_jac`` with the Jacobians of each output with respect to each
        non-theta input (``d<out>_d<in>``, each of shape (nnz(out), numel(in))).
    library : str
        Base name of the ``.c``/``.h`` files and of the shared library.
    prefix : str
        Prefix of every C symbol.
    cse : bool
        Let CasADi eliminate common subexpressions (shared products and trig terms).
    fast_trig : bool
        Replace libm's ``sin``/``cos`` in the generated code by inlined ones (``psdm_sin``/``psdm_cos``:
        Cody-Waite reduction and minimax polynomials, within a few ulp of libm; libm beyond
        ``|x| >= 2^17``). Calling libm costs most of the time of a small robot's inverse dynamics.
    lanes : {"auto", True, False}
        Write the regressor with its joint rows in vector lanes (``codegen.lane_regressor``) when its
        structure is known: ``regressor_structure``, or that of a DynamicsFunctions built by
        ``build_recursive_functions``. ``"auto"`` does so when the vector code plus its scalar parts
        have fewer operations than CasADi's scalar regressor (a small scalar regressor stays scalar).
        CasADi's scalar code stays in the file as the fallback (compilers without vector extensions, or
        ``-DPSDM_NO_LANES``).
    regressor_structure : psdm_casadi.recursive.RegressorStructure, optional
        The structure of the exported ``regressor`` Function, when ``functions`` is a list.
    kernels : sequence of codegen.lane_derivatives.LaneJacobian
        Vector code of exported functions (``codegen.derivatives.lane_kernels``), spliced beside CasADi's
        scalar code like the regressor's (not when ``lanes`` is False).
    overwrite : bool
        Allow writing into a non-empty folder (files of the same name are replaced).

    Returns
    -------
    CExport

    Raises
    ------
    FileExistsError
        When ``folder`` is not empty and ``overwrite`` is False.
    ParameterError
        For a bad ``functions``, ``library`` or ``prefix``.
    ShapeError
        When ``theta`` does not match the functions' theta input.

    Examples
    --------
    >>> export = export_c(build_functions(model), "out", theta=theta)     # doctest: +SKIP
    >>> export.n_instructions["psdm_inverse_dynamics"]                    # doctest: +SKIP
    """
    _check_name(library, "library")
    _check_name(prefix + "x", "prefix")
    sources = _collect(functions)
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise FileExistsError(f"export_c folder {str(folder)!r} is a file. Pass a folder path.")
    if folder.is_dir() and any(folder.iterdir()) and not overwrite:
        raise FileExistsError(f"export_c folder {str(folder)!r} is not empty. Pass overwrite=True or another folder.")
    if theta is not None:
        theta = np.asarray(theta, dtype=float).ravel()
        if not np.all(np.isfinite(theta)):
            raise ParameterError("export_c theta must be finite; got NaN or inf. Pass identified base parameters.")
    has_theta = [THETA_INPUT in f.name_in() for f in sources]
    if theta is not None and not any(has_theta):
        raise ParameterError(
            "export_c theta must be None when no function has a theta input; got theta with "
            f"{theta.size} values. Drop theta (these functions already have their parameters compiled in)."
        )
    if not runtime_theta and theta is None and any(has_theta):
        raise ParameterError(
            "export_c runtime_theta must be True when no theta is given; got runtime_theta=False, theta=None. "
            "Pass theta to bake it in."
        )

    if regressor_structure is None:
        regressor_structure = getattr(functions, "regressor_structure", None)
    lane_name = prefix + "regressor"
    kernel = _lane_kernel(sources, regressor_structure, lanes, lane_name)

    exported = []
    for f, takes_theta in zip(sources, has_theta):
        name = prefix + f.name()
        if not takes_theta:
            inputs, outputs = _symbolic_io(f)
            exported.append(_rebuild(name, f, inputs, outputs, False, cse))
            continue
        if theta is not None:
            exported.append(_bake(f, theta, name, cse))
        if runtime_theta:
            inputs, outputs = _symbolic_io(f)
            exported.append(_rebuild(name + RUNTIME_SUFFIX, f, inputs, outputs, False, cse))
    if jacobians:
        exported += [_jacobian(f, f.name() + JACOBIAN_SUFFIX, cse) for f in list(exported)]

    folder.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".export-", dir=folder))
    try:
        generator = ca.CodeGenerator(f"{library}.c", {"with_header": True})
        for f in exported:
            generator.add(f)
        if kernel is not None:
            generator.add(kernel.parts)
        generator.generate(str(staging) + os.sep)
        if fast_trig:
            _inline_trig(staging / f"{library}.c")
        spliced = ([(kernel, lane_name)] if kernel is not None else []) + [(k, k.name) for k in kernels if lanes]
        _splice_kernels(staging / f"{library}.c", staging / f"{library}.h", spliced)
        input_code, call_code = _example_code(exported, theta, np.random.default_rng(_EXAMPLE_SEED))
        main_c = _template("main.c.in").replace("@LIBRARY@", library).replace("@INPUTS@", input_code)
        (staging / "main.c").write_text(main_c.replace("@CALLS@", call_code))
        (staging / "Makefile").write_text(_template("Makefile.in").replace("@LIBRARY@", library))
        for item in (f"{library}.c", f"{library}.h", "main.c", "Makefile"):
            os.replace(staging / item, folder / item)
    finally:
        shutil.rmtree(staging, ignore_errors=True)

    return CExport(
        folder=folder,
        library=library,
        header=folder / f"{library}.h",
        source=folder / f"{library}.c",
        example=folder / "main.c",
        build_file=folder / "Makefile",
        function_names=tuple(f.name() for f in exported),
        operation_counts=tuple(count_operations(f) for f in exported),
        theta_baked=theta is not None and any(has_theta),
        lane_regressor=None if kernel is None else kernel.count,
    )
