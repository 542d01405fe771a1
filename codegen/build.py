"""Compile an exported C folder with the system compiler and load it back (casadi.external) for round-trip tests.

Compiling is its own explicit step after ``export_c``: ``build_library(export)`` returns a
CompiledLibrary whose Functions evaluate the C code through CasADi's ``external``.
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import casadi as ca

from codegen.export import CExport
from psdm_casadi.errors import ParameterError, SolverError

DEFAULT_FLAGS = ("-O2",)
_COMPILERS = ("cc", "gcc", "clang")


@dataclass(frozen=True)
class CompiledLibrary:
    """A compiled shared library of an export and its Functions loaded through ``casadi.external``.

    Attributes
    ----------
    path : Path
        The shared library (``lib<library>.so``) in the build folder.
    functions : tuple of casadi.Function
        One external Function per exported C function, same order as ``CExport.function_names``.
    """

    path: Path
    functions: tuple

    def function(self, name: str) -> ca.Function:
        """The external Function with this C name."""
        for f in self.functions:
            if f.name() == name:
                return f
        raise ParameterError(
            f"CompiledLibrary.functions must contain {name!r}; got {[f.name() for f in self.functions]}. "
            "Use a name from CExport.function_names."
        )


def find_compiler(compiler=None) -> str:
    """Path of the C compiler: ``compiler``, else ``$CC``, else the first of cc, gcc, clang on PATH.

    Raises
    ------
    SolverError
        When no compiler is found, naming the fix.
    """
    candidates = [compiler] if compiler else ([os.environ["CC"]] if os.environ.get("CC") else list(_COMPILERS))
    for candidate in candidates:
        found = shutil.which(candidate)
        if found:
            return found
    raise SolverError(
        f"build_library compiler must be an installed C compiler; none of {candidates} was found on PATH. "
        "Install one (e.g. apt-get install gcc) or pass compiler='/path/to/cc'."
    )


def compile_shared(sources, output, *, compiler=None, flags=DEFAULT_FLAGS) -> Path:
    """Compile C sources into a shared library.

    Parameters
    ----------
    sources : sequence of Path
    output : Path
        The ``.so`` to write.
    compiler : str, optional
        See ``find_compiler``.
    flags : sequence of str
        Optimisation and other flags, e.g. ``("-O3", "-march=native")``.

    Raises
    ------
    SolverError
        When no compiler is found or compilation fails (the compiler's last lines are quoted).
    """
    cc = find_compiler(compiler)
    command = [cc, *flags, "-fPIC", "-shared", "-o", str(output), *map(str, sources), "-lm"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        tail = "\n".join(result.stderr.strip().splitlines()[-12:])
        raise SolverError(
            f"build_library compilation must succeed; `{shlex.join(command)}` exited with {result.returncode}:\n"
            f"{tail}\nCheck the compiler and flags (compiler=, flags=).",
            status=result.returncode,
        )
    return Path(output)


def build_library(export: CExport, *, build_dir=None, compiler=None, flags=DEFAULT_FLAGS) -> CompiledLibrary:
    """Compile an export into a shared library and load its functions with ``casadi.external``.

    Parameters
    ----------
    export : CExport
        The result of ``export_c``.
    build_dir : str or Path, optional
        Where to put the library; a fresh temporary folder by default (left for the caller to delete).
    compiler : str, optional
        C compiler; defaults to ``$CC`` or cc/gcc/clang on PATH.
    flags : sequence of str
        Compiler flags; ``-O2`` by default (use ``-O3 -march=native`` for deployment).

    Returns
    -------
    CompiledLibrary

    Raises
    ------
    ParameterError
        When ``export`` is not a CExport or its source is missing.
    SolverError
        When no compiler is found or compilation fails.

    Examples
    --------
    >>> lib = build_library(export_c(functions, "out"))            # doctest: +SKIP
    >>> lib.function("psdm_inverse_dynamics")(q, qd, qdd)          # doctest: +SKIP
    """
    if not isinstance(export, CExport):
        raise ParameterError(
            f"build_library export must be a CExport; got {type(export).__name__}. Pass export_c(...)."
        )
    if not export.source.exists():
        raise ParameterError(
            f"build_library export.source must exist; got missing {str(export.source)!r}. Run export_c again."
        )
    if isinstance(flags, str):
        flags = tuple(shlex.split(flags))
    folder = Path(build_dir) if build_dir is not None else Path(tempfile.mkdtemp(prefix="psdm_codegen_"))
    folder.mkdir(parents=True, exist_ok=True)
    library = compile_shared([export.source], folder / f"lib{export.library}.so", compiler=compiler, flags=flags)
    functions = tuple(ca.external(name, str(library)) for name in export.function_names)
    return CompiledLibrary(path=library, functions=functions)
