"""Batched C (codegen.batch, codegen.batch_library) against the single-call exported C and Pinocchio."""

import ctypes
import json
import shutil

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from codegen.batch import LANES, add_batch, export_batch
from codegen.batch_kernel import function_bodies, vectorise_body
from codegen.batch_library import build_batch
from codegen.export import export_c
from psdm_casadi.cli import main
from psdm_casadi.errors import ParameterError, ShapeError, SolverError
from psdm_casadi.oracle import build_pinocchio_model
from psdm_casadi.recursive import build_recursive_functions
from tests.conftest import DENSO_FILE

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
FLAGS = ("-O1", "-fopenmp")
# Not multiples of the lane widths tested (4 and 2), and a single state.
STATE_COUNTS = (1, 7, 13)


@pytest.fixture(scope="module")
def denso_batch(tmp_path_factory, denso, denso_model):
    """(robot, theta, {label: BatchLibrary}): the default export (the Denso's regressor state by state) and
    one with every function in lanes of two states."""
    functions = build_recursive_functions(denso_model, denso)
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    base = tmp_path_factory.mktemp("batch")
    libraries = {}
    for label, options in (("default", {}), ("lanes2", {"lane_width": 2, "state_lanes": True})):
        export = export_batch(functions, base / label, theta=theta, **options)
        libraries[label] = build_batch(export, build_dir=base / f"{label}_build", flags=FLAGS)
    return denso, theta, libraries


def _states(rng, n_states, n_dof):
    return (
        rng.uniform(-np.pi, np.pi, (n_states, n_dof)),
        rng.uniform(-2.0, 2.0, (n_states, n_dof)),
        rng.uniform(-10.0, 10.0, (n_states, n_dof)),
    )


def _assert_relative(got, want, rtol=1e-9):
    scale = max(1.0, float(np.max(np.abs(want))))
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale)


def _single(library, name, *inputs):
    """The single-call exported C function of the same library, state by state (casadi.external)."""
    function = ca.external(name, str(library.path))
    rows = [function(*(x[k] for x in inputs)) for k in range(inputs[0].shape[0])]
    return np.array([np.array(r) for r in rows])


@needs_cc
@pytest.mark.needs_cc
@pytest.mark.parametrize("label", ["default", "lanes2"])
@pytest.mark.parametrize("n_threads", [1, 2])
def test_batch_equals_single_call_and_pinocchio(denso_batch, rng, label, n_threads):
    robot, theta, libraries = denso_batch
    library = libraries[label]
    pin_model = build_pinocchio_model(robot)
    data = pin_model.createData()
    for n_states in STATE_COUNTS:
        q, qd, qdd = _states(rng, n_states, pin_model.nv)
        tau_ref = np.array([pin.rnea(pin_model, data, q[k], qd[k], qdd[k]) for k in range(n_states)])
        tau = library.inverse_dynamics(q, qd, qdd, n_threads=n_threads)
        assert tau.shape == (n_states, pin_model.nv)
        _assert_relative(tau, tau_ref)
        _assert_relative(tau, _single(library, "psdm_inverse_dynamics", q, qd, qdd)[:, :, 0])

        applied = rng.uniform(-20.0, 20.0, q.shape)
        qdd_ref = np.array([pin.aba(pin_model, data, q[k], qd[k], applied[k]) for k in range(n_states)])
        qdd_batch = library.forward_dynamics(q, qd, applied, n_threads=n_threads)
        _assert_relative(qdd_batch, qdd_ref)
        _assert_relative(qdd_batch, _single(library, "psdm_forward_dynamics", q, qd, applied)[:, :, 0])

        regressor = library.regressor(q, qd, qdd, n_threads=n_threads)
        assert regressor.shape == (n_states, pin_model.nv, theta.size)
        _assert_relative(regressor, _single(library, "psdm_regressor", q, qd, qdd))
        _assert_relative(regressor @ theta, tau_ref)


