"""Exported derivatives: equal to finite differences of Pinocchio (Denso, Panda), compiled C (scalar and vector
lanes) equals CasADi."""

import ctypes
import shutil

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from codegen.build import build_library
from codegen.derivatives import build_derivative_functions, export_derivatives
from codegen.export import export_c
from codegen.lane_derivatives import lane_jacobian
from codegen.operation_count import count_operations
from psdm_casadi.cli import main
from psdm_casadi.derive import derive_psdm
from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.oracle import build_pinocchio_model
from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.robot import from_urdf
from tests.conftest import DENSO_FILE, example_robot_urdf

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
STEP = 1e-6  # central differences: truncation ~STEP^2, rounding ~1e-16 |f| / STEP


def _central_difference(f, x, step=STEP):
    """d f / d x (columns per entry of x) by central differences."""
    columns = []
    for k in range(x.size):
        dx = np.zeros_like(x)
        dx[k] = step
        columns.append((np.ravel(f(x + dx)) - np.ravel(f(x - dx))) / (2 * step))
    return np.column_stack(columns)


def _assert_close(got, want):
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-6, atol=1e-6 * np.abs(want).max())


def _assert_equal(got, want):
    """Outputs of a compiled function and of its CasADi Function, to rounding."""
    assert len(got) == len(want)
    for g, w in zip(got, want):
        w = np.array(w)
        np.testing.assert_allclose(np.array(g), w, rtol=1e-12, atol=1e-12 * np.abs(w).max())


def _partials(f, args):
    """Central differences of f(*args) in each of its arguments."""
    partials = []
    for index in range(len(args)):

        def moved(x, index=index):
            return f(*args[:index], x, *args[index + 1 :])

        partials.append(_central_difference(moved, args[index]))
    return partials


def _check_against_pinocchio(robot, derivatives, theta, rng):
    """Both derivative functions (theta as a runtime input) against finite differences of rnea and aba."""
    pm = build_pinocchio_model(robot)
    data = pm.createData()
    n = pm.nv

    def rnea(q, qd, qdd):
        return pin.rnea(pm, data, q, qd, qdd)

    def aba(q, qd, tau):
        return pin.aba(pm, data, q, qd, tau)

    for _ in range(2):
        q, qd = rng.uniform(-np.pi, np.pi, n), rng.uniform(-2, 2, n)
        qdd, tau = rng.uniform(-10, 10, n), rng.uniform(-20, 20, n)
        for function, reference, args in (
            (derivatives.inverse_dynamics_derivatives, rnea, (q, qd, qdd)),
            (derivatives.forward_dynamics_derivatives, aba, (q, qd, tau)),
        ):
            value, *jacobians = function(*args, theta)
            _assert_close(value, reference(*args)[:, None])
            for got, want in zip(jacobians, _partials(reference, args), strict=True):
                _assert_close(got, want)


def _check_regressor(model, derivatives, rng):
    """d vec(Y) against finite differences of the PSDM model's own numeric regressor."""
    n = model.n_dof
    args = (rng.uniform(-np.pi, np.pi, n), rng.uniform(-2, 2, n), rng.uniform(-10, 10, n))

    def vec_y(q, qd, qdd):
        return np.asarray(model.regressor(q, qd, qdd)).ravel(order="F")

    for got, want in zip(derivatives.regressor_derivatives(*args), _partials(vec_y, args), strict=True):
        _assert_close(got, want)


@pytest.mark.parametrize("form", ["structured", "direct"])
def test_denso_derivatives_equal_finite_differences_of_pinocchio(denso, denso_model, rng, form):
    functions = build_recursive_functions(denso_model, denso)
    derivatives = build_derivative_functions(functions, form=form)
    assert derivatives.forward_form == form
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    _check_against_pinocchio(denso, derivatives, theta, rng)
    _check_regressor(denso_model, derivatives, rng)


def test_panda_derivatives_equal_finite_differences_of_pinocchio(rng):
    robot = from_urdf(
        example_robot_urdf("panda_description/urdf/panda.urdf"),
        locked_joints=["panda_finger_joint1", "panda_finger_joint2"],
    )
    model = derive_psdm(robot)
    # the regressor's derivatives are checked on the Denso: the Panda's numeric PSDM regressor (p = 29639) is slow
    derivatives = build_derivative_functions(build_recursive_functions(model, robot), regressor=False)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    _check_against_pinocchio(robot, derivatives, theta, rng)


