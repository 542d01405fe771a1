"""A small theta-linear toy model (Functions named like DynamicsFunctions) for export tests without PSDM."""

from types import SimpleNamespace

import casadi as ca
import numpy as np

N_DOF, N_BASE = 3, 5
# theta with zero entries: baking it in must drop the products with them
THETA = np.array([1.5, 0.0, -0.7, 0.0, 2.25])


def toy_functions():
    q, qd, qdd = (ca.SX.sym(name, N_DOF) for name in ("q", "qd", "qdd"))
    theta, tau = ca.SX.sym("theta", N_BASE), ca.SX.sym("tau", N_DOF)
    s, c = ca.sin(q), ca.cos(q)
    y = ca.horzcat(qdd, s * c * qd, c * qd**2, s * s * qdd, ca.vertcat(s[0] * c[1], s[1] * c[2], s[2] * c[0]))
    mass = ca.diag(theta[0] + theta[3] * s * s + 0.1)
    bias = y[:, 1] * theta[1] + y[:, 2] * theta[2] + y[:, 4] * theta[4]
    return SimpleNamespace(
        inverse_dynamics=ca.Function(
            "inverse_dynamics", [q, qd, qdd, theta], [y @ theta], ["q", "qd", "qdd", "theta"], ["tau"]
        ),
        forward_dynamics=ca.Function(
            "forward_dynamics", [q, qd, tau, theta], [ca.solve(mass, tau - bias)], ["q", "qd", "tau", "theta"], ["qdd"]
        ),
        regressor=ca.Function("regressor", [q, qd, qdd], [y], ["q", "qd", "qdd"], ["Y"]),
        mass_matrix=None,
    )


def random_inputs(function, rng, theta=THETA):
    """Random non-zero inputs for each input of a Function (theta is the given one)."""
    return [
        theta if function.name_in(i) == "theta" else rng.uniform(-1.5, 1.5, function.nnz_in(i))
        for i in range(function.n_in())
    ]
