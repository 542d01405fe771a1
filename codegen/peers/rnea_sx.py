"""A direct CasADi SX Newton-Euler model built from a Pinocchio model: the peer the PSDM export is benchmarked against.

This is the "obvious alternative" a CasADi user would write: the recursive Newton-Euler
algorithm (rnea) evaluated on SX symbols with the robot's numbers baked in, and forward dynamics
through the mass matrix (one unit-acceleration rnea pass per column, sharing the kinematics) and
a symbolic Cholesky solve. It is tested against ``pinocchio.rnea``/``pinocchio.aba``.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from psdm_casadi.forward import ldl_solve, symmetric_from_columns
from psdm_casadi.kinematics_sx import clean, cross, joint_chain
from psdm_casadi.newton_euler import backward_pass


@dataclass(frozen=True)
class RneaFunctions:
    """SX functions of the direct Newton-Euler peer.

    Attributes
    ----------
    inverse_dynamics : casadi.Function
        ``(q, qd, qdd) -> tau``, each (n_dof,) [rad, rad/s, rad/s^2 -> N m].
    mass_matrix : casadi.Function
        ``q -> M``, (n_dof, n_dof) [kg m^2], armature included.
    forward_dynamics : casadi.Function
        ``(q, qd, tau) -> qdd`` by Cholesky of M.
    n_dof : int
    """

    inverse_dynamics: ca.Function
    mass_matrix: ca.Function
    forward_dynamics: ca.Function
    n_dof: int


def _inertia_apply(mass, com, inertia, w, v):
    """Spatial inertia (mass, COM, inertia about the COM) times the motion (w, v): returns (force, torque about the
    origin)."""
    f = mass * (v - cross(com, w))
    n = ca.mtimes(inertia, w) + cross(com, f)
    return f, n


def _rnea_pass(model, kin, qd, qdd, gravity, with_velocity):
    """One rnea pass on the precomputed kinematics: tau for the given qd, qdd and base acceleration."""
    n = len(kin.parents)
    zero = ca.SX.zeros(3, 1)
    w_list, v_list, dw_list, dv_list = [], [], [], []
    forces, torques = [], []
    for i in range(n):
        parent = kin.parents[i]
        rt = kin.rotations[i].T
        p = kin.translations[i]
        if parent < 0:
            w_p, v_p, dw_p, dv_p = zero, zero, zero, -gravity
        else:
            w_p, v_p, dw_p, dv_p = w_list[parent], v_list[parent], dw_list[parent], dv_list[parent]
        axis = kin.axes[i]
        revolute = kin.revolute[i]
        # motion transported into the child frame: w' = R^T w, v' = R^T (v + w x p)
        w_in = ca.mtimes(rt, w_p)
        v_in = ca.mtimes(rt, v_p + cross(w_p, p))
        dw_in = ca.mtimes(rt, dw_p)
        dv_in = ca.mtimes(rt, dv_p + cross(dw_p, p))
        s_w, s_v = (axis, zero) if revolute else (zero, axis)
        if with_velocity:
            w = w_in + s_w * qd[i]
            v = v_in + s_v * qd[i]
            # a = a_in + S qdd + v x (S qd)
            dw = dw_in + s_w * qdd[i] + cross(w, s_w) * qd[i]
            dv = dv_in + s_v * qdd[i] + (cross(w, s_v) + cross(v, s_w)) * qd[i]
        else:
            w, v = zero, zero
            dw = dw_in + s_w * qdd[i]
            dv = dv_in + s_v * qdd[i]
        w_list.append(w)
        v_list.append(v)
        dw_list.append(dw)
        dv_list.append(dv)
        inertia = model.inertias[i + 1]
        mass = float(inertia.mass)
        com = ca.SX(ca.DM(clean(inertia.lever)))
        rot_inertia = ca.SX(ca.DM(clean(inertia.inertia)))  # about the centre of mass
        f, t = _inertia_apply(mass, com, rot_inertia, dw, dv)
        if with_velocity:
            hf, ht = _inertia_apply(mass, com, rot_inertia, w, v)
            f = f + cross(w, hf)
            t = t + cross(w, ht) + cross(v, hf)
        forces.append(f)
        torques.append(t)
    return backward_pass(kin, list(zip(forces, torques)), qdd, [float(a) for a in clean(model.armature)])


# The peer solves D qdd = tau - h with the same square-root-free LDL^T as the PSDM model, so the two
# forward dynamics differ only in how D and h are computed.
cholesky_solve_sx = ldl_solve


def build_rnea_functions(model, *, cse=True) -> RneaFunctions:
    """Build SX inverse dynamics, mass matrix and forward dynamics of a Pinocchio model by rnea.

    Parameters
    ----------
    model : pinocchio.Model
        Serial or branched model of 1-DOF revolute/prismatic joints (axis-aligned or unaligned);
        its inertias, armature and gravity are baked in as constants.
    cse : bool
        Ask CasADi to eliminate common subexpressions in each Function.

    Returns
    -------
    RneaFunctions

    Raises
    ------
    ParameterError
        When a joint is not a 1-DOF revolute or prismatic joint.

    Examples
    --------
    >>> peer = build_rnea_functions(oracle.model)        # doctest: +SKIP
    >>> peer.inverse_dynamics(q, qd, qdd)                # doctest: +SKIP
    """
    n = model.nv
    q, qd, qdd, tau = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd", "tau"))
    kin = joint_chain(model, q, caller="build_rnea_functions")
    gravity = ca.SX(ca.DM(clean(model.gravity.linear)))
    opts = {"cse": bool(cse)}
    tau_id = _rnea_pass(model, kin, qd, qdd, gravity, with_velocity=True)
    zero = ca.SX.zeros(n, 1)
    unit = np.eye(n)
    columns = [
        _rnea_pass(model, kin, zero, ca.SX(ca.DM(unit[:, j])), ca.SX.zeros(3, 1), with_velocity=False) for j in range(n)
    ]
    mass_sym = symmetric_from_columns(columns)  # M is symmetric: the lower triangle of the columns once
    bias = _rnea_pass(model, kin, qd, zero, gravity, with_velocity=True)
    qdd_fd = cholesky_solve_sx(mass_sym, tau - bias)
    return RneaFunctions(
        inverse_dynamics=ca.Function("inverse_dynamics", [q, qd, qdd], [tau_id], ["q", "qd", "qdd"], ["tau"], opts),
        mass_matrix=ca.Function("mass_matrix", [q], [mass_sym], ["q"], ["M"], opts),
        forward_dynamics=ca.Function("forward_dynamics", [q, qd, tau], [qdd_fd], ["q", "qd", "tau"], ["qdd"], opts),
        n_dof=n,
    )
