"""The real-time-iteration MPC: its QP against finite differences and a dense KKT solve, the closed loop, the C."""

from __future__ import annotations

import dataclasses
import shutil
import subprocess
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from psdm_casadi.errors import ParameterError, SolverError
from psdm_casadi.oracle import PinocchioOracle
from tests.trajopt.conftest import sine_reference
from trajopt.hpipm_c import hpipm_cache_folder, persistent_workspace
from trajopt.joint_friction import friction_function
from trajopt.mpc import MPCOptions, variable_bounds
from trajopt.mpc_loop import build_pinocchio_plant, simulate_closed_loop
from trajopt.mpc_model import build_step_function, stage_functions
from trajopt.mpc_rti import build_rti, compile_rti, hpipm_folders, rti_qp_data

DT = 0.005
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def nodes(reference, horizon, t=0.0):
    return np.array([np.concatenate(reference(t + k * DT)) for k in range(horizon + 1)])


def guess_vector(states, torques):
    return np.concatenate([np.hstack([states[:-1], torques]).ravel(), states[-1]])


def test_euler_stage_jacobian_equals_casadi_ad_of_the_step(denso, denso_dynamics, rng):
    n, (fd, jacobian) = denso.n_dof, denso_dynamics
    friction = friction_function(denso)
    step = build_step_function(fd, n, DT, 2, friction, "euler")
    _, model_jacobian = stage_functions(fd, n, DT, 2, friction, jacobian, "euler")
    x, u = ca.SX.sym("x", 2 * n), ca.SX.sym("u", n)
    reference_jacobian = ca.Function("j", [x, u], [ca.jacobian(step(x, u), ca.vertcat(x, u))])
    xv, uv = rng.uniform(-1, 1, 2 * n), rng.uniform(-20, 20, n)
    value, jac = model_jacobian(xv, uv)
    # semi-implicit Euler by hand: qd += h qdd, q += h qd (new), twice
    state = xv.copy()
    for _ in range(2):
        qdd = np.array(fd(state[:n], state[n:], uv - np.array(friction(state[n:])).ravel())).ravel()
        state[n:] += DT / 2 * qdd
        state[:n] += DT / 2 * state[n:]
    np.testing.assert_allclose(np.array(value).ravel(), state, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.array(jac), np.array(reference_jacobian(xv, uv)), rtol=1e-8, atol=1e-8)


