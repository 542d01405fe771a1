"""export_batch(): the exported dynamics for N states per call, vectorised across states and threaded
(DynamicsFunctions -> BatchExport, beside ``export_c``; compiled and called on numpy arrays by
``codegen.batch_library``).

The single-call C of ``export_c`` evaluates one state at a time in straight-line scalar code. Written
again (``codegen.batch_kernel``) with every scalar replaced by a vector of ``lane_width`` doubles
(GCC/Clang vector extensions, one state per lane, as ``codegen.lane_regressor`` puts joint rows in
lanes), the same instructions evaluate ``lane_width`` states at once: inverse dynamics, forward
dynamics (divisions included) and the regressor alike. The sin/cos of the joint angles keep the
inlined ``psdm_sincos_n`` (over all lanes); other calls (rare) run lane by lane. Blocks of
``lane_width`` states are shared between threads by OpenMP; the pool must stay awake between calls (libgomp's
default, or ``OMP_WAIT_POLICY=ACTIVE``): with ``PASSIVE`` every call of ~1000 states pays a thread wake-up
as long as its work, and two threads run slower than one. The rewrite understands exactly the
statements CasADi writes for SX Functions and refuses anything else (``SolverError``), so it never
computes something else silently. A function whose outputs outweigh its arithmetic (a small robot's
regressor) calls its single-call C state by state instead, its joint rows still in lanes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import casadi as ca

from codegen.batch_kernel import (
    Signature,
    dense_index,
    function_bodies,
    header_code,
    prototype,
    spec_code,
    vectorise_body,
    wrapper_code,
)
from codegen.export import EXPORTED_ATTRIBUTES, CExport, export_c
from codegen.lane_regressor import LANES
from psdm_casadi.errors import ParameterError, SolverError
from psdm_casadi.fileio import atomic_write

# The functions a batch export evaluates by default (the mass matrix is left to the single-call library).
BATCH_ATTRIBUTES = EXPORTED_ATTRIBUTES[:3]
BATCH_SUFFIX = "_batch"
LANE_WIDTHS = (2, 4, 8)
# Below this many operations per output entry, a function's batch calls its single-call C state by state
# (export_batch(state_lanes="auto")): storing each lane's outputs separately then costs more than the lanes save.
STATE_LANES_OPERATIONS_PER_OUTPUT = 4
MAX_ARGUMENTS = 8  # inputs or outputs of one function (the block buffers of batch.c.in)
_TEMPLATES = Path(__file__).parent / "templates"


@dataclass(frozen=True)
class BatchExport:
    """A C folder with the single-call export and its batched functions.

    Attributes
    ----------
    single : CExport
        The single-call export (``<library>.c``/``.h``) the batch functions reproduce.
    source, header : Path
        ``<library>_batch.c`` and ``<library>_batch.h``.
    function_names : tuple of str
        C symbols of the batch functions (``<single name>_batch``).
    single_names : tuple of str
        The single-call function each one evaluates, same order.
    base_names : tuple of str
        The names of the casadi Functions (``inverse_dynamics``), same order.
    lane_width : int
        States per vector instruction.
    state_lanes : tuple of bool
        Per batch function: whether it runs the vector kernel (else the single call, state by state).
    in_sizes, out_shapes : tuple of tuple
        Per batch function: entries of each input per state, and (rows, columns) of each output.
    in_names, out_names : tuple of tuple of str
        Per batch function: the names of its inputs and outputs.
    """

    single: CExport
    source: Path
    header: Path
    function_names: tuple
    single_names: tuple
    base_names: tuple
    lane_width: int
    state_lanes: tuple
    in_sizes: tuple
    out_shapes: tuple
    in_names: tuple
    out_names: tuple

    def __post_init__(self):
        lengths = {
            len(v)
            for v in (
                self.single_names,
                self.base_names,
                self.state_lanes,
                self.in_sizes,
                self.out_shapes,
                self.in_names,
                self.out_names,
            )
        }
        if lengths != {len(self.function_names)}:
            raise ParameterError(
                "BatchExport fields must have one entry per batch function; got differing lengths. Use export_batch."
            )

    @property
    def folder(self) -> Path:
        return self.single.folder

    @property
    def library(self) -> str:
        return self.single.library


def _check_functions(functions) -> list:
    """The casadi Functions to batch: a DynamicsFunctions-like object's three, or a Function sequence."""
    if isinstance(functions, ca.Function):
        functions = [functions]
    if not isinstance(functions, (list, tuple)):
        functions = [getattr(functions, a) for a in BATCH_ATTRIBUTES if getattr(functions, a, None) is not None]
    if not functions or not all(isinstance(f, ca.Function) for f in functions):
        raise ParameterError(
            "export_batch functions must be a DynamicsFunctions-like object with "
            f"{BATCH_ATTRIBUTES}, or a non-empty sequence of casadi.Function; got {type(functions).__name__}. "
            "Pass build_recursive_functions(model, robot)."
        )
    for f in functions:
        if f.n_in() > MAX_ARGUMENTS or f.n_out() > MAX_ARGUMENTS:
            raise ParameterError(
                f"export_batch functions must have at most {MAX_ARGUMENTS} inputs and outputs; {f.name()} has "
                f"{f.n_in()} and {f.n_out()}. Split it."
            )
        dense = all(f.sparsity_in(i).is_dense() for i in range(f.n_in()))
        if not dense:
            raise ParameterError(f"export_batch functions must have dense inputs; {f.name()} does not. Densify them.")
    return list(functions)


