"""codegen: export the dynamics Functions as C (export_c -> CExport), compile and load them back (build_library)."""

from .build import CompiledLibrary, build_library, compile_shared, find_compiler
from .export import CExport, OperationCount, count_operations, export_c
from .rnea_sx import RneaFunctions, build_rnea_functions

__all__ = [
    "CExport", "CompiledLibrary", "OperationCount", "RneaFunctions", "build_library", "build_rnea_functions",
    "compile_shared", "count_operations", "export_c", "find_compiler",
]
