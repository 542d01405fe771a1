"""Newton-Euler recursion on SX, linear in the standard inertial parameters: how the recursive form evaluates
Y(q, qd, qdd) theta.

The link parameters are the Pinocchio dynamic parameters of each joint frame (m, m r, inertia about
the frame origin) plus the rotor inertia, so a link with zero mass but a first moment is fine and
every torque is linear in them. The forward pass carries the angular velocity w, angular
acceleration dw and the linear acceleration of each frame origin; the matrix U = [dw]x + [w]x[w]x
of each frame is built once and used both for the next frame's acceleration and for the link's
force (Khalil and Kleinfinger's customised Newton-Euler). With numeric parameters CasADi folds
every zero, so only the parameters a base-parameter preimage keeps cost anything.

The link wrench has two equal forms: the matrix form (``link_wrench``: m dv + U m r and
I dw + m r x dv + w x I w, fewest operations for numeric parameters) and the per-parameter form
(``link_wrench_per_parameter``: the sum of each parameter times the wrench of that parameter alone,
computed once per link). The regressor is the Jacobian in the parameters; in the per-parameter
form each of its entries is one short dot product with a vector shared by every joint below the
link, which is why the regressor is built from that form rather than by differentiating the matrix
form.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from psdm_casadi.kinematics_sx import JointChain, cross

# Index of each quantity in a joint's 11 standard parameters.
MASS, FIRST_MOMENT, INERTIA, ROTOR_INERTIA = 0, slice(1, 4), slice(4, 10), 10
_ZERO3 = ca.SX.zeros(3, 1)


@dataclass(frozen=True)
class LinkMotion:
    """Motion of one joint frame, in its own coordinates: w, dw, the origin's acceleration dv, and U."""

    w: ca.SX
    dw: ca.SX
    dv: ca.SX
    u: ca.SX


def _u_matrix(w, dw):
    """U = [dw]x + [w]x[w]x as a 3x3 SX, sharing the products of w."""
    wxx, wyy, wzz = w[0] * w[0], w[1] * w[1], w[2] * w[2]
    wxy, wxz, wyz = w[0] * w[1], w[0] * w[2], w[1] * w[2]
    return ca.vertcat(
        ca.horzcat(-(wyy + wzz), wxy - dw[2], wxz + dw[1]),
        ca.horzcat(wxy + dw[2], -(wxx + wzz), wyz - dw[0]),
        ca.horzcat(wxz - dw[1], wyz + dw[0], -(wxx + wyy)),
    )


def _inertia_matrix(values):
    """The symmetric inertia about the frame origin from (Ixx, Ixy, Iyy, Ixz, Iyz, Izz)."""
    xx, xy, yy, xz, yz, zz = values
    return ca.vertcat(ca.horzcat(xx, xy, xz), ca.horzcat(xy, yy, yz), ca.horzcat(xz, yz, zz))


def forward_pass(chain: JointChain, qd, qdd, base_acceleration, with_velocity: bool = True) -> list:
    """LinkMotion of every joint frame, base to tip.

    Parameters
    ----------
    chain : JointChain
    qd, qdd : casadi.SX, shape (n_dof, 1)
    base_acceleration : casadi.SX or DM, shape (3, 1)
        Linear acceleration of the base frame; ``-gravity`` puts gravity in.
    with_velocity : bool
        False treats qd as zero (mass-matrix columns, gravity): the velocity terms are skipped.
    """
    motions = []
    for i in range(chain.n_dof):
        parent, axis, p = chain.parents[i], chain.axes[i], chain.translations[i]
        rt = chain.rotations[i].T
        if parent < 0:
            w_in, dw_in = _ZERO3, _ZERO3
            dv_in = ca.mtimes(rt, ca.SX(base_acceleration))
        else:
            up = motions[parent]
            w_in, dw_in = ca.mtimes(rt, up.w), ca.mtimes(rt, up.dw)
            dv_in = ca.mtimes(rt, up.dv + ca.mtimes(up.u, p))
        if chain.revolute[i]:
            w = w_in + axis * qd[i] if with_velocity else _ZERO3
            dw = dw_in + axis * qdd[i]
            if with_velocity:
                dw = dw + cross(w_in, axis) * qd[i]
            dv = dv_in
        else:
            w, dw = (w_in if with_velocity else _ZERO3), dw_in
            dv = dv_in + axis * qdd[i]
            if with_velocity:
                dv = dv + 2 * cross(w_in, axis) * qd[i]
        motions.append(LinkMotion(w, dw, dv, _u_matrix(w, dw)))
    return motions


