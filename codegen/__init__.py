"""codegen: export the dynamics Functions as C (export_c -> CExport), compile and load them back (build_library).

``export`` (C sources from CasADi Functions, with inlined sin/cos), ``lane_regressor`` (the regressor
with joint rows in SIMD lanes), ``derivatives`` (d(tau)/d(q, qd, qdd), d(qdd)/d(q, qd, tau) and the
regressor's, exported beside the dynamics: export_derivatives), ``operation_count``, ``build`` (compile
and load), ``templates``; the calibrated model as a URDF (``urdf_export``), sharing ``target_holds``, the
statement of what each export target can hold; the peers the speed benchmark compares against live in
``codegen.peers``.
"""

from codegen.build import CompiledLibrary, build_library, compile_shared, find_compiler
from codegen.derivatives import DerivativeFunctions, build_derivative_functions, export_derivatives
from codegen.export import CExport, OperationCount, count_operations, export_c

__all__ = [
    "CExport",
    "CompiledLibrary",
    "DerivativeFunctions",
    "OperationCount",
    "build_derivative_functions",
    "build_library",
    "compile_shared",
    "count_operations",
    "export_c",
    "export_derivatives",
    "find_compiler",
]
