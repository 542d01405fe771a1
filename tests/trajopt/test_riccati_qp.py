"""The RTI's own QP solver (trajopt.riccati_qp, C): against Ipopt and HPIPM on the same QPs, and its compiled step."""

from __future__ import annotations

import dataclasses
import shutil
import subprocess
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from psdm_casadi.oracle import PinocchioOracle
from trajopt.joint_friction import friction_function
from trajopt.mpc import MPCOptions, variable_bounds
from trajopt.mpc_model import stage_functions
from trajopt.mpc_rti import build_rti, compile_rti, rti_qp_data, rti_qp_solver
from trajopt.riccati_qp import riccati_qp

pytestmark = [pytest.mark.needs_cc, pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")]
DT = 0.005
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def ipopt_qp(h, g, a, b, lbx, ubx):
    """The QP ``min 1/2 z' diag(h) z + g' z, a z = b, lbx <= z <= ubx`` by Ipopt (an independent solver)."""
    z = ca.MX.sym("z", h.size)
    nlp = {"x": z, "f": 0.5 * ca.dot(z, ca.DM(h) * z) + ca.dot(ca.DM(g), z), "g": ca.mtimes(ca.DM(a), z)}
    ipopt = {"print_level": 0, "sb": "yes", "tol": 1e-13, "constr_viol_tol": 1e-13, "bound_relax_factor": 0.0}
    solver = ca.nlpsol("qp", "ipopt", nlp, {"ipopt": ipopt, "print_time": False})
    result = solver(lbx=lbx, ubx=ubx, lbg=b, ubg=b)
    assert solver.stats()["success"]
    return np.array(result["x"]).ravel(), np.array(result["lam_g"]).ravel()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_stage_qp_equals_ipopt_with_and_without_active_bounds(seed):
    """Random stage-structured QPs (dynamics feasible by construction): the unconstrained Riccati path when
    no bound is reached, the interior point when some are; solution and dynamics multipliers to 1e-8."""
    rng = np.random.default_rng(seed)
    nx, nu, horizon = 4, 2, 6
    nz, nw = nx + nu, (nx + nu) * horizon + nx
    jac = rng.normal(0, 0.3, (nx, nz * horizon))
    for k in range(horizon):
        jac[:, k * nz : k * nz + nx] += np.eye(nx)
    b = rng.normal(0, 0.1, nx * horizon)
    h, g = rng.uniform(0.5, 2.0, nw), rng.normal(0, 1.0, nw)
    feasible = np.zeros(nw)
    feasible[:nx] = rng.normal(0, 0.1, nx)
    for k in range(horizon):
        feasible[k * nz + nx : (k + 1) * nz] = rng.normal(0, 0.3, nu)
        feasible[(k + 1) * nz : (k + 1) * nz + nx] = jac[:, k * nz : (k + 1) * nz] @ feasible[k * nz : (k + 1) * nz]
        feasible[(k + 1) * nz : (k + 1) * nz + nx] += b[k * nx : (k + 1) * nx]
    a = np.zeros((nx * horizon, nw))
    for k in range(horizon):
        a[k * nx : (k + 1) * nx, k * nz : (k + 1) * nz] = -jac[:, k * nz : (k + 1) * nz]
        a[k * nx : (k + 1) * nx, (k + 1) * nz : (k + 1) * nz + nx] = np.eye(nx)
    qp = riccati_qp(nx, nu, horizon, 50, 1e-11).function
    spread = rng.uniform(0.5, 1.0, (2, nw))
    for width in (np.inf, 1.0):  # no bound, then bounds that the unconstrained solution crosses
        lbx, ubx = feasible - width * spread[0], feasible + width * spread[1]
        lbx[:nx] = ubx[:nx] = feasible[:nx]
        lbx[-1] = -np.inf  # a one-sided bound
        z, lam = (np.array(v).ravel() for v in qp(h, g, jac, b, lbx, ubx))
        z_ref, lam_ref = ipopt_qp(h, g, a, b, lbx, ubx)
        active = np.sum((z_ref[nx:] - lbx[nx:] < 1e-7) | (ubx[nx:] - z_ref[nx:] < 1e-7))
        assert active == 0 if width == np.inf else 1 <= active <= 4  # few active: unique multipliers
        np.testing.assert_allclose(z, z_ref, rtol=0, atol=1e-8)
        np.testing.assert_allclose(lam, lam_ref, rtol=0, atol=1e-8 * max(1.0, np.abs(lam_ref).max()))


def rti_qp_case(robot, fd, jacobian, horizon, rng):
    """The RTI's QP data at a perturbed guess about a sine reference: (options, model Jacobian, x0, w, p)."""
    options = MPCOptions(horizon=horizon, dt=DT, max_iter=60, tol=1e-11)
    _, model_jacobian = stage_functions(fd, robot.n_dof, DT, 1, friction_function(robot), jacobian)
    n = robot.n_dof
    middle = (robot.q_min + robot.q_max) / 2
    t = np.arange(horizon + 1)[:, None] * DT
    reference = np.hstack(
        [middle + 0.3 * np.sin(2 * np.pi * t), np.full((horizon + 1, n), 0.3) * np.cos(2 * np.pi * t)]
    )
    torque = PinocchioOracle(robot).gravity(reference[0, :n])
    w = np.concatenate([np.hstack([reference[:-1], np.tile(torque, (horizon, 1))]).ravel(), reference[-1]])
    w += rng.normal(0, 1e-3, w.size)
    return options, model_jacobian, reference[0] + 0.02, w, reference.ravel()


def test_rti_qp_with_a_torque_at_its_limit_equals_hpipm_and_ipopt(denso, denso_dynamics, rng):
    """The Denso's RTI QP with joint 1's torque limit cut so that the step hits it: the Riccati interior
    point against HPIPM (robust, converged) and Ipopt, step and dynamics multipliers to 1e-8."""
    fd, jacobian = denso_dynamics
    joints = list(denso.joints)
    joints[0] = dataclasses.replace(joints[0], tau_max=abs(PinocchioOracle(denso).gravity(denso.q_min)[0]) + 0.5)
    robot = dataclasses.replace(denso, joints=tuple(joints))
    horizon = 5
    options, model_jacobian, x0, w, p = rti_qp_case(robot, fd, jacobian, horizon, rng)
    bounds = variable_bounds(robot, horizon)
    data = rti_qp_data(robot, options, model_jacobian, bounds)
    qp = {k: np.array(ca.densify(v)) for k, v in data(x0=x0, w=w, p=p).items()}
    n, nx = robot.n_dof, 2 * robot.n_dof
    nz = nx + n
    a = qp["a"]
    jac = np.hstack([-a[k * nx : (k + 1) * nx, k * nz : (k + 1) * nz] for k in range(horizon)])
    h = np.diag(qp["h"])
    lbx, ubx, b = qp["lbx"].ravel(), qp["ubx"].ravel(), qp["lba"].ravel()
    z, lam = (np.array(v).ravel() for v in riccati_qp(nx, n, horizon, 60, 1e-11).function(h, qp["g"], jac, b, lbx, ubx))
    hpipm = rti_qp_solver(data, dataclasses.replace(options, max_iter=200, tol=1e-12), "robust")
    ref = hpipm(h=qp["h"], g=qp["g"], a=a, lba=b, uba=b, lbx=lbx, ubx=ubx)
    z_ipopt, lam_ipopt = ipopt_qp(h, qp["g"].ravel(), a, b, lbx, ubx)
    at_limit = [k for k in range(horizon) if ubx[k * nz + nx] - z[k * nz + nx] < 1e-7]
    assert at_limit  # the interior point's path: joint 1's torque at its (cut) limit
    scale = np.abs(lam_ipopt).max()
    for z_ref, lam_ref in ((np.array(ref["x"]).ravel(), np.array(ref["lam_a"]).ravel()), (z_ipopt, lam_ipopt)):
        np.testing.assert_allclose(z, z_ref, rtol=0, atol=1e-8)
        np.testing.assert_allclose(lam, lam_ref, rtol=0, atol=1e-8 * scale)


def test_compiled_riccati_step_agrees_with_the_casadi_evaluated_one_and_the_c_program(
    denso, denso_dynamics, tmp_path, rng
):
    """The step's generated C compiled with the QP's C (-O1) against CasADi's evaluation of the same
    Function (the QP loaded from its -O3 build), with no bound active and with a torque at its cut limit
    (the interior point stopped at the benchmark's cap of 4 iterations); then from examples/mpc_rti_loop.c."""
    fd, jacobian = denso_dynamics
    horizon = 4
    joints = list(denso.joints)
    middle = (denso.q_min + denso.q_max) / 2
    joints[1] = dataclasses.replace(joints[1], tau_max=abs(PinocchioOracle(denso).gravity(middle)[1]) * 0.5)
    cut = dataclasses.replace(denso, joints=tuple(joints))
    for robot in (denso, cut):
        options = MPCOptions(horizon=horizon, dt=DT, max_iter=4, tol=1e-3)
        controller = build_rti(robot, fd, options, forward_dynamics_jacobian=jacobian)
        folder = tmp_path / robot.name.replace(" ", "_") / str(robot is cut)
        compiled = compile_rti(controller, folder, flags=("-O1",))
        assert "psdm_hpipm" not in (folder / "mpc_rti.c").read_text() and (folder / "riccati_qp.c").exists()
        _, _, x0, w, p = rti_qp_case(robot, fd, jacobian, horizon, rng)
        for guess in (w, w + rng.normal(0, 1e-2, w.size)):
            expected = controller.function(x0, guess, p)
            for want, got in zip(expected, compiled.function(x0, guess, p)):
                np.testing.assert_allclose(np.array(got), np.array(want), rtol=1e-9, atol=1e-9)
        u = np.array(expected[0]).ravel()
        assert np.all(np.abs(u) <= robot.tau_max + 1e-12)
    assert abs(u[1]) > 0.8 * robot.tau_max[1]  # the cut robot's step: joint 2 pushed towards its limit
    program = tmp_path / "loop"
    subprocess.run(
        ["cc", "-O1", str(EXAMPLES / "mpc_rti_loop.c"), str(folder / "mpc_rti.c"), str(folder / "riccati_qp.c"),
         f"-I{folder}", "-lm", "-o", str(program)],
        check=True,
    )  # fmt: skip
    np.concatenate([x0, w, p]).tofile(tmp_path / "in.bin")
    run = subprocess.run([str(program), str(tmp_path / "in.bin"), str(tmp_path / "out.bin"), "3"], capture_output=True)
    assert run.returncode == 0, run.stderr
    guess = w
    for _ in range(3):
        u, guess, w_sol, _ = (np.array(v).ravel() for v in controller.function(x0, guess, p))
    np.testing.assert_allclose(
        np.fromfile(tmp_path / "out.bin"), np.concatenate([u, guess, w_sol]), rtol=1e-9, atol=1e-9
    )