@needs_cc
@pytest.mark.needs_cc
def test_batch_records_its_paths_and_threads(denso_batch):
    _, _, libraries = denso_batch
    default, lanes2 = libraries["default"].export, libraries["lanes2"].export
    assert default.lane_width == LANES and lanes2.lane_width == 2
    assert default.state_lanes == (True, True, False)  # the Denso's regressor: more outputs than arithmetic
    assert lanes2.state_lanes == (True, True, True)
    assert default.function_names == (
        "psdm_inverse_dynamics_batch",
        "psdm_forward_dynamics_batch",
        "psdm_regressor_batch",
    )
    assert libraries["default"].default_threads >= 1
    header = default.header.read_text()
    assert all(f"int {name}(" in header for name in default.function_names)


@needs_cc
@pytest.mark.needs_cc
def test_batch_shape_and_argument_errors(denso_batch, rng):
    _, _, libraries = denso_batch
    library = libraries["default"]
    q, qd, qdd = _states(rng, 5, 6)
    with pytest.raises(ShapeError, match=r"input q must have shape \(n_states, 6\)"):
        library.inverse_dynamics(q[0], qd[:1], qdd[:1])
    with pytest.raises(ShapeError, match=r"input qd must have shape \(n_states, 6\)"):
        library.inverse_dynamics(q, qd[:4], qdd)
    with pytest.raises(ShapeError, match="input qdd"):
        library.inverse_dynamics(q, qd, qdd[:, :5])
    with pytest.raises(ParameterError, match="n_threads must be a positive integer"):
        library.inverse_dynamics(q, qd, qdd, n_threads=0)
    with pytest.raises(ParameterError, match="takes 3 inputs"):
        library.evaluate("inverse_dynamics", q, qd)
    with pytest.raises(ParameterError, match="BatchLibrary function must be one of"):
        library.evaluate("mass_matrix", q, qd, qdd)
    empty = library.inverse_dynamics(q[:0], qd[:0], qdd[:0])
    assert empty.shape == (0, 6)


@needs_cc
@pytest.mark.needs_cc
def test_batch_sparse_output_and_lanewise_calls(tmp_path, rng):
    """A sparse matrix output is scattered to its dense column-major place; sqrt runs lane by lane."""
    x = ca.SX.sym("x", 3)
    out = ca.diag(ca.sin(x)) + ca.sparsify(ca.DM([[0, 0, 0], [0, 0, 0], [1, 0, 0]])) * ca.sqrt(x[0] ** 2 + 1)
    function = ca.Function("f", [x], [out], ["x"], ["m"])
    assert not function.sparsity_out(0).is_dense()
    export = export_batch([function], tmp_path / "out", lane_width=2)
    library = build_batch(export, build_dir=tmp_path / "build", flags=FLAGS)
    states = rng.uniform(-2.0, 2.0, (5, 3))
    (got,) = library.evaluate("f", states)
    want = np.array([np.array(ca.densify(function(s))) for s in states])
    _assert_relative(got, want, rtol=1e-12)


def test_export_batch_errors(tmp_path, denso, denso_model):
    functions = build_recursive_functions(denso_model, denso)
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    with pytest.raises(ParameterError, match="lane_width must be one of"):
        export_batch(functions, tmp_path / "a", theta=theta, lane_width=3)
    with pytest.raises(ParameterError, match="theta must be given"):
        export_batch(functions, tmp_path / "b")
    with pytest.raises(ParameterError, match="state_lanes must be"):
        export_batch(functions, tmp_path / "c", theta=theta, state_lanes="yes")
    with pytest.raises(ParameterError, match="export_batch functions must be"):
        export_batch(object(), tmp_path / "d")
    (tmp_path / "e").mkdir()
    (tmp_path / "e" / "mine.txt").write_text("keep")
    with pytest.raises(FileExistsError, match="not empty"):
        export_batch(functions, tmp_path / "e", theta=theta)


