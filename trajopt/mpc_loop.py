"""Closed loop of the tracking MPC: the drives' friction in numbers, an independent Pinocchio plant and the run.

The plant shares no code with the controller's model: Pinocchio's aba on the robot's own
kinematics and inertias, minus the same smooth friction law, integrated by RK4 with several
steps per control interval.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psdm_casadi.description import RobotDescription
from trajopt.joint_friction import friction_torque
from trajopt.mpc import MPCController
from trajopt.mpc_model import rk4


def build_pinocchio_plant(robot: RobotDescription, *, friction=True):
    """The plant ``(q, qd, tau) -> qdd``: Pinocchio's aba on the robot's own model, minus the drives' friction.

    It shares no code with the PSDM model or the CasADi peers, so a controller that tracks it is
    tested against an independent implementation of the same physics.
    """
    from psdm_casadi.oracle import PinocchioOracle

    oracle = PinocchioOracle(robot)

    def plant(q, qd, tau):
        return oracle.aba(q, qd, tau - friction_torque(robot, qd) if friction else tau)

    return plant


@dataclass(frozen=True)
class ClosedLoopResult:
    """A closed-loop run: plant states, applied torques, references and per-step solver figures.

    Attributes
    ----------
    time : ndarray, shape (n_steps + 1,) [s]
    q, qd, q_ref : ndarray, shape (n_steps + 1, n_dof)
    torque : ndarray, shape (n_steps, n_dof) [N m]
    step_time_s, step_cpu_s : ndarray, shape (n_steps,)
        Wall and process CPU time of each controller solve [s].
    iterations : ndarray, shape (n_steps,)
    statuses : tuple of str
        CasADi's unified return status of each solve (``SOLVER_RET_SUCCESS``, ``SOLVER_RET_LIMITED`` when
        the iteration cap of the real-time scheme stopped it, ...).
    """

    time: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    q_ref: np.ndarray
    torque: np.ndarray
    step_time_s: np.ndarray
    step_cpu_s: np.ndarray
    iterations: np.ndarray
    statuses: tuple

    @property
    def tracking_rmse(self) -> float:
        """RMS joint position error [rad] over all joints and the states after the first."""
        return float(np.sqrt(np.mean((self.q[1:] - self.q_ref[1:]) ** 2)))

    def limit_violation(self, robot: RobotDescription) -> float:
        """Largest excess of the plant's positions, velocities or the applied torques over the robot's limits."""
        excess = [
            np.max(robot.q_min - self.q),
            np.max(self.q - robot.q_max),
            np.max(np.abs(self.qd) - robot.qd_max),
            np.max(np.abs(self.torque) - robot.tau_max),
        ]
        return float(max(0.0, *excess))


def simulate_closed_loop(controller: MPCController, plant, reference, n_steps: int, *, substeps=4, torque_guess=None):
    """Run the MPC against a plant for n_steps control intervals, starting on the reference.

    Parameters
    ----------
    controller : MPCController
    plant : callable
        ``(q, qd, tau) -> qdd``, integrated by RK4 with ``substeps`` steps per control interval (a
        finer integration than the controller's).
    reference : callable
        ``t -> (q_ref, qd_ref)``, each (n_dof,).
    n_steps : int
    torque_guess : array, shape (n_dof,) or (N, n_dof), optional
        Torques of the first guess (the states are the reference's); zeros by default.

    Returns
    -------
    ClosedLoopResult
    """
    options, n = controller.options, controller.n_dof
    dt, horizon = options.dt, options.horizon

    def nodes(t):
        return np.array([np.concatenate(reference(t + k * dt)) for k in range(horizon + 1)])

    guess = np.zeros((horizon, n)) if torque_guess is None else np.broadcast_to(torque_guess, (horizon, n))
    controller.initialize(nodes(0.0), guess)
    x = nodes(0.0)[0]
    states, torques, times, cpu, iterations, statuses = [x], [], [], [], [], []
    for i in range(n_steps):
        tau, stats = controller.step(x, nodes(i * dt))
        x = _integrate(plant, x, tau, dt, substeps, n)
        states.append(x)
        torques.append(tau)
        times.append(stats["time_s"])
        cpu.append(stats["cpu_time_s"])
        iterations.append(stats.get("iter_count", -1))
        statuses.append(str(stats.get("unified_return_status", stats.get("return_status"))))
    states = np.array(states)
    t = dt * np.arange(n_steps + 1)
    return ClosedLoopResult(
        time=t,
        q=states[:, :n],
        qd=states[:, n:],
        q_ref=np.array([reference(tk)[0] for tk in t]),
        torque=np.array(torques),
        step_time_s=np.array(times),
        step_cpu_s=np.array(cpu),
        iterations=np.array(iterations),
        statuses=tuple(statuses),
    )


def _integrate(plant, x, tau, dt, substeps, n):
    """RK4 of (q, qd)' = (qd, plant(q, qd, tau)) over dt in substeps steps."""

    def rhs(state):
        return np.concatenate([state[n:], plant(state[:n], state[n:], tau)])

    return rk4(rhs, x, dt, substeps)
