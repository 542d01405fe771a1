"""The MPC's compiler runs: a C file that does not compile is a SolverError quoting the command and the compiler's
own message, not a traceback from ctypes or CasADi."""

from __future__ import annotations

import shutil

import pytest

from psdm_casadi.errors import SolverError
from trajopt.c_compiler import run_compiler

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


def test_a_source_that_does_not_compile_names_the_purpose_the_command_and_the_error(tmp_path):
    source = tmp_path / "broken.c"
    source.write_text("int f(void) { return undeclared_name; }\n")
    command = ["cc", "-c", str(source), "-o", str(tmp_path / "broken.o")]
    with pytest.raises(SolverError, match=r"the RTI's QP solver must compile; `cc -c .*broken.c") as error:
        run_compiler(command, "the RTI's QP solver")
    assert "undeclared_name" in str(error.value) and error.value.status != 0


def test_a_source_that_compiles_writes_its_object(tmp_path):
    source = tmp_path / "fine.c"
    source.write_text("int f(void) { return 1; }\n")
    run_compiler(["cc", "-c", str(source), "-o", str(tmp_path / "fine.o")], "a test")
    assert (tmp_path / "fine.o").stat().st_size > 0