def _use_state_lanes(state_lanes, signature: Signature, count) -> bool:
    """Whether a batch function runs the vector kernel (``export_batch(state_lanes=...)``)."""
    if not all(sparsity.is_dense() for sparsity in signature.out_sparsity):
        return True
    if state_lanes == "auto":
        n_outputs = sum(sparsity.nnz() for sparsity in signature.out_sparsity)
        return count.n_operations >= STATE_LANES_OPERATIONS_PER_OUTPUT * n_outputs
    return state_lanes


def _template(name: str) -> str:
    return (_TEMPLATES / name).read_text()


def export_batch(
    functions,
    folder,
    *,
    theta=None,
    lane_width: int = LANES,
    state_lanes="auto",
    library: str = "psdm_dynamics",
    prefix: str = "psdm_",
    lanes="auto",
    regressor_structure=None,
    overwrite: bool = False,
) -> BatchExport:
    """Write the single-call C export and, beside it, the same functions for N states per call.

    Parameters
    ----------
    functions : DynamicsFunctions-like, casadi.Function or sequence of casadi.Function
        With a DynamicsFunctions (``build_recursive_functions(model, robot)``) the batched ones are
        ``inverse_dynamics, forward_dynamics, regressor``.
    folder : str or Path
        Output folder (new or empty unless ``overwrite``).
    theta : array, shape (n_base,), optional
        Base parameters baked into the functions that take ``theta``; required when any does.
    lane_width : {2, 4, 8}
        States per vector instruction (4 doubles: AVX2; 8: AVX-512).
    state_lanes : {"auto", True, False}
        Evaluate each function with its states in vector lanes (True), or call its single-call C state by
        state (False; the regressor's joint rows stay in lanes, see ``lanes``). ``"auto"`` takes the vector
        kernel unless the function's outputs outweigh its arithmetic (fewer than STATE_LANES_OPERATIONS_PER_OUTPUT
        operations per output entry, as in a small robot's regressor), where writing each lane's outputs one
        by one costs more than the vector arithmetic saves, or CasADi wrote a statement the rewrite does not
        handle; a function with sparse outputs always takes it.
    library, prefix, lanes, regressor_structure :
        As in ``export_c`` (the single-call library; ``lanes`` is its joint-row regressor).
    overwrite : bool
        Allow writing into a non-empty folder.

    Returns
    -------
    BatchExport
        ``<library>.c``/``.h`` (single call, ``export_c``), ``<library>_batch.c``/``.h`` with
        ``<prefix><name>_batch(inputs..., outputs..., n_states, n_threads)``, and a Makefile that builds
        both into ``lib<library>.so`` with OpenMP.

    Raises
    ------
    ParameterError
        For bad ``functions``, ``lane_width`` or a missing ``theta``; and as ``export_c``.
    SolverError
        When CasADi writes a statement the batch rewrite does not handle, in a function that must take the
        vector kernel (``state_lanes=True``, or sparse outputs).

    Examples
    --------
    >>> export = export_batch(build_recursive_functions(model, robot), "out", theta=theta)  # doctest: +SKIP
    >>> library = build_batch(export)                                                     # doctest: +SKIP
    >>> tau = library.inverse_dynamics(q, qd, qdd)              # q, qd, qdd: (N, n_dof)   # doctest: +SKIP
    """
    sources = _check_functions(functions)
    _check_batch_options(lane_width, state_lanes)
    if any("theta" in f.name_in() for f in sources) and theta is None:
        raise ParameterError(
            "export_batch theta must be given when a function takes theta; got None. Pass the base parameters "
            "(model.base_parameters(robot.nominal_dynamic_parameters()) or identified ones)."
        )
    if regressor_structure is None and not isinstance(functions, (list, tuple, ca.Function)):
        regressor_structure = getattr(functions, "regressor_structure", None)
    single = export_c(
        sources,
        folder,
        theta=theta,
        runtime_theta=False,
        library=library,
        prefix=prefix,
        lanes=lanes,
        regressor_structure=regressor_structure,
        overwrite=overwrite,
    )
    return add_batch(single, sources, prefix=prefix, lane_width=lane_width, state_lanes=state_lanes)


def _check_batch_options(lane_width, state_lanes) -> None:
    if lane_width not in LANE_WIDTHS:
        raise ParameterError(f"export_batch lane_width must be one of {LANE_WIDTHS}; got {lane_width!r}. Pass 4.")
    if state_lanes not in ("auto", True, False):
        raise ParameterError(f"export_batch state_lanes must be 'auto', True or False; got {state_lanes!r}.")


