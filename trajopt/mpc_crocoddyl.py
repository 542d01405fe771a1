"""Crocoddyl's FDDP/BoxFDDP on the tracking task of ``trajopt.mpc``: the peer MPC a user would otherwise pick.

The same horizon, interval, cost weights and torque limits as ``trajopt.mpc`` (its ``MPCOptions``),
on Pinocchio's model of the robot with Crocoddyl's analytical derivatives (``pip install crocoddyl``,
the optional ``bench`` extra). The cost maps term by term: Crocoddyl's running cost is
``dt * 1/2 r' W r`` at node k (x_k, u_k) and its terminal cost ``1/2 r' W r`` at x_N, so the weights
``2 w / dt`` (running) and ``2 w`` (terminal) give exactly ``sum_k wq |q_k - q_ref|^2 + wv |qd_k -
qd_ref|^2 + wu |tau_k / tau_max|^2`` (x_0 is fixed). With ``integrator="euler"`` the discretisation is
the same semi-implicit Euler as the controller's; with ``"rk4"`` Crocoddyl's RK4 also averages the
running cost over its four stage points (a slightly different quadrature of the same integral).
Joint position and velocity limits are not constraints of FDDP (``limit_violation`` reports them).
The controller has the ``initialize``/``step`` interface of ``trajopt.mpc_loop.simulate_closed_loop``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import ParameterError

SOLVERS = ("fddp", "box-fddp")


def crocoddyl_missing_reason() -> str | None:
    """None when crocoddyl imports and computes Pinocchio's dynamics, else why not and the fix.

    Crocoddyl's wheels compile Pinocchio's templates into libcrocoddyl: one built for another
    Pinocchio than the installed ``pin`` imports fine but reads its models with the wrong layout
    (crocoddyl 3.2.1 with pin 4.1 returns accelerations off by tens of rad/s^2), so the check
    compares one forward dynamics with ``pinocchio.aba``.
    """
    try:
        import crocoddyl
        import pinocchio
    except ImportError as error:
        return f"import crocoddyl failed ({error}); install the optional extra: pip install 'psdm-casadi[bench]'"
    model = pinocchio.buildSampleModelManipulator()
    state = crocoddyl.StateMultibody(model)
    differential = crocoddyl.DifferentialActionModelFreeFwdDynamics(
        state, crocoddyl.ActuationModelFull(state), crocoddyl.CostModelSum(state, model.nv)
    )
    data = differential.createData()
    q, v, tau = pinocchio.neutral(model) + 0.3, np.full(model.nv, 0.2), np.linspace(-1.0, 1.0, model.nv)
    differential.calc(data, np.concatenate([q, v]), tau)
    error = float(np.max(np.abs(data.xout - pinocchio.aba(model, model.createData(), q, v, tau))))
    if not error < 1e-8:
        return (
            f"crocoddyl {crocoddyl.__version__} disagrees with pinocchio {pinocchio.__version__}'s aba by {error:.3g} "
            "rad/s^2 (a wheel built for another Pinocchio); install a matching pair in its own environment, "
            "e.g. pip install crocoddyl==3.1.0 pin==3.8.0"
        )
    return None


@dataclass
class CrocoddylController:
    """A Crocoddyl shooting problem and solver, re-solved from the shifted previous solution each interval.

    Attributes
    ----------
    solver : crocoddyl.SolverFDDP or crocoddyl.SolverBoxFDDP
    options : MPCOptions
        Horizon, interval, integrator and weights (the fields of the NLP solvers do not apply).
    n_dof : int
    iterations : int
        Solver iterations per control interval (1: the real-time scheme).
    """

    solver: object
    options: object
    n_dof: int
    iterations: int = 1
    _xs: list | None = field(default=None, repr=False)
    _us: list | None = field(default=None, repr=False)

    def initialize(self, states, torques) -> None:
        """Set the first guess: states (N + 1, 2 n_dof) and torques (N, n_dof)."""
        states, torques = np.asarray(states, dtype=float), np.asarray(torques, dtype=float)
        n, horizon = self.n_dof, self.options.horizon
        if states.shape != (horizon + 1, 2 * n) or torques.shape != (horizon, n):
            raise ParameterError(
                f"CrocoddylController.initialize needs states ({horizon + 1}, {2 * n}) and torques "
                f"({horizon}, {n}); got {states.shape} and {torques.shape}."
            )
        self._xs, self._us = list(states), list(torques)

    def step(self, state, reference) -> tuple[np.ndarray, dict]:
        """Solve one interval from the measured state; returns the first torque and the solve's figures.

        The references are written into the cost models before the timer starts; the timed part is
        Crocoddyl's ``solve`` alone (its derivatives, backward pass and line search).
        """
        n, horizon = self.n_dof, self.options.horizon
        reference, state = np.asarray(reference, dtype=float), np.asarray(state, dtype=float)
        if reference.shape != (horizon + 1, 2 * n) or state.shape != (2 * n,):
            raise ParameterError(
                f"CrocoddylController.step needs state ({2 * n},) and reference ({horizon + 1}, {2 * n}); "
                f"got {state.shape} and {reference.shape}."
            )
        if self._xs is None:
            raise ParameterError("CrocoddylController.step needs a first guess; call initialize first.")
        problem = self.solver.problem
        for k, model in enumerate([*problem.runningModels, problem.terminalModel]):
            model.differential.costs.costs["state"].cost.residual.reference = reference[k]
        problem.x0 = state
        xs = [state, *self._xs[1:]]
        start, start_cpu = time.perf_counter(), time.process_time()
        self.solver.solve(xs, self._us, self.iterations, False)
        elapsed, cpu = time.perf_counter() - start, time.process_time() - start_cpu
        xs, us = list(self.solver.xs), list(self.solver.us)
        self._xs, self._us = [*xs[1:], xs[-1]], [*us[1:], us[-1]]
        stats = {"time_s": elapsed, "cpu_time_s": cpu, "iter_count": self.solver.iter, "return_status": "fddp"}
        return np.array(us[0]), stats


def build_crocoddyl_mpc(
    robot: RobotDescription, options, *, solver: str = "box-fddp", iterations: int = 1
) -> CrocoddylController:
    """Crocoddyl's FDDP or BoxFDDP on the tracking task of ``options`` (an ``MPCOptions``).

    Parameters
    ----------
    robot : RobotDescription
        Pinocchio's model of it (``psdm_casadi.oracle``) is the controller's model; no drive friction.
    options : MPCOptions
    solver : {"fddp", "box-fddp"}
        BoxFDDP keeps the torques within ``robot.tau_max``; FDDP has no bounds.
    iterations : int
        Solver iterations per control interval.

    Raises
    ------
    ParameterError
        On an unknown solver, or when crocoddyl is not installed (naming the extra to install).
    """
    reason = crocoddyl_missing_reason()
    if reason:
        raise ParameterError(f"build_crocoddyl_mpc needs crocoddyl: {reason}.")
    if solver not in SOLVERS:
        raise ParameterError(f"build_crocoddyl_mpc solver must be one of {SOLVERS}; got {solver!r}.")
    import crocoddyl

    from psdm_casadi.oracle import PinocchioOracle

    model = PinocchioOracle(robot).model
    state = crocoddyl.StateMultibody(model)
    actuation = crocoddyl.ActuationModelFull(state)
    n, dt = robot.n_dof, options.dt
    tau_scale = np.where(np.isfinite(robot.tau_max), robot.tau_max, 1.0)
    state_weights = 2 * np.concatenate([np.full(n, options.position_weight), np.full(n, options.velocity_weight)])
    torque_weights = 2 * options.torque_weight / tau_scale**2

    def node(terminal: bool):
        costs = crocoddyl.CostModelSum(state, n)
        weights = state_weights if terminal else state_weights / dt
        residual = crocoddyl.ResidualModelState(state, np.zeros(2 * n), n)
        activation = crocoddyl.ActivationModelWeightedQuad(weights)
        costs.addCost("state", crocoddyl.CostModelResidual(state, activation, residual), 1.0)
        if not terminal:
            control = crocoddyl.ActivationModelWeightedQuad(torque_weights / dt)
            costs.addCost(
                "torque", crocoddyl.CostModelResidual(state, control, crocoddyl.ResidualModelControl(state, n)), 1.0
            )
        differential = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, costs)
        if options.integrator == "euler":
            integrated = crocoddyl.IntegratedActionModelEuler(differential, 0.0 if terminal else dt)
        else:
            integrated = crocoddyl.IntegratedActionModelRK(differential, crocoddyl.RKType.four, 0.0 if terminal else dt)
        if not terminal:
            integrated.u_lb, integrated.u_ub = -robot.tau_max, robot.tau_max
        return integrated

    problem = crocoddyl.ShootingProblem(np.zeros(2 * n), [node(False) for _ in range(options.horizon)], node(True))
    problem.nthreads = 1  # one core, as the compiled RTI step
    shooting = crocoddyl.SolverBoxFDDP(problem) if solver == "box-fddp" else crocoddyl.SolverFDDP(problem)
    return CrocoddylController(shooting, options, n, iterations)
