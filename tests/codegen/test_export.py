"""export_c: folder contents, names of both theta flavours, operation counts and error paths."""

import casadi as ca
import numpy as np
import pytest

from codegen.export import CExport, count_operations, export_c
from psdm_casadi.errors import ParameterError, ShapeError
from tests.codegen._toy import N_BASE, THETA, toy_functions


def test_export_writes_self_contained_folder(tmp_path):
    export = export_c(toy_functions(), tmp_path / "out", theta=THETA)
    assert isinstance(export, CExport)
    for path in (export.header, export.source, export.example, export.build_file):
        assert path.exists() and path.stat().st_size > 0
    assert export.function_names == (
        "psdm_inverse_dynamics",
        "psdm_inverse_dynamics_theta",
        "psdm_forward_dynamics",
        "psdm_forward_dynamics_theta",
        "psdm_regressor",
    )
    header = export.header.read_text()
    example = export.example.read_text()
    for name in export.function_names:
        assert f"int {name}(const casadi_real** arg" in header
        assert f"FUNCTION({name})" in example
    assert "psdm_dynamics.c" in export.build_file.read_text().replace("$(LIB).c", "psdm_dynamics.c")
    assert export.theta_baked
    assert [p.name for p in (tmp_path / "out").iterdir() if p.name.startswith(".")] == []  # no staging left


def test_baked_theta_drops_zero_products(tmp_path):
    export = export_c(toy_functions(), tmp_path, theta=THETA)
    baked = export.operation_count("psdm_inverse_dynamics")
    runtime = export.operation_count("psdm_inverse_dynamics_theta")
    assert baked.n_operations < runtime.n_operations
    # two of five theta entries are zero: the runtime flavour multiplies by all five per row
    assert runtime.n_multiplications - baked.n_multiplications >= 2 * 3
    assert baked.n_trig <= 6  # sin and cos of 3 joints, shared by every column


def test_runtime_only_without_theta(tmp_path):
    export = export_c(toy_functions(), tmp_path)
    assert "psdm_inverse_dynamics" not in export.function_names
    assert "psdm_inverse_dynamics_theta" in export.function_names
    assert not export.theta_baked


def test_jacobians_on_request(tmp_path):
    toy = toy_functions()
    export = export_c([toy.regressor, toy.inverse_dynamics], tmp_path, theta=THETA, jacobians=True, prefix="rb_")
    assert "rb_regressor_jac" in export.function_names
    assert "rb_inverse_dynamics_theta_jac" in export.function_names
    assert "dtau_dq" in export.source.read_text()


def test_count_operations_by_kind():
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    f = ca.Function("f", [x, y], [x * y + ca.sin(x) - ca.cos(y) / y])
    count = count_operations(f)
    assert (count.n_trig, count.n_multiplications, count.n_additions) == (2, 2, 2)
    assert count.n_operations == 6 and count.n_instructions == f.n_instructions()


def test_refuses_non_empty_folder(tmp_path):
    (tmp_path / "keep.txt").write_text("user file")
    with pytest.raises(FileExistsError, match="not empty"):
        export_c(toy_functions(), tmp_path)
    export_c(toy_functions(), tmp_path, overwrite=True)
    assert (tmp_path / "keep.txt").read_text() == "user file"


def test_error_paths(tmp_path):
    with pytest.raises(ParameterError, match="functions"):
        export_c([], tmp_path / "a")
    with pytest.raises(ParameterError, match="functions"):
        export_c(["not a function"], tmp_path / "a")
    with pytest.raises(ShapeError, match="theta"):
        export_c(toy_functions(), tmp_path / "a", theta=np.ones(N_BASE + 1))
    with pytest.raises(ParameterError, match="theta"):
        export_c(toy_functions(), tmp_path / "a", theta=np.full(N_BASE, np.nan))
    with pytest.raises(ParameterError, match="runtime_theta"):
        export_c(toy_functions(), tmp_path / "a", runtime_theta=False)
    with pytest.raises(ParameterError, match="prefix"):
        export_c(toy_functions(), tmp_path / "a", prefix="bad-prefix")
    with pytest.raises(ParameterError, match="library"):
        export_c(toy_functions(), tmp_path / "a", library="1lib")
    f = toy_functions().regressor
    with pytest.raises(ParameterError, match="theta must be None"):
        export_c(f, tmp_path / "a", theta=THETA)
    with pytest.raises(ParameterError, match="distinct names"):
        export_c([f, f], tmp_path / "a")
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError, match="is a file"):
        export_c(toy_functions(), tmp_path / "file")