def test_qp_linearisation_matches_finite_differences_and_its_step_the_kkt_solve(denso, denso_dynamics, rng):
    """The QP data against central differences of the RK4 model, and HPIPM's step against a dense KKT solve.

    With the state on the reference every bound is inactive, so the first SQP step of the full
    problem is the equality-constrained Gauss-Newton step ``[H A'; A 0] [dw; lam] = [-g; -c]`` with
    dx0 fixed: solved here by numpy, independently of HPIPM's Riccati interior point.
    """
    n, horizon, (fd, jacobian) = denso.n_dof, 3, denso_dynamics
    options = MPCOptions(horizon=horizon, dt=DT, max_iter=50, tol=1e-10)
    controller = build_rti(denso, fd, options, forward_dynamics_jacobian=jacobian, qp_mode="robust")
    friction = friction_function(denso)
    step = build_step_function(fd, n, DT, 1, friction)
    _, model_jacobian = stage_functions(fd, n, DT, 1, friction, jacobian)
    data = rti_qp_data(denso, options, model_jacobian, variable_bounds(denso, horizon))
    reference = sine_reference(denso)
    states = nodes(reference, horizon) + rng.normal(0, 1e-3, (horizon + 1, 2 * n))
    gravity = PinocchioOracle(denso).gravity(states[0, :n])
    w = guess_vector(states, np.tile(gravity, (horizon, 1)) + rng.normal(0, 0.5, (horizon, n)))
    x0, p = nodes(reference, horizon)[0], nodes(reference, horizon).ravel()
    qp = {k: np.array(ca.densify(v)) for k, v in data(x0=x0, w=w, p=p).items()}
    # A: row block k holds d(x_{k+1} - F(x_k, u_k)) / dw, by central differences of the RK4 step
    a_fd, eps = np.zeros_like(qp["a"]), 1e-6
    for j in range(w.size):
        e = np.zeros(w.size)
        e[j] = eps
        gaps = [
            np.concatenate(
                [
                    wv[3 * n * (k + 1) : 3 * n * (k + 1) + 2 * n]
                    - np.array(step(wv[3 * n * k : 3 * n * k + 2 * n], wv[3 * n * k + 2 * n : 3 * n * (k + 1)])).ravel()
                    for k in range(horizon)
                ]
            )  # fmt: skip
            for wv in (w + e, w - e)
        ]
        a_fd[:, j] = (gaps[0] - gaps[1]) / (2 * eps)
    np.testing.assert_allclose(qp["a"], a_fd, rtol=1e-6, atol=1e-6 * np.abs(a_fd).max())
    # the step: equality-constrained KKT with dx0 = x0 - w_x0
    free = np.arange(2 * n, w.size)
    dx0 = x0 - w[: 2 * n]
    h, a = qp["h"], qp["a"]
    g = qp["g"].ravel() + h[:, : 2 * n] @ dx0
    c = -qp["lba"].ravel() + a[:, : 2 * n] @ dx0  # gaps + A_x0 dx0
    hf, af = h[np.ix_(free, free)], a[:, free]
    kkt = np.block([[hf, af.T], [af, np.zeros((af.shape[0], af.shape[0]))]])
    solution = np.linalg.solve(kkt, np.concatenate([-g[free], -c]))
    expected = w + np.concatenate([dx0, solution[: free.size]])
    _, _, w_sol, _ = controller.function(x0, w, p)
    w_sol = np.array(w_sol).ravel()
    assert np.all(w_sol > variable_bounds(denso, horizon)["lbx"]) and np.all(
        w_sol < variable_bounds(denso, horizon)["ubx"]
    )
    np.testing.assert_allclose(w_sol, expected, rtol=1e-6, atol=1e-6)


def test_rti_tracks_the_pinocchio_plant_within_the_torque_limits(denso, denso_dynamics):
    fd, jacobian = denso_dynamics
    options = MPCOptions(horizon=6, dt=DT, max_iter=10, tol=1e-6)
    controller = build_rti(denso, fd, options, forward_dynamics_jacobian=jacobian)
    reference = sine_reference(denso)
    guess = PinocchioOracle(denso).gravity(reference(0.0)[0])
    result = simulate_closed_loop(controller, build_pinocchio_plant(denso), reference, 40, torque_guess=guess)
    assert result.tracking_rmse < 1e-3
    assert np.max(np.abs(result.q - result.q_ref)) < 3e-3
    assert result.limit_violation(denso) == 0.0
    assert np.all(np.abs(result.torque) <= denso.tau_max)


@pytest.mark.parametrize("horizon, max_iter", [(6, 20), (20, 4)])
def test_rti_holds_a_torque_limit_the_reference_would_need_to_exceed(denso, denso_dynamics, horizon, max_iter):
    """A fast reference on joint 1 with its torque limit cut below what tracking needs: saturate, never exceed
    (not by an ulp either), converged and at the benchmark's cap of 4 interior-point iterations."""

    fd, jacobian = denso_dynamics
    joints = list(denso.joints)
    joints[0] = dataclasses.replace(joints[0], tau_max=2.0)
    robot = dataclasses.replace(denso, joints=tuple(joints))
    options = MPCOptions(horizon=horizon, dt=DT, max_iter=max_iter, tol=1e-6)
    controller = build_rti(robot, fd, options, forward_dynamics_jacobian=jacobian)
    reference = sine_reference(robot, amplitude=0.4)
    guess = np.clip(PinocchioOracle(robot).gravity(reference(0.0)[0]), -robot.tau_max, robot.tau_max)
    result = simulate_closed_loop(controller, build_pinocchio_plant(robot), reference, 40, torque_guess=guess)
    assert np.max(np.abs(result.torque[:, 0])) > 0.95 * 2.0  # it does push against the limit
    assert np.all(np.abs(result.torque) <= robot.tau_max)  # exactly: the step is held inside its bounds