def link_wrench(motion: LinkMotion, link) -> tuple:
    """(force, moment about the frame origin) of one link with parameters ``link[:10]`` (numbers or SX)."""
    first_moment = ca.vertcat(*link[FIRST_MOMENT])
    inertia = _inertia_matrix(link[INERTIA])
    force = link[MASS] * motion.dv + ca.mtimes(motion.u, first_moment)
    moment = (
        ca.mtimes(inertia, motion.dw) + cross(first_moment, motion.dv) + cross(motion.w, ca.mtimes(inertia, motion.w))
    )
    return force, moment


def _unit_inertia_moment(motion: LinkMotion, index: int):
    """The moment B dw + w x (B w) of the unit inertia parameter ``index`` (0-5, Ixx ... Izz); CasADi folds B's
    zeros."""
    unit = _inertia_matrix([1.0 if k == index else 0.0 for k in range(6)])
    return ca.mtimes(unit, motion.dw) + cross(motion.w, ca.mtimes(unit, motion.w))


def unit_parameter_wrench(motion: LinkMotion, kind: int) -> tuple:
    """(force, moment) of a link whose standard parameter ``kind`` (0-9: m, m r, inertia) is 1 and the others 0."""
    if kind == MASS:
        return motion.dv, _ZERO3
    if kind < INERTIA.start:
        axis = kind - FIRST_MOMENT.start
        return motion.u[:, axis], cross(ca.SX(ca.DM.eye(3)[:, axis]), motion.dv)
    if kind < INERTIA.stop:
        return _ZERO3, _unit_inertia_moment(motion, kind - INERTIA.start)
    raise ValueError(f"unit_parameter_wrench kind must be 0-9 (m, m r, inertia); got {kind}")


def link_wrench_per_parameter(motion: LinkMotion, link) -> tuple:
    """``link_wrench`` written as the sum over the nonzero parameters of parameter times unit-parameter wrench."""
    force, moment = _ZERO3, _ZERO3
    for kind, value in enumerate(link[: INERTIA.stop]):
        if not ca.SX(value).is_zero():
            unit_force, unit_moment = unit_parameter_wrench(motion, kind)
            force, moment = force + value * unit_force, moment + value * unit_moment
    return force, moment


def backward_pass(chain: JointChain, wrenches: list, qdd, rotor_inertia) -> ca.SX:
    """Joint torques from the link wrenches (tip to base), plus rotor inertia times qdd."""
    forces, moments = [w[0] for w in wrenches], [w[1] for w in wrenches]
    tau = [None] * chain.n_dof
    for i in reversed(range(chain.n_dof)):
        axis = chain.axes[i]
        tau[i] = ca.dot(axis, moments[i] if chain.revolute[i] else forces[i]) + rotor_inertia[i] * qdd[i]
        parent = chain.parents[i]
        if parent >= 0:
            rot, p = chain.rotations[i], chain.translations[i]
            force_in_parent = ca.mtimes(rot, forces[i])
            forces[parent] = forces[parent] + force_in_parent
            moments[parent] = moments[parent] + ca.mtimes(rot, moments[i]) + cross(p, force_in_parent)
    return ca.vertcat(*tau)


def newton_euler(
    chain: JointChain, parameters, qd, qdd, base_acceleration, with_velocity: bool = True, per_parameter: bool = False
) -> ca.SX:
    """Joint torques of a chain by Newton-Euler, linear in the standard parameters.

    Parameters
    ----------
    chain : JointChain
        Joint placements as SX of q.
    parameters : sequence of sequences
        Per joint 11 entries (numbers or SX): m, m r (3), I about the joint-frame origin
        (Ixx, Ixy, Iyy, Ixz, Iyz, Izz), rotor inertia.
    qd, qdd : casadi.SX, shape (n_dof, 1)
    base_acceleration : casadi.SX or DM, shape (3, 1)
    with_velocity : bool
        False treats qd as zero: the velocity terms are skipped.
    per_parameter : bool
        Use the per-parameter link wrench (``link_wrench_per_parameter``): for symbolic parameters whose
        Jacobian is wanted (the regressor).

    Returns
    -------
    casadi.SX, shape (n_dof, 1)
    """
    motions = forward_pass(chain, qd, qdd, base_acceleration, with_velocity)
    wrench = link_wrench_per_parameter if per_parameter else link_wrench
    wrenches = [wrench(motion, link) for motion, link in zip(motions, parameters)]
    return backward_pass(chain, wrenches, qdd, [link[ROTOR_INERTIA] for link in parameters])
