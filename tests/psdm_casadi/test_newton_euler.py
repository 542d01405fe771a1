"""The two forms of the link wrench against the rigid-body formula in numpy, and what each costs."""

import casadi as ca
import numpy as np
import pytest

from codegen.export import count_operations
from psdm_casadi.kinematics_sx import joint_chain
from psdm_casadi.newton_euler import LinkMotion, _u_matrix, link_wrench, link_wrench_per_parameter, newton_euler
from psdm_casadi.oracle import N_PARAMETERS_PER_JOINT, build_pinocchio_model


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _reference_wrench(w, dw, dv, link):
    """Force and moment about the frame origin of a rigid body, from its 10 parameters (numpy)."""
    m, first_moment = link[0], np.asarray(link[1:4])
    xx, xy, yy, xz, yz, zz = link[4:10]
    inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    force = m * dv + (_skew(dw) + _skew(w) @ _skew(w)) @ first_moment
    moment = inertia @ dw + np.cross(first_moment, dv) + np.cross(w, inertia @ w)
    return force, moment


def _motion(w, dw, dv):
    w, dw, dv = (ca.SX(ca.DM(v)) for v in (w, dw, dv))
    return LinkMotion(w, dw, dv, _u_matrix(w, dw))


@pytest.mark.parametrize("wrench", [link_wrench, link_wrench_per_parameter], ids=["matrix", "per-parameter"])
def test_link_wrench_forms_equal_the_rigid_body_formula(wrench, rng):
    for _ in range(5):
        w, dw, dv = rng.normal(size=(3, 3))
        link = rng.normal(size=10)
        force, moment = (np.array(ca.DM(x)).ravel() for x in wrench(_motion(w, dw, dv), list(link)))
        ref_force, ref_moment = _reference_wrench(w, dw, dv, link)
        np.testing.assert_allclose(force, ref_force, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(moment, ref_moment, rtol=1e-13, atol=1e-13)
        for k in range(10):  # one parameter at a time: the zero ones are skipped, not mistaken for others
            single = np.zeros(10)
            single[k] = link[k]
            force, moment = (np.array(ca.DM(x)).ravel() for x in wrench(_motion(w, dw, dv), list(single)))
            ref_force, ref_moment = _reference_wrench(w, dw, dv, single)
            np.testing.assert_allclose(np.r_[force, moment], np.r_[ref_force, ref_moment], rtol=1e-13, atol=1e-13)


def test_per_parameter_form_gives_a_smaller_regressor_and_the_same_torques(denso, rng):
    n = denso.n_dof
    q, qd, qdd = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd"))
    chain = joint_chain(build_pinocchio_model(denso, np.zeros((n, N_PARAMETERS_PER_JOINT))), q)
    theta = ca.SX.sym("theta", N_PARAMETERS_PER_JOINT * n)
    links = [[theta[N_PARAMETERS_PER_JOINT * i + j] for j in range(N_PARAMETERS_PER_JOINT)] for i in range(n)]
    gravity = ca.DM([0.0, 0.0, 9.81])
    regressors = {}
    for per_parameter in (False, True):
        tau = newton_euler(chain, links, qd, qdd, gravity, per_parameter=per_parameter)
        regressors[per_parameter] = ca.Function("y", [q, qd, qdd], [ca.densify(ca.jacobian(tau, theta))])
    ops = {key: count_operations(f).n_operations for key, f in regressors.items()}
    assert ops[True] < 0.97 * ops[False]
    for _ in range(5):
        state = [rng.uniform(-3, 3, n) for _ in range(3)]
        per_parameter, matrix = (np.array(regressors[key](*state)) for key in (True, False))
        assert np.abs(per_parameter - matrix).max() <= 1e-12 * np.abs(matrix).max()


def test_unit_parameter_wrench_refuses_the_rotor_and_beyond():
    from psdm_casadi.newton_euler import unit_parameter_wrench

    motion = _motion([0.1, 0.2, 0.3], [1.0, 0.0, 0.0], [0.0, 0.0, 9.81])
    force, moment = unit_parameter_wrench(motion, 0)  # mass: force dv, no moment
    np.testing.assert_allclose(np.array(ca.DM(force)).ravel(), [0.0, 0.0, 9.81])
    assert np.all(np.array(ca.DM(moment)) == 0)
    with pytest.raises(ValueError, match="kind must be 0-9"):
        unit_parameter_wrench(motion, 10)