def test_unsupported_statement_is_refused(tmp_path):
    """CasADi's fmax is not in the rewrite's grammar: refused with the statement named, never mistranslated;
    ``state_lanes="auto"`` then calls the single-call C state by state."""
    x = ca.SX.sym("x", 2)
    function = ca.Function("g", [x], [ca.fmax(x[0], x[1]) * x[0] + ca.sin(x[1]) * x[1] ** 3], ["x"], ["y"])
    with pytest.raises(SolverError, match="cannot vectorise psdm_g_batch_lanes: CasADi wrote the statement"):
        export_batch([function], tmp_path / "out", state_lanes=True)
    assert export_batch([function], tmp_path / "auto").state_lanes == (False,)


def test_function_bodies_and_vector_rewrite():
    x = ca.SX.sym("x", 2)
    function = ca.Function("h", [x], [ca.vertcat(x[0] * x[1], -x[0] / 3.0)], ["x"], ["y"])
    generator = ca.CodeGenerator("h.c")
    generator.add(function)
    bodies = function_bodies(generator.dump())
    assert set(bodies) == {"h"}
    kernel, lanewise = vectorise_body(bodies["h"], "h_lanes", [[0, 1]])
    assert lanewise == set() and "psdm_v " in kernel and "PSDM_STORE(y + 0 * W, 1," in kernel
    assert "casadi_real a" not in kernel


def test_add_batch_needs_baked_theta(tmp_path, denso, denso_model):
    functions = build_recursive_functions(denso_model, denso)
    runtime_only = export_c(functions, tmp_path / "runtime")
    with pytest.raises(ParameterError, match="add_batch needs theta baked into the export"):
        add_batch(runtime_only, functions)
    with pytest.raises(ParameterError, match="add_batch single must be a CExport"):
        add_batch(tmp_path, functions)


@needs_cc
@pytest.mark.needs_cc
def test_codegen_cli_batch(tmp_path, capsys, denso, denso_model, rng):
    """``psdm codegen --batch --compile``: the batch functions in the same library, callable on states."""
    out = tmp_path / "out"
    code = main(["codegen", str(DENSO_FILE), "--out", str(out), "--batch", "--compile", "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["batch_functions"] == [
        "psdm_inverse_dynamics_batch",
        "psdm_forward_dynamics_batch",
        "psdm_regressor_batch",
    ]
    assert (out / "psdm_dynamics_batch.c").exists() and (out / "psdm_dynamics_batch.h").exists()
    library = ctypes.CDLL(str(out / "libpsdm_dynamics.so"))
    q, qd, qdd = _states(rng, 3, 6)
    tau = np.empty_like(q)
    pointers = [x.ctypes.data_as(ctypes.c_void_p) for x in (q, qd, qdd, tau)]
    assert library.psdm_inverse_dynamics_batch(*pointers, ctypes.c_long(3), ctypes.c_int(1)) == 0
    pin_model = build_pinocchio_model(denso)
    data = pin_model.createData()
    _assert_relative(tau, np.array([pin.rnea(pin_model, data, q[k], qd[k], qdd[k]) for k in range(3)]))
    assert "$(LIB)_batch.c" in (out / "Makefile").read_text()  # make builds both sources into one library


def test_batch_argument_errors_without_compiling(tmp_path, denso, denso_model):
    many = ca.Function("many", [ca.SX.sym(f"x{k}") for k in range(9)], [ca.SX(1)])
    with pytest.raises(ParameterError, match="at most 8 inputs and outputs; many has 9"):
        export_batch([many], tmp_path / "many")
    x = ca.SX.sym("x", ca.Sparsity.diag(2))
    sparse_in = ca.Function("sparse_in", [x], [ca.sum1(ca.sum2(x))])
    with pytest.raises(ParameterError, match="must have dense inputs; sparse_in"):
        export_batch([sparse_in], tmp_path / "sparse")
    functions = build_recursive_functions(denso_model, denso)
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    only_tau = export_c([functions.inverse_dynamics], tmp_path / "only_tau", theta=theta, runtime_theta=False)
    with pytest.raises(ParameterError, match="add_batch functions must be in the export; 'psdm_regressor'"):
        add_batch(only_tau, [functions.regressor])
    with pytest.raises(ParameterError, match="build_batch export must be a BatchExport"):
        build_batch(only_tau)
