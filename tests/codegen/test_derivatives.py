"""Exported derivatives: equal to finite differences of Pinocchio (Denso, Panda), compiled C equals CasADi."""

import shutil

import numpy as np
import pinocchio as pin
import pytest

from codegen.build import build_library
from codegen.derivatives import build_derivative_functions, export_derivatives
from codegen.operation_count import count_operations
from psdm_casadi.cli import main
from psdm_casadi.derive import derive_psdm
from psdm_casadi.errors import ParameterError
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
