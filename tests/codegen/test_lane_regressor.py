"""The vectorised regressor (codegen.lane_regressor) compiled, against the paper's sum model and Pinocchio."""

import ctypes
import math
import shutil

import numpy as np
import pytest

from codegen.build import build_library
from codegen.export import export_c
from codegen.lane_regressor import LANES, lane_kernel
from psdm_casadi import derive_psdm
from psdm_casadi.errors import ParameterError
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.robot import from_dh, from_urdf
from psdm_casadi.samples import kr6, scara
from psdm_casadi.sampling import random_standard_parameters
from tests.conftest import example_robot_urdf

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
FAST = ("-O1",)


def five_dof():
    """The first five KR6 joints: two lane blocks, the second holding one row (spare lanes run on)."""
    pi = math.pi
    return from_dh(
        [
            (0.025, -pi / 2, 0.183, 0),
            (-0.315, 0, 0, 0),
            (-0.035, pi / 2, 0, 0),
            (0, -pi / 2, 0.365, 0),
            (0, pi / 2, 0, 0),
        ],
        name="KR6 first five joints",
    )


def _compiled(robot, folder, flags):
    model = derive_psdm(robot)
    export = export_c(build_recursive_functions(model, robot), folder, lanes=True)  # Y has no theta: one flavour
    return model, export, build_library(export, build_dir=folder / "build", flags=flags)


def _lanes_enabled(library) -> int:
    return ctypes.CDLL(str(library.path)).psdm_regressor_lanes_enabled()


@pytest.mark.needs_cc
@needs_cc
@pytest.mark.parametrize("make", [scara, five_dof, kr6], ids=["scara-4-prismatic", "five-dof", "kr6"])
def test_vector_regressor_equals_the_sum_model_and_pinocchio(make, tmp_path, rng):
    robot = make()
    model, export, library = _compiled(robot, tmp_path, FAST)
    assert "psdm_regressor_lanes" in export.source.read_text()
    assert _lanes_enabled(library) == 1
    regressor = library.function("psdm_regressor")
    standard = random_standard_parameters(robot, rng)
    oracle, theta = PinocchioOracle(robot, standard), model.base_parameters(standard)
    for _ in range(4):
        q, qd, qdd = rng.uniform(-np.pi, np.pi, (3, robot.n_dof))
        y = np.array(regressor(q, qd, qdd))
        reference = model.regressor(q, qd, qdd)
        assert np.abs(reference).max() > 0
        np.testing.assert_allclose(y, reference, rtol=1e-12, atol=1e-12 * np.abs(reference).max())
        np.testing.assert_allclose(y @ theta, oracle.rnea(q, qd, qdd), rtol=1e-9, atol=1e-9)


@pytest.mark.needs_cc
@needs_cc
def test_scalar_fallback_gives_the_same_regressor(tmp_path, rng):
    robot = five_dof()
    _, _, vector = _compiled(robot, tmp_path / "lanes", FAST)
    _, _, scalar = _compiled(robot, tmp_path / "scalar", (*FAST, "-DPSDM_NO_LANES"))
    assert (_lanes_enabled(vector), _lanes_enabled(scalar)) == (1, 0)
    for _ in range(3):
        q, qd, qdd = rng.uniform(-2, 2, (3, robot.n_dof))
        np.testing.assert_allclose(
            np.array(vector.function("psdm_regressor")(q, qd, qdd)),
            np.array(scalar.function("psdm_regressor")(q, qd, qdd)),
            rtol=1e-12,
            atol=1e-13,
        )


@pytest.mark.needs_cc
@needs_cc
def test_missing_inputs_are_zeros_and_a_missing_output_is_skipped(tmp_path, rng):
    robot = scara()
    model, _, library = _compiled(robot, tmp_path, FAST)
    call = ctypes.CDLL(str(library.path)).psdm_regressor
    n, l = robot.n_dof, model.n_base
    q, qdd = rng.uniform(-2, 2, (2, n))
    Pointer = ctypes.POINTER(ctypes.c_double)
    out = np.full(n * l + LANES, 7.0)
    args = (Pointer * 3)(q.ctypes.data_as(Pointer), None, qdd.ctypes.data_as(Pointer))
    assert call(args, (Pointer * 1)(out.ctypes.data_as(Pointer)), None, None, 0) == 0
    expected = model.regressor(q, np.zeros(n), qdd)
    np.testing.assert_allclose(out[: n * l].reshape(l, n).T, expected, rtol=1e-12, atol=1e-12)
    assert np.all(out[n * l :] == 7.0)  # nothing written past Y
    assert call(args, (Pointer * 1)(None), None, None, 0) == 0


