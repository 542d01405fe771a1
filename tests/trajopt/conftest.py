"""Fixtures of the trajopt tests: a planar 2R arm with an analytic base-parameter regressor, and the Denso's
forward dynamics with their Jacobian and a sine reference for the MPC tests."""

import casadi as ca
import numpy as np
import pytest

from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.robot import from_dh
from trajopt.mpc_model import build_forward_dynamics_jacobian

G = 9.81
A1 = 0.5  # length of link 1 [m]


def planar_regressor_numpy(q, qd, qdd, g=G):
    """Analytic regressor of a planar 2R arm, base parameters
    [I1 + m2 a1^2, I2 (about joint 2), m2 a1 lc2, m1 lc1 + m2 a1, m2 lc2]; gravity along -y of the plane."""
    q, qd, qdd = (np.atleast_2d(a) for a in (q, qd, qdd))
    c1, c2, s2, c12 = np.cos(q[:, 0]), np.cos(q[:, 1]), np.sin(q[:, 1]), np.cos(q[:, 0] + q[:, 1])
    n = q.shape[0]
    y = np.zeros((n, 2, 5))
    y[:, 0, 0] = qdd[:, 0]
    y[:, 0, 1] = qdd[:, 0] + qdd[:, 1]
    y[:, 0, 2] = (2 * qdd[:, 0] + qdd[:, 1]) * c2 - s2 * (2 * qd[:, 0] * qd[:, 1] + qd[:, 1] ** 2)
    y[:, 0, 3] = g * c1
    y[:, 0, 4] = g * c12
    y[:, 1, 1] = qdd[:, 0] + qdd[:, 1]
    y[:, 1, 2] = qdd[:, 0] * c2 + s2 * qd[:, 0] ** 2
    y[:, 1, 4] = g * c12
    return y


def build_planar_regressor():
    q, qd, qdd = (ca.SX.sym(n, 2) for n in ("q", "qd", "qdd"))
    c1, c2, s2, c12 = ca.cos(q[0]), ca.cos(q[1]), ca.sin(q[1]), ca.cos(q[0] + q[1])
    y = ca.SX.zeros(2, 5)
    y[0, 0] = qdd[0]
    y[0, 1] = qdd[0] + qdd[1]
    y[0, 2] = (2 * qdd[0] + qdd[1]) * c2 - s2 * (2 * qd[0] * qd[1] + qd[1] ** 2)
    y[0, 3] = G * c1
    y[0, 4] = G * c12
    y[1, 1] = qdd[0] + qdd[1]
    y[1, 2] = qdd[0] * c2 + s2 * qd[0] ** 2
    y[1, 4] = G * c12
    return ca.Function("regressor", [q, qd, qdd], [y], ["q", "qd", "qdd"], ["Y"])


PLANAR_GRAVITY_MASK = np.array([False, False, False, True, True])


def sine_reference(robot, amplitude=0.15):
    """``t -> (q, qd)``: every joint a 0.5 Hz sine of ``amplitude`` [rad] about the middle of its range (the MPC
    tests' reference)."""
    middle = (robot.q_min + robot.q_max) / 2
    omega = 2 * np.pi * 0.5

    def reference(t):
        return middle + amplitude * np.sin(omega * t), np.full(robot.n_dof, amplitude * omega * np.cos(omega * t))

    return reference


@pytest.fixture(scope="session")
def planar_regressor():
    return build_planar_regressor()


@pytest.fixture(scope="session")
def planar_robot():
    limits = [
        dict(q_min=-2.0, q_max=2.0, qd_max=2.0, qdd_max=6.0, tau_max=50.0),
        dict(q_min=-2.5, q_max=2.5, qd_max=3.0, qdd_max=8.0, tau_max=20.0),
    ]
    return from_dh([(A1, 0.0, 0.0, 0.0), (0.4, 0.0, 0.0, 0.0)], gravity=(0.0, -G, 0.0), name="planar2r", limits=limits)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="session")
def denso_functions(denso, denso_model):
    """The Denso's nominal model as recursive CasADi functions (``forward_dynamics``, ``inverse_dynamics``,
    ``mass_matrix``), shared by the MPC, RTI and Riccati-QP tests."""
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    return build_recursive_functions(denso_model, denso, theta)


@pytest.fixture(scope="session")
def denso_dynamics(denso_functions):
    """(forward dynamics, its Jacobian) of the Denso's nominal model, shared by the RTI and Riccati-QP tests."""
    functions = denso_functions
    jacobian = build_forward_dynamics_jacobian(
        functions.forward_dynamics, functions.inverse_dynamics, functions.mass_matrix
    )
    return functions.forward_dynamics, jacobian