def test_auto_keeps_the_form_with_fewer_operations(denso, denso_model):
    functions = build_recursive_functions(denso_model, denso)
    counts = {
        form: count_operations(build_derivative_functions(functions, form=form).forward_dynamics_derivatives)
        for form in ("structured", "direct")
    }
    auto = build_derivative_functions(functions, regressor=False)
    assert auto.regressor_derivatives is None
    assert count_operations(auto.forward_dynamics_derivatives).n_operations == min(
        c.n_operations for c in counts.values()
    )
    assert auto.forward_form == min(counts, key=lambda k: counts[k].n_operations)


def test_bad_inputs_are_refused(denso, denso_model):
    functions = build_recursive_functions(denso_model, denso)
    with pytest.raises(ParameterError, match="form must be one of"):
        build_derivative_functions(functions, form="fast")
    with pytest.raises(ParameterError, match="inverse_dynamics"):
        build_derivative_functions(object())


@pytest.mark.needs_cc
@needs_cc
def test_compiled_derivatives_equal_casadi(tmp_path, denso, denso_model, rng):
    """The exported C (theta baked in and as a runtime input) reproduces the CasADi derivative Functions."""
    functions = build_recursive_functions(denso_model, denso)
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    export = export_derivatives(functions, tmp_path / "out", theta=theta)
    names = set(export.function_names)
    for name in ("inverse_dynamics_derivatives", "forward_dynamics_derivatives", "regressor_derivatives"):
        assert f"psdm_{name}" in names
    assert "psdm_inverse_dynamics_derivatives_theta" in names and "psdm_inverse_dynamics" in names
    library = build_library(export, build_dir=tmp_path / "build", flags=("-O0",))
    reference = build_derivative_functions(functions)
    n = denso.n_dof
    for _ in range(2):
        q, qd, third = rng.uniform(-np.pi, np.pi, n), rng.uniform(-2, 2, n), rng.uniform(-10, 10, n)
        for name in ("inverse_dynamics_derivatives", "forward_dynamics_derivatives"):
            want = getattr(reference, name)(q, qd, third, theta)
            for got in (
                library.function(f"psdm_{name}")(q, qd, third),
                library.function(f"psdm_{name}_theta")(q, qd, third, theta),
            ):
                _assert_equal(got, want)
        got = library.function("psdm_regressor_derivatives")(q, qd, third)
        _assert_equal(got, reference.regressor_derivatives(q, qd, third))


def test_cli_derivatives_flag(tmp_path, capsys):
    code = main(["codegen", str(DENSO_FILE), "--out", str(tmp_path / "out"), "--derivatives"])
    assert code == 0
    header = (tmp_path / "out" / "psdm_dynamics.h").read_text()
    for name in ("inverse_dynamics_derivatives", "forward_dynamics_derivatives", "regressor_derivatives"):
        assert f"int psdm_{name}(const casadi_real** arg" in header
    assert "psdm_forward_dynamics_derivatives" in capsys.readouterr().out


def test_sweeps_give_the_rows_of_the_derivatives(denso, denso_model, rng):
    """seed = e_i gives row i of every Jacobian, equal to finite differences of Pinocchio's rnea and aba."""
    functions = build_recursive_functions(denso_model, denso)
    derivatives = build_derivative_functions(functions, regressor=False)
    assert [s.name() for s in derivatives.sweeps] == [
        "inverse_dynamics_derivatives_sweep",
        "forward_dynamics_derivatives_sweep",
    ]
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    pm = build_pinocchio_model(denso)
    data, n = pm.createData(), pm.nv
    references = (lambda *a: pin.rnea(pm, data, *a), lambda *a: pin.aba(pm, data, *a))
    args = (rng.uniform(-np.pi, np.pi, n), rng.uniform(-2, 2, n), rng.uniform(-10, 10, n))
    for sweep, reference in zip(derivatives.sweeps, references, strict=True):
        rows = [sweep(*args, theta, np.eye(n)[i]) for i in range(n)]
        _assert_close(rows[0][0], reference(*args)[:, None])
        for block, want in enumerate(_partials(reference, args), start=1):
            _assert_close(np.hstack([row[block].full() for row in rows]).T, want)


def test_lane_writer_keeps_scalar_code_for_what_it_cannot_translate():
    x, seed = ca.SX.sym("x", 2), ca.SX.sym("seed", 2)
    value = ca.vertcat(ca.sin(x[0]) * x[1], x[0] * x[1])
    plain = ca.Function("f", [x, seed], [value, ca.jtimes(value, x, seed, True)])
    assert lane_jacobian(plain, "f", 1, 2) is not None
    seed_in_sin = ca.Function("g", [x, seed], [value, ca.sin(seed) * x])
    assert lane_jacobian(seed_in_sin, "g", 1, 2) is None
    with pytest.raises(ParameterError, match="width must be 2, 4 or 8"):
        lane_jacobian(plain, "f", 1, 2, width=3)
    sparse = ca.Function("h", [x, seed], [value, ca.vertcat(seed[0] * x[0], ca.SX(1, 1))])
    with pytest.raises(ParameterError, match="outputs must be dense"):
        lane_jacobian(sparse, "h", 1, 2)