def _signatures(single: CExport, sources, prefix: str) -> list:
    """The Signature of each function in the single-call export (theta dropped when baked in)."""
    signatures = []
    for f in sources:
        name = prefix + f.name()
        if "theta" in f.name_in() and not single.theta_baked:
            raise ParameterError(
                f"add_batch needs theta baked into the export for {f.name()}; got an export without it. Export "
                "with theta (export_c(theta=...), psdm codegen --theta or a robot with nominal inertia)."
            )
        if name not in single.function_names:
            raise ParameterError(
                f"add_batch functions must be in the export; {name!r} is not in {list(single.function_names)}. "
                "Pass the functions and prefix given to export_c."
            )
        signatures.append(Signature.of(name, f, "theta"))
    return signatures


def add_batch(single: CExport, functions, *, prefix: str = "psdm_", lane_width: int = LANES, state_lanes="auto"):
    """Write ``<library>_batch.c``/``.h`` (and a Makefile building both) beside a single-call export.

    Parameters
    ----------
    single : CExport
        An ``export_c`` folder holding the functions (theta baked in where they take it).
    functions : DynamicsFunctions-like, casadi.Function or sequence of casadi.Function
        The Functions given to ``export_c`` (a DynamicsFunctions: its inverse and forward dynamics and
        regressor).
    prefix, lane_width, state_lanes :
        As in ``export_batch``.

    Returns
    -------
    BatchExport

    Raises
    ------
    ParameterError
        For a ``single`` that is not a CExport, a function not in it, or one taking theta when it has no
        baked theta.
    SolverError
        As ``export_batch``.
    """
    if not isinstance(single, CExport):
        raise ParameterError(f"add_batch single must be a CExport; got {type(single).__name__}. Pass export_c(...).")
    sources = _check_functions(functions)
    _check_batch_options(lane_width, state_lanes)
    signatures = _signatures(single, sources, prefix)
    bodies = function_bodies(single.source.read_text())
    kernels, lanewise, specs, wrappers, in_lanes = [], set(), [], [], []
    for signature in signatures:
        name = signature.name + BATCH_SUFFIX
        in_lanes.append(_use_state_lanes(state_lanes, signature, single.operation_count(signature.name)))
        if in_lanes[-1]:
            index = [dense_index(sparsity) for sparsity in signature.out_sparsity]
            try:
                kernel, used = vectorise_body(bodies[signature.name], f"{name}_lanes", index)
            except SolverError:
                if state_lanes is True or not all(x.is_dense() for x in signature.out_sparsity):
                    raise
                in_lanes[-1], kernel, used = False, "", set()  # "auto": the single call, state by state
            kernels.append(kernel)
            lanewise |= used
        specs.append(spec_code(name, signature, in_lanes[-1]))
        wrappers.append(wrapper_code(name, signature))
    names = tuple(s.name + BATCH_SUFFIX for s in signatures)
    library = single.library
    source = (
        _template("batch.c.in")
        .replace("@FAST_TRIG@", _template("fast_trig.c.in"))
        .replace("@WIDTH@", str(lane_width))
        .replace("@MAX_IN@", str(max(sum(s.in_sizes) for s in signatures)))
        .replace("@MAX_NUMEL@", str(max(x.numel() for s in signatures for x in s.out_sparsity)))
        .replace("@LANEWISE@", "\n".join(f"PSDM_LANEWISE({f})" for f in sorted(lanewise)))
        .replace("@KERNELS@", "\n".join(kernels + specs))
        .replace("@WRAPPERS@", "\n".join(wrappers))
        .replace("@LIBRARY@", library)
    )
    header = header_code(library, [prototype(n, s) for n, s in zip(names, signatures)])
    batch_source = single.folder / f"{library}{BATCH_SUFFIX}.c"
    batch_header = single.folder / f"{library}{BATCH_SUFFIX}.h"
    atomic_write(batch_header, lambda handle: handle.write(header), overwrite=True)
    atomic_write(batch_source, lambda handle: handle.write(source), overwrite=True)
    makefile = _template("batch_Makefile.in").replace("@LIBRARY@", library)
    atomic_write(single.build_file, lambda handle: handle.write(makefile), overwrite=True)
    return BatchExport(
        single=single,
        source=batch_source,
        header=batch_header,
        function_names=names,
        single_names=tuple(s.name for s in signatures),
        base_names=tuple(f.name() for f in sources),
        lane_width=lane_width,
        state_lanes=tuple(in_lanes),
        in_sizes=tuple(s.in_sizes for s in signatures),
        out_shapes=tuple(tuple(x.shape for x in s.out_sparsity) for s in signatures),
        in_names=tuple(s.in_names for s in signatures),
        out_names=tuple(s.out_names for s in signatures),
    )
