"""build_recursive_functions(): the PSDM model's CasADi functions evaluated by a Newton-Euler recursion (the fast form).

Same outputs as ``build_functions`` (the pseudo-symbolic sum of the paper) and equal to it to
rounding, for every theta_b: torques are Y(q, qd, qdd) theta_b computed as the Newton-Euler
recursion on the sparse standard-parameter preimage ``T theta_b`` (``psdm_casadi.preimage``). The
reduction to base parameters shows up as the standard parameters the preimage sets to zero, which
CasADi folds away; the kinematics are shared by every function. The regressor is the exact
Jacobian of that linear map. This form needs the robot's kinematics, not only E and P, and is the
one to export when speed matters (see ``benchmarks/dynamics_speed.py``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import casadi as ca
import numpy as np

from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import ParameterError
from psdm_casadi.kinematics_sx import JointChain, joint_chain
from psdm_casadi.model import PSDMModel
from psdm_casadi.newton_euler import ROTOR_INERTIA, forward_pass, newton_euler, unit_parameter_wrench
from psdm_casadi.oracle import N_PARAMETERS_PER_JOINT, build_pinocchio_model
from psdm_casadi.preimage import StandardPreimage, model_preimage, standard_preimage
from psdm_casadi.symbolic import DynamicsFunctions, assemble_functions, baked_theta


@dataclass(frozen=True)
class RegressorStructure:
    """The regressor of the recursive form as its pieces, for code generators that vectorise it.

    Column c of Y is ``sum_r preimage[r, c] y_r``. For a link parameter r (kind ``r % 11`` below 10) of
    joint frame j = ``r // 11``, ``y_r[i] = a_ij . moment_r + b_ij . force_r`` for the ancestors i of j
    (j included) and 0 elsewhere, where (a_ij, b_ij) is joint i's unit motion (angular, linear) expressed
    at frame j and (force_r, moment_r) is ``unit_wrenches[r]``. For a rotor inertia r, ``y_r = qdd[j] e_j``.

    Attributes
    ----------
    inputs : tuple of casadi.SX
        The symbols (q, qd, qdd) every SX here depends on.
    chain : JointChain
    unit_wrenches : dict
        Row r of the preimage (link parameters only) -> (force, moment), SX (3, 1) each.
    preimage : numpy.ndarray, shape (11 n_dof, n_base)
    """

    inputs: tuple
    chain: JointChain
    unit_wrenches: dict
    preimage: np.ndarray


def _regressor_structure(chain, inputs, preimage: StandardPreimage, base_acceleration) -> RegressorStructure:
    motions = forward_pass(chain, inputs[1], inputs[2], base_acceleration)
    wrenches = {}
    for row in preimage.support:
        joint, kind = divmod(row, N_PARAMETERS_PER_JOINT)
        if kind != ROTOR_INERTIA:
            wrenches[row] = unit_parameter_wrench(motions[joint], kind)
    return RegressorStructure(inputs=tuple(inputs), chain=chain, unit_wrenches=wrenches, preimage=preimage.matrix)


def _linear_parameters(preimage: StandardPreimage, theta) -> list:
    """Per joint 11 SX entries of T theta, summed over the nonzeros of T only."""
    values = []
    for row in range(preimage.matrix.shape[0]):
        entry = ca.SX(0)
        for k in np.flatnonzero(preimage.matrix[row]):
            entry = entry + float(preimage.matrix[row, k]) * theta[int(k)]
        values.append(entry)
    return [values[N_PARAMETERS_PER_JOINT * i : N_PARAMETERS_PER_JOINT * (i + 1)] for i in range(preimage.n_dof)]


def build_recursive_functions(
    model: PSDMModel, robot: RobotDescription | None, theta=None, *, preimage: StandardPreimage | None = None
) -> DynamicsFunctions:
    """Build the CasADi functions of a PSDM model by Newton-Euler on its standard-parameter preimage.

    Parameters
    ----------
    model : PSDMModel
    robot : RobotDescription or None
        The robot the model was derived from; None for a model derived without monomial table, which
        carries its own joint tree (``model.chain``).
    theta : array, shape (n_base,), optional
        Numeric base parameters to compile in; the functions then have no ``theta`` input.
    preimage : StandardPreimage, optional
        Reuse one computed by ``standard_preimage(model, robot)``.

    Returns
    -------
    DynamicsFunctions
        Same names, inputs and outputs as ``build_functions(model, theta)``.

    Raises
    ------
    DerivationError
        When the model was not derived from this robot.
    ShapeError
        When theta does not have n_base entries.
    ParameterError
        When robot is None and the model has a monomial table (its kinematics are the robot's).
    """
    n, l = model.n_dof, model.n_base
    if robot is None:
        if model.chain is None:
            raise ParameterError(
                f"build_recursive_functions needs the robot of model {model.robot_name!r} (derived with a monomial "
                "table, it does not carry its kinematics); got robot=None. Pass the robot it was derived from."
            )
        preimage = preimage or model_preimage(model)
        kinematics, gravity = model.chain.pinocchio_model(), model.chain.gravity
    else:
        preimage = preimage or standard_preimage(model, robot)
        kinematics = build_pinocchio_model(robot, np.zeros((n, N_PARAMETERS_PER_JOINT)))  # placements only
        gravity = robot.gravity
    q, qd, qdd, tau_in = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd", "tau"))
    theta_sym = ca.SX.sym("theta", l)
    chain = joint_chain(kinematics, q, caller="build_recursive_functions")
    base_acceleration = ca.DM(-np.asarray(gravity, dtype=float))
    no_gravity = ca.DM.zeros(3, 1)
    zero = ca.SX.zeros(n, 1)

    # The regressor is the Jacobian of the (linear) torques in theta; dense, like build_functions' one.
    symbolic_parameters = _linear_parameters(preimage, theta_sym)
    tau_symbolic = newton_euler(chain, symbolic_parameters, qd, qdd, base_acceleration, per_parameter=True)
    gravity_symbolic = newton_euler(
        chain, symbolic_parameters, zero, zero, base_acceleration, with_velocity=False, per_parameter=True
    )
    regressor = ca.densify(ca.jacobian(tau_symbolic, theta_sym))
    gravity_regressor = ca.densify(ca.jacobian(gravity_symbolic, theta_sym))

    if theta is None:
        parameters, theta_inputs, theta_names, baked = symbolic_parameters, [theta_sym], ["theta"], None
    else:
        baked = baked_theta(theta, l)
        parameters = [[float(v) for v in row] for row in preimage.standard_parameters(baked)]
        theta_inputs, theta_names = [], []

    tau = newton_euler(chain, parameters, qd, qdd, base_acceleration)
    gravity = newton_euler(chain, parameters, zero, zero, base_acceleration, with_velocity=False)
    bias = newton_euler(chain, parameters, qd, zero, base_acceleration)
    columns = [
        newton_euler(chain, parameters, zero, ca.SX(ca.DM(np.eye(n)[k])), no_gravity, with_velocity=False)
        for k in range(n)
    ]
    functions = assemble_functions(
        (q, qd, qdd, tau_in),
        theta_inputs,
        theta_names,
        regressor=regressor,
        gravity_regressor=gravity_regressor,
        tau=tau,
        bias=bias,
        gravity=gravity,
        mass_columns=columns,
        theta=baked,
    )
    structure = _regressor_structure(chain, (q, qd, qdd), preimage, base_acceleration)
    return dataclasses.replace(functions, regressor_structure=structure)
