"""Compiled C against the CasADi Functions (round trip through casadi.external) and the C example program."""

import shutil
import subprocess

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from codegen.build import CompiledLibrary, build_library, find_compiler
from codegen.export import export_c
from codegen.peers.rnea_sx import build_rnea_functions
from psdm_casadi.errors import ParameterError, SolverError
from psdm_casadi.oracle import build_pinocchio_model
from tests.codegen._toy import THETA, random_inputs, toy_functions

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
FAST = ("-O1",)


def _flat(value):
    return np.array(value, dtype=float).ravel()


def _evaluate(function, inputs):
    out = function(*inputs)
    out = out if isinstance(out, (list, tuple)) else [out]
    return [np.array(o.nonzeros()) if isinstance(o, ca.DM) else np.ravel(o) for o in out]


def _reference(toy, name):
    """The Python-side Function a compiled function must reproduce, and how to map its inputs."""
    base = name.removeprefix("psdm_").removesuffix("_jac")
    runtime = base.endswith("_theta")
    source = getattr(toy, base.removesuffix("_theta"))
    if name.endswith("_jac"):
        ins = source.sx_in()
        outs = source.call(ins)
        jac = [ca.jacobian(ca.vec(o), i) for o in outs for i, n in zip(ins, source.name_in()) if n != "theta"]
        source = ca.Function("ref", ins, jac, source.name_in(), [f"j{k}" for k in range(len(jac))])
    if "theta" in source.name_in() and not runtime:
        return source, lambda inputs: [*inputs[: source.name_in().index("theta")], THETA]
    return source, lambda inputs: inputs


@pytest.mark.needs_cc
@needs_cc
def test_round_trip_equals_casadi(tmp_path, rng):
    toy = toy_functions()
    export = export_c(toy, tmp_path / "out", theta=THETA, jacobians=True)
    library = build_library(export, build_dir=tmp_path / "build", flags=FAST)
    assert isinstance(library, CompiledLibrary) and library.path.exists()
    assert [f.name() for f in library.functions] == list(export.function_names)
    for compiled in library.functions:
        reference, map_inputs = _reference(toy, compiled.name())
        for _ in range(3):
            inputs = random_inputs(compiled, rng)
            got, want = _evaluate(compiled, inputs), _evaluate(reference, map_inputs(inputs))
            assert len(got) == len(want)
            for g, w in zip(got, want):
                assert np.all(w != 0) or compiled.name().endswith("_jac")  # non-trivial values
                np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-12)


