"""The CppADCodeGen peer of the speed benchmark: missing headers named, null ratios with a reason, model file."""

import numpy as np
import pytest

from codegen.peers import cppadcg
from codegen.peers.speed import CPPADCG_RATIOS, cppadcg_speedups, derivative_speedups
from psdm_casadi.errors import SolverError
from psdm_casadi.oracle import build_pinocchio_model


def test_missing_headers_name_the_wheel_to_install(tmp_path):
    with pytest.raises(SolverError, match="cmeel-cppad"):
        cppadcg.check_headers(tmp_path)
    (tmp_path / "cppad").mkdir()
    (tmp_path / "cppad" / "cppad.hpp").write_text("")
    with pytest.raises(SolverError, match="cmeel-cppadcodegen"):
        cppadcg.check_headers(tmp_path)


def test_unbuilt_peer_gives_null_ratios_and_its_reason():
    ratios = cppadcg_speedups({}, "cppad/cg.hpp not found")
    assert ratios["cppadcg_error"] == "cppad/cg.hpp not found"
    assert all(ratios[name] is None for name, _, _ in CPPADCG_RATIOS)


def test_ratios_are_against_the_fastest_cppadcg_route():
    ns = {
        "psdm_id": 50.0,
        "psdm_fd": 100.0,
        "psdm_regressor": 80.0,
        "psdm_id_derivatives": 300.0,
        "psdm_fd_derivatives": 400.0,
        "cppadcg_rnea": 100.0,
        "cppadcg_aba": 150.0,
        "cppadcg_regressor": 400.0,
        "cppadcg_rnea_jacobian": 900.0,
        "cppadcg_rnea_derivatives": 600.0,
        "cppadcg_aba_jacobian": 1200.0,
        "cppadcg_aba_derivatives": 2000.0,
        "pinocchio_rnea_derivatives": 1500.0,
        "pinocchio_aba_derivatives": 2000.0,
    }
    ratios = cppadcg_speedups(ns, None)
    assert ratios["id_speedup_vs_cppadcg"] == 2.0 and ratios["regressor_speedup_vs_cppadcg"] == 5.0
    assert ratios["id_derivatives_speedup_vs_cppadcg"] == 2.0  # the generated derivatives, faster than the Jacobian
    assert ratios["fd_derivatives_speedup_vs_cppadcg"] == 3.0  # the Jacobian, faster than the generated derivatives
    assert derivative_speedups(ns) == {
        "id_derivatives_speedup_vs_pinocchio": 5.0,
        "fd_derivatives_speedup_vs_pinocchio": 5.0,
    }


def test_model_file_holds_every_joint_and_inertia(tmp_path, denso):
    pin_model = build_pinocchio_model(denso)
    path = tmp_path / "model.txt"
    cppadcg.write_model_file(pin_model, path)
    lines = path.read_text().splitlines()
    assert int(lines[0]) == pin_model.njoints and len(lines) == pin_model.njoints + 2
    for jid in range(1, pin_model.njoints):
        fields = lines[jid].split()
        assert int(fields[0]) == pin_model.parents[jid] and fields[1] == pin_model.joints[jid].shortname()
        numbers = np.array(fields[2:], dtype=float)
        np.testing.assert_array_equal(numbers[3:12], pin_model.jointPlacements[jid].rotation.ravel())
        assert numbers[15] == pin_model.inertias[jid].mass
    np.testing.assert_array_equal(np.array(lines[-1].split(), dtype=float), pin_model.gravity.linear)


def test_harness_declares_every_generated_function():
    declarations, setup, timing = cppadcg.harness_code(60)
    for name, kind, _ in cppadcg.MODELS:
        assert f"void {name}_{kind}(" in declarations
        assert f"cppadcg_{name}_{kind}_call" in setup and f"cppadcg_{name}_{kind}_call" in timing
    assert "const int n_regressor = 60;" in setup