def test_lanes_off_and_a_wrong_structure(tmp_path, denso, denso_model):
    functions = build_recursive_functions(denso_model, denso)
    plain = export_c(functions, tmp_path / "plain", lanes=False)
    assert "psdm_regressor_lanes" not in plain.source.read_text()
    other = build_recursive_functions(derive_psdm(scara()), scara())
    with pytest.raises(ParameterError, match="regressor_structure"):
        export_c([functions.regressor], tmp_path / "wrong", regressor_structure=other.regressor_structure)


def test_auto_lanes_follow_the_operation_counts(denso, denso_model, tmp_path):
    """'auto' writes the vector code only when it has fewer operations than CasADi's scalar regressor."""
    from codegen.export import count_operations

    for robot, model in ((denso, denso_model), (five_dof(), None)):
        model = model or derive_psdm(robot)
        functions = build_recursive_functions(model, robot)
        kernel = lane_kernel(functions.regressor_structure, "psdm_regressor")
        assert kernel.count.n_scalars == kernel.parts.nnz_out(0)
        assert kernel.count.parts == count_operations(kernel.parts)
        fewer = kernel.count.n_operations < count_operations(functions.regressor).n_operations
        export = export_c(functions, tmp_path / robot.name.replace(" ", "_"))
        assert ("psdm_regressor_lanes" in export.source.read_text()) == fewer == (export.lane_regressor is not None)
    with pytest.raises(ParameterError, match="lanes"):
        export_c(functions, tmp_path / "bad", lanes="yes")


@pytest.mark.needs_cc
@needs_cc
def test_panda_gets_the_vector_regressor_and_it_is_exact(tmp_path, rng):
    """7 joints: two lane blocks with a spare lane; 'auto' picks the vector code (fewer operations)."""
    robot = from_urdf(
        example_robot_urdf("panda_description/urdf/panda.urdf"),
        locked_joints=["panda_finger_joint1", "panda_finger_joint2"],
    )
    model = derive_psdm(robot)
    functions = build_recursive_functions(model, robot)
    export = export_c([functions.regressor], tmp_path, regressor_structure=functions.regressor_structure)
    library = build_library(export, build_dir=tmp_path / "build", flags=FAST)
    assert _lanes_enabled(library) == 1
    lanes = export.lane_regressor
    assert lanes.name == "psdm_regressor" and lanes.n_scalars > 0
    assert lanes.n_operations < export.operation_count("psdm_regressor").n_operations
    oracle = PinocchioOracle(robot)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    for _ in range(3):
        q, qd, qdd = rng.uniform(-np.pi, np.pi, (3, robot.n_dof))
        y = np.array(library.function("psdm_regressor")(q, qd, qdd))
        reference = model.regressor(q, qd, qdd)
        np.testing.assert_allclose(y, reference, rtol=1e-12, atol=1e-12 * np.abs(reference).max())
        np.testing.assert_allclose(y @ theta, oracle.rnea(q, qd, qdd), rtol=1e-9, atol=1e-9)


@pytest.mark.slow
@pytest.mark.needs_cc
@needs_cc
def test_branching_tree_gets_an_exact_vector_regressor(tmp_path, rng):
    """The Panda with its two finger joints free: both children of joint 7, nine rows in three lane blocks.

    Slow (the derivation of the nine-joint tree takes about 100 s)."""
    robot = from_urdf(example_robot_urdf("panda_description/urdf/panda.urdf"))
    model = derive_psdm(robot)
    functions = build_recursive_functions(model, robot)
    assert functions.regressor_structure.chain.parents[-2:] == (6, 6)
    export = export_c([functions.regressor], tmp_path, regressor_structure=functions.regressor_structure, lanes=True)
    library = build_library(export, build_dir=tmp_path / "build", flags=FAST)
    oracle = PinocchioOracle(robot)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    for _ in range(3):
        q, qd, qdd = rng.uniform(-1, 1, (3, robot.n_dof))
        y = np.array(library.function("psdm_regressor")(q, qd, qdd))
        reference = model.regressor(q, qd, qdd)
        np.testing.assert_allclose(y, reference, rtol=1e-12, atol=1e-12 * np.abs(reference).max())
        np.testing.assert_allclose(y @ theta, oracle.rnea(q, qd, qdd), rtol=1e-9, atol=1e-9)


def test_bad_structure_or_generated_code_names_the_fix(denso, denso_model):
    import dataclasses

    from codegen.lane_regressor import splice, splice_header
    from psdm_casadi.errors import SolverError

    structure = build_recursive_functions(denso_model, denso).regressor_structure
    with pytest.raises(SolverError, match="no unit wrench for preimage row"):
        lane_kernel(dataclasses.replace(structure, unit_wrenches={}), "psdm_regressor")
    kernel = lane_kernel(structure, "psdm_regressor")
    with pytest.raises(SolverError, match="no wrapper for psdm_regressor; export with lanes=False"):
        splice("int main(void) { return 0; }\n", kernel, "psdm_regressor")
    with pytest.raises(SolverError, match='no extern "C" block; export with lanes=False'):
        splice_header("int psdm_regressor(void);\n", "psdm_regressor")