def _compiled_against_pinocchio(robot, model, folder, rng):
    """Export with theta baked in, compile with and without the vector lanes; both against CasADi and
    finite differences of Pinocchio's rnea and aba."""
    functions = build_recursive_functions(model, robot)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    export = export_derivatives(functions, folder / "out", theta=theta, regressor=False, runtime_theta=False)
    reference = build_derivative_functions(functions, regressor=False)
    pm = build_pinocchio_model(robot)
    data, n = pm.createData(), pm.nv
    oracles = {"inverse": lambda *a: pin.rnea(pm, data, *a), "forward": lambda *a: pin.aba(pm, data, *a)}
    for lanes, flags in ((1, ("-O1",)), (0, ("-O1", "-DPSDM_NO_LANES"))):
        library = build_library(export, build_dir=folder / f"build{lanes}", flags=flags)
        for kind, oracle in oracles.items():
            name = f"psdm_{kind}_dynamics_derivatives"
            assert getattr(ctypes.CDLL(str(library.path)), f"{name}_lanes_enabled")() == lanes
            args = (rng.uniform(-np.pi, np.pi, n), rng.uniform(-2, 2, n), rng.uniform(-10, 10, n))
            got = library.function(name)(*args)
            _assert_equal(got, getattr(reference, f"{kind}_dynamics_derivatives")(*args, theta))
            _assert_close(got[0], oracle(*args)[:, None])
            for block, want in zip(got[1:], _partials(oracle, args), strict=True):
                _assert_close(block, want)


@pytest.mark.needs_cc
@needs_cc
def test_compiled_lanes_equal_pinocchio_denso(tmp_path, denso, denso_model, rng):
    _compiled_against_pinocchio(denso, denso_model, tmp_path, rng)


@pytest.mark.needs_cc
@needs_cc
@pytest.mark.slow
def test_compiled_lanes_equal_pinocchio_panda(tmp_path, rng):
    robot = from_urdf(
        example_robot_urdf("panda_description/urdf/panda.urdf"),
        locked_joints=["panda_finger_joint1", "panda_finger_joint2"],
    )
    _compiled_against_pinocchio(robot, derive_psdm(robot), tmp_path, rng)


@pytest.mark.needs_cc
@needs_cc
def test_compiled_lanes_of_elementary_functions_equal_casadi(tmp_path, rng):
    """The lane writer's C for every instruction it translates (friction-like tanh, sign, |x|, ...) equals
    CasADi, with a seed-independent part and rows in two sweeps of width 2."""
    x, seed = ca.SX.sym("x", 3), ca.SX.sym("seed", 3)
    value = ca.vertcat(
        ca.tanh(x[0] / 0.1) + ca.fabs(x[1]) * ca.sign(x[0]) + ca.exp(x[1]) + ca.sqrt(x[0] ** 2 + 1),
        ca.atan2(x[0], x[1]) + x[0] ** 3 * ca.log(x[1] ** 2 + 1) + ca.fmin(x[0], x[2]) + ca.fmax(x[1], x[2]),
        ca.sin(x[0]) * ca.cos(x[2]) + ca.atan(x[2]) / (x[1] ** 2 + 2) - (x[2] ** 2 + 1) ** x[1],
    )
    jacobian = ca.Function("toy", [x], [value, ca.densify(ca.jacobian(value, x))], ["x"], ["value", "jacobian"])
    sweep = ca.Function("toy_sweep", [x, seed], [value, ca.densify(ca.jtimes(value, x, seed, True))], {"cse": True})
    kernel = lane_jacobian(sweep, "psdm_toy", 1, 3, width=2)
    assert kernel is not None and kernel.n_vector_operations > 0
    export = export_c(jacobian, tmp_path / "out", kernels=[kernel])
    library = build_library(export, build_dir=tmp_path / "build")
    assert ctypes.CDLL(str(library.path)).psdm_toy_lanes_enabled() == 1
    for _ in range(3):
        point = rng.uniform(0.2, 2.0, 3) * rng.choice([-1.0, 1.0], 3)
        _assert_equal(library.function("psdm_toy")(point), jacobian(point))


def test_export_with_a_theta_of_the_wrong_size_is_refused(tmp_path, denso, denso_model):
    with pytest.raises(ShapeError, match="theta must have 32 entries"):
        export_derivatives(build_recursive_functions(denso_model, denso), tmp_path, theta=np.ones(5), regressor=False)