@pytest.mark.needs_cc
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_compiled_hpipm_step_agrees_with_the_casadi_evaluated_one(denso, denso_dynamics, tmp_path, rng):
    """The generated C (dynamics, derivatives, HPIPM call with its workspace kept between calls) against
    CasADi's evaluation of the same Function, at the benchmark's iteration cap (4, ``speed_abs``): the
    iterate there is not the QP's solution, and both stop at the same one (the same cap, tolerances,
    options and zero start reach HPIPM); a second call reuses the workspace.
    """
    fd, jacobian = denso_dynamics
    horizon, n = 4, denso.n_dof
    options = MPCOptions(horizon=horizon, dt=DT, max_iter=4, tol=1e-3)
    controller = build_rti(
        denso, fd, options, forward_dynamics_jacobian=jacobian, qp_mode="speed_abs", qp_solver="hpipm"
    )
    compiled = compile_rti(controller, tmp_path, flags=("-O1",))
    assert (tmp_path / "mpc_rti.c").exists() and (tmp_path / "mpc_rti.h").exists()
    assert "static int psdm_hpipm_ready" in (tmp_path / "mpc_rti.c").read_text()
    reference = nodes(sine_reference(denso), horizon)
    gravity = PinocchioOracle(denso).gravity(reference[0, :n])
    w = guess_vector(reference, np.tile(gravity, (horizon, 1))) + rng.normal(0, 1e-2, 3 * n * horizon + 2 * n)
    x0 = reference[0] + rng.normal(0, 1e-2, 2 * n)
    converged = build_rti(
        denso, fd, dataclasses.replace(options, max_iter=50, tol=1e-10), forward_dynamics_jacobian=jacobian,
        qp_mode="robust", qp_solver="hpipm",
    ).function(x0, w, reference.ravel())  # fmt: skip
    for guess in (w, w + rng.normal(0, 1e-2, w.size)):
        expected = controller.function(x0, guess, reference.ravel())
        for want, got in zip(expected, compiled.function(x0, guess, reference.ravel())):
            np.testing.assert_allclose(np.array(got), np.array(want), rtol=1e-9, atol=1e-9)
    assert np.max(np.abs(np.array(expected[2] - converged[2]))) > 1e-6  # the cap does stop short of the solution
    # the same C from a C program (examples/mpc_rti_loop.c): three iterations, the guess shifted in C
    include, lib = hpipm_folders()
    program = tmp_path / "loop"
    subprocess.run(
        ["cc", "-O1", str(EXAMPLES / "mpc_rti_loop.c"), str(tmp_path / "mpc_rti.c"), f"-I{tmp_path}", f"-I{include}",
         f"-L{lib}", "-lhpipm", "-lblasfeo", f"-Wl,-rpath,{lib}", "-lm", "-o", str(program)],
        check=True,
    )  # fmt: skip
    np.concatenate([x0, w, reference.ravel()]).tofile(tmp_path / "in.bin")
    files = [str(tmp_path / "in.bin"), str(tmp_path / "out.bin")]
    run = subprocess.run([str(program), *files, "3"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert all(float(t) > 0 for t in run.stdout.split())  # wall and CPU microseconds per step
    guess = w
    for _ in range(3):
        u, guess, w_sol, _ = (np.array(v).ravel() for v in controller.function(x0, guess, reference.ravel()))
    out = np.fromfile(tmp_path / "out.bin")
    np.testing.assert_allclose(out, np.concatenate([u, guess, w_sol]), rtol=1e-9, atol=1e-9)


def test_bad_qp_mode_and_dynamics_are_refused(denso, denso_dynamics):
    fd, _ = denso_dynamics
    with pytest.raises(ParameterError, match="qp_mode"):
        build_rti(denso, fd, MPCOptions(horizon=2, dt=DT), qp_mode="fastest")
    q, qd, tau = (ca.SX.sym(name, 2) for name in ("q", "qd", "tau"))
    with pytest.raises(ParameterError, match="forward_dynamics"):
        build_rti(denso, ca.Function("f", [q, qd, tau], [q + qd + tau]), MPCOptions(horizon=2, dt=DT))
    with pytest.raises(ParameterError, match="MPCOptions.integrator"):
        MPCOptions(integrator="midpoint")


def test_crocoddyl_peer_solves_the_same_problem_or_names_the_fix(denso, denso_dynamics):
    """Crocoddyl's converged FDDP and Ipopt on ``trajopt.mpc``'s NLP (PSDM dynamics) give the same first
    torque: the same cost, weights and Euler discretisation. Without a working crocoddyl (the project's
    own environment: its wheel needs another Pinocchio) the builder names the fix instead."""
    import dataclasses

    from trajopt.mpc import build_mpc
    from trajopt.mpc_crocoddyl import build_crocoddyl_mpc, crocoddyl_missing_reason

    options = MPCOptions(horizon=5, dt=DT, integrator="euler", solver="ipopt", max_iter=200, tol=1e-12)
    if crocoddyl_missing_reason() is not None:
        with pytest.raises(ParameterError, match="pip install"):
            build_crocoddyl_mpc(denso, options)
        return
    robot = dataclasses.replace(denso, drives=None)  # Crocoddyl's free forward dynamics has no drive friction
    reference = nodes(sine_reference(robot), options.horizon)
    torques = np.tile(PinocchioOracle(robot).gravity(reference[0, : robot.n_dof]), (options.horizon, 1))
    ipopt = build_mpc(robot, denso_dynamics[0], options, friction=False)
    croc = build_crocoddyl_mpc(robot, options, solver="fddp", iterations=100)
    firsts = []
    for controller in (ipopt, croc):
        controller.initialize(reference, torques)
        firsts.append(controller.step(reference[0] + 0.01, reference)[0])
    np.testing.assert_allclose(firsts[1], firsts[0], rtol=1e-5, atol=1e-6 * np.abs(firsts[0]).max())


def test_hpipm_folder_without_the_headers_is_refused_naming_the_fix(tmp_path, monkeypatch):
    monkeypatch.setenv("PSDM_HPIPM_DIR", str(tmp_path))
    with pytest.raises(ParameterError, match="include/hpipm_d_ocp_qp_ipm.h"):
        hpipm_folders()
    monkeypatch.delenv("PSDM_HPIPM_DIR")
    include, lib = hpipm_folders()  # CasADi's own copies
    assert (include / "hpipm_d_ocp_qp_ipm.h").exists() and any(lib.glob("libhpipm*"))


def test_generated_hpipm_call_of_another_shape_is_refused_not_patched_blindly():
    with pytest.raises(SolverError, match="casadi_hpipm_solve"):
        persistent_workspace("int main(void) { return 0; }")
    one_allocation = "int casadi_hpipm_solve(void) {\n    void *m = malloc(n);\n   return d->return_status==0;\n}"
    with pytest.raises(SolverError, match="differently than expected"):
        persistent_workspace(one_allocation)


def test_make_hpipm_build_is_used_when_this_cpu_runs_it_else_casadis_copies(tmp_path, monkeypatch, caplog):
    monkeypatch.delenv("PSDM_HPIPM_DIR", raising=False)
    monkeypatch.setenv("PSDM_CACHE_DIR", str(tmp_path))
    casadi_include, casadi_lib = hpipm_folders()  # nothing built: CasADi's portable copies
    assert casadi_lib == Path(ca.__file__).parent
    cached = hpipm_cache_folder()
    assert cached == tmp_path / "hpipm"
    (cached / "lib").mkdir(parents=True)
    (cached / "include").mkdir()
    (cached / "include" / "hpipm_d_ocp_qp_ipm.h").write_text("")
    (cached / "include" / "blasfeo_target.h").write_text(
        "#define TARGET_NEED_FEATURE_AVX2 1\n#define TARGET_NEED_FEATURE_FMA 1\n"
    )
    monkeypatch.setattr("trajopt.hpipm_c.cpu_flags", lambda: {"avx", "avx2", "fma"})
    assert hpipm_folders() == (cached / "include", cached / "lib")
    monkeypatch.setattr("trajopt.hpipm_c.cpu_flags", lambda: {"avx", "sse4_2"})  # a CPU without AVX2: not that build
    with caplog.at_level("WARNING", logger="trajopt.hpipm_c"):
        assert hpipm_folders() == (casadi_include, casadi_lib)
    assert "lacks avx2, fma" in caplog.text