@pytest.mark.needs_cc
@needs_cc
def test_compiled_rnea_matches_pinocchio(tmp_path, denso, rng):
    model = build_pinocchio_model(denso)
    peer = build_rnea_functions(model)
    export = export_c([peer.inverse_dynamics, peer.forward_dynamics, peer.mass_matrix], tmp_path, prefix="rnea_")
    library = build_library(export, flags=FAST)
    data = model.createData()
    for _ in range(5):
        q, qd, qdd, tau = rng.uniform(-2, 2, (4, denso.n_dof))
        tau_c = _flat(library.function("rnea_inverse_dynamics")(q, qd, qdd))
        np.testing.assert_allclose(tau_c, _flat(peer.inverse_dynamics(q, qd, qdd)), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(tau_c, pin.rnea(model, data, q, qd, qdd), rtol=1e-10, atol=1e-10)
        qdd_c = _flat(library.function("rnea_forward_dynamics")(q, qd, tau))
        np.testing.assert_allclose(qdd_c, pin.aba(model, data, q, qd, tau), rtol=1e-10, atol=1e-10)


def _parse_example(stdout):
    inputs, outputs = {}, {}
    for line in stdout.splitlines():
        kind, function, _, *values = line.split()
        if kind in ("in", "out"):
            target = inputs if kind == "in" else outputs
            target.setdefault(function, []).append(np.array([float(v) for v in values]))
    return inputs, outputs


@pytest.mark.needs_cc
@needs_cc
def test_c_example_builds_and_matches_python(tmp_path):
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    toy = toy_functions()
    export = export_c(toy, tmp_path, theta=THETA)
    build = subprocess.run(["make", "-s", "CFLAGS=-O1"], cwd=tmp_path, capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    assert (tmp_path / "libpsdm_dynamics.so").exists()
    run = subprocess.run(["./example", "time"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    inputs, outputs = _parse_example(run.stdout)
    assert sorted(outputs) == sorted(export.function_names)
    assert run.stdout.count("us/call") == len(export.function_names)
    for name in export.function_names:
        reference, map_inputs = _reference(toy, name)
        want = _evaluate(reference, map_inputs(inputs[name]))
        for got, expected in zip(outputs[name], want):
            assert np.any(expected != 0)
            np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.needs_cc
@needs_cc
def test_psdm_functions_round_trip(tmp_path, denso, rng):
    pytest.importorskip("psdm_casadi.symbolic")
    from psdm_casadi import derive_psdm
    from psdm_casadi.oracle import PinocchioOracle
    from psdm_casadi.symbolic import build_functions

    model = derive_psdm(denso)
    functions = build_functions(model)
    theta = model.base_parameters(denso.nominal_dynamic_parameters())
    export = export_c([functions.inverse_dynamics, functions.regressor], tmp_path, theta=theta)
    library = build_library(export, flags=FAST)
    oracle = PinocchioOracle(denso)
    for _ in range(3):
        q, qd, qdd = rng.uniform(-2, 2, (3, denso.n_dof))
        baked = _flat(library.function("psdm_inverse_dynamics")(q, qd, qdd))
        runtime = _flat(library.function("psdm_inverse_dynamics_theta")(q, qd, qdd, theta))
        reference = _flat(functions.inverse_dynamics(q, qd, qdd, theta))
        np.testing.assert_allclose(runtime, reference, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(baked, reference, rtol=1e-12, atol=1e-11)
        np.testing.assert_allclose(baked, oracle.rnea(q, qd, qdd), rtol=1e-9, atol=1e-9)
        y = np.array(library.function("psdm_regressor")(q, qd, qdd))
        np.testing.assert_allclose(y, np.array(functions.regressor(q, qd, qdd)), rtol=1e-12, atol=1e-12)


def test_missing_compiler_names_the_fix(tmp_path):
    with pytest.raises(SolverError, match="compiler"):
        find_compiler("no-such-compiler-xyz")
    export = export_c(toy_functions().regressor, tmp_path / "out")
    with pytest.raises(SolverError, match="compiler="):
        build_library(export, compiler="no-such-compiler-xyz")


@pytest.mark.needs_cc
@needs_cc
def test_failed_compilation_raises_solver_error(tmp_path):
    export = export_c(toy_functions().regressor, tmp_path / "out")
    with pytest.raises(SolverError, match="compilation"):
        build_library(export, flags=("-O1", "--no-such-flag-xyz"))


def test_build_library_rejects_non_export(tmp_path):
    with pytest.raises(ParameterError, match="export"):
        build_library(tmp_path)
    export = export_c(toy_functions().regressor, tmp_path / "out")
    export.source.unlink()
    with pytest.raises(ParameterError, match="export.source"):
        build_library(export)
    library = CompiledLibrary(path=tmp_path, functions=())
    with pytest.raises(ParameterError, match="functions"):
        library.function("psdm_regressor")


@pytest.mark.needs_cc
@needs_cc
def test_recursive_form_round_trip_equals_the_sum_model(tmp_path, denso, denso_model, rng):
    """The default export (recursive form, inlined sin/cos) compiled, against the paper's sum Y theta."""
    from psdm_casadi.recursive import build_recursive_functions

    functions = build_recursive_functions(denso_model, denso)
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    export = export_c(functions, tmp_path, theta=theta)
    library = build_library(export, flags=FAST)
    for _ in range(3):
        q, qd, qdd = rng.uniform(-np.pi, np.pi, (3, denso.n_dof))
        tau = rng.uniform(-20, 20, denso.n_dof)
        other = rng.normal(size=denso_model.n_base)  # any theta, not only physical ones
        reference = denso_model.inverse_dynamics(q, qd, qdd, theta)
        np.testing.assert_allclose(
            _flat(library.function("psdm_inverse_dynamics")(q, qd, qdd)), reference, rtol=1e-12, atol=1e-11
        )
        np.testing.assert_allclose(
            _flat(library.function("psdm_inverse_dynamics_theta")(q, qd, qdd, other)),
            denso_model.inverse_dynamics(q, qd, qdd, other),
            rtol=1e-12,
            atol=1e-11,
        )
        np.testing.assert_allclose(
            np.array(library.function("psdm_regressor")(q, qd, qdd)),
            denso_model.regressor(q, qd, qdd),
            rtol=1e-12,
            atol=1e-12,
        )
        mass = np.array(library.function("psdm_mass_matrix")(q))
        np.testing.assert_allclose(mass, np.array(functions.mass_matrix(q, theta)), rtol=1e-12, atol=1e-12)
        qdd_fd = _flat(library.function("psdm_forward_dynamics")(q, qd, tau))
        np.testing.assert_allclose(
            mass @ qdd_fd + denso_model.inverse_dynamics(q, qd, 0 * qd, theta), tau, rtol=1e-10, atol=1e-10
        )
