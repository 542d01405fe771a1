"""The MPC on the exported C forward dynamics (casadi.external with its exported Jacobians) equals the SX one."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from codegen.build import build_library
from codegen.export import export_c
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.recursive import build_recursive_functions
from trajopt.mpc import MPCOptions, build_mpc
from trajopt.mpc_loop import build_pinocchio_plant, simulate_closed_loop


@pytest.mark.slow
@pytest.mark.needs_cc
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_mpc_on_exported_c_matches_the_sx_model(denso, denso_model, tmp_path):
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    fd = build_recursive_functions(denso_model, denso, theta).forward_dynamics
    library = build_library(export_c([fd], tmp_path / "c", jacobians=True), build_dir=tmp_path / "build")
    options = MPCOptions(horizon=5, dt=0.005, solver="sqpmethod", qp_solver="hpipm", max_iter=4)
    middle = (denso.q_min + denso.q_max) / 2

    def reference(t):
        return middle + 0.1 * np.sin(3 * t), np.full(denso.n_dof, 0.3 * np.cos(3 * t))

    guess = PinocchioOracle(denso).gravity(middle)
    runs = []
    for controller in (
        build_mpc(denso, fd, options),
        build_mpc(
            denso,
            library.function("psdm_forward_dynamics"),
            options,
            forward_dynamics_jacobian=library.function("psdm_forward_dynamics_jac"),
        ),
    ):
        runs.append(simulate_closed_loop(controller, build_pinocchio_plant(denso), reference, 6, torque_guess=guess))
    sx, external = runs
    np.testing.assert_allclose(external.torque, sx.torque, rtol=1e-7, atol=1e-7 * np.abs(sx.torque).max())
    assert external.tracking_rmse < 1e-3 and external.limit_violation(denso) == 0.0
