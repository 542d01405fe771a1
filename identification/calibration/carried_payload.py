"""The robot file's links with a found payload at the flange: the prior a recalibration holds the rigid body to.

``recalibrate`` takes a payload finding (kind ``rigid_body``) up in the re-identified rigid body. The consistent fit
starts from the robot file's links, pulls towards them (``prior_pull``) and keeps each inside its physical envelope
(``envelope``: its mass within 0.5-2 x the file's, its bounding ellipsoid). A 2 kg payload at the flange of a 0.8 kg
wrist link is outside both, so the fit could take up only part of it and the other findings' columns took the rest
(a Coulomb asymmetry of joint 5 fitted 0.24 N m where the virtual robot holds 1.2). The finding says the flange
carries the load, so the fit starts from, is pulled to and is bounded around the robot file with the load added
(:func:`carrying_payloads`): as a point mass at its centre of mass in the last link frame, on the last link whose
inertia the model holds (a robot file's ``massless_links`` end the chain before the flange), moved there through the
joints between at q = 0 (exact for a load on their axes, as on the Denso's massless flange link).

The diagnosis's payload term folds its load into the base parameters the same way (:func:`flange_parameter_map`):
through the last link's block of the parameter map, which is zero on such a robot (the Denso's augmented model lost
its payload).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from identification.calibration.consistent_fit import link_is_free
from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT
from psdm_casadi.description import LinkInertia
from psdm_casadi.oracle import build_kinematic_model

__all__ = ["carried_payload_parameters", "carrying_payloads", "flange_carrier", "flange_parameter_map"]


def carried_payload_parameters(entries) -> np.ndarray | None:
    """The ten dynamic parameters (m, m r, I about the origin; last link frame) of the payload findings among the
    calibrated-model ``entries`` (point masses at their centres of mass), or None when they hold none."""
    total = np.zeros(10)
    for entry in entries:
        if entry.get("kind") != "rigid_body" or entry.get("effect") != "payload":
            continue
        stated = entry.get("parameters") or entry.get("diagnosis", {}).get("parameters", {})
        mass = float(stated.get("mass", 0.0))
        if mass > 0.0:
            com = np.array([float(stated.get(f"com_{axis}", 0.0)) for axis in "xyz"])
            total += pin.Inertia(mass, com, np.zeros((3, 3))).toDynamicParameters()
    return total if total[0] > 0.0 else None


def flange_carrier(robot, model) -> tuple | None:
    """(the last link the model holds, the placement of the last link frame in its frame at q = 0: ``pin.SE3``), or
    None when the model holds no link (module docstring)."""
    free = [i for i in range(robot.n_dof) if link_is_free(model, i)]
    if not free:
        return None
    kinematics, link_placements = build_kinematic_model(robot)
    data = kinematics.createData()
    pin.forwardKinematics(kinematics, data, pin.neutral(kinematics))
    frames = [data.oMi[i + 1] * link_placements[i] for i in range(robot.n_dof)]
    return free[-1], frames[free[-1]].inverse() * frames[-1]


def flange_parameter_map(robot, model) -> np.ndarray:
    """``model.parameter_map`` with the last link's 10 inertial columns those of a body at the flange carried by the
    last link the model holds (module docstring): the base parameters' change per unit of each of its dynamic
    parameters (m, m r, inertia about the flange origin; Pinocchio's order). The map itself where the last link is
    held (the placement is then the identity) or none is."""
    parameter_map = np.array(model.parameter_map, dtype=float)
    found = flange_carrier(robot, model)
    if found is None or found[0] == robot.n_dof - 1:
        return parameter_map
    carrier, placement = found
    start = np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0])  # a unit body: the action is linear
    moved = placement.act(pin.Inertia.FromDynamicParameters(start)).toDynamicParameters()
    carried = np.column_stack([placement.act(pin.Inertia.FromDynamicParameters(start + unit)).toDynamicParameters()
                               - moved for unit in np.eye(10)])  # fmt: skip
    stride, last = LINK_PARAMETER_COUNT + 1, robot.n_dof - 1
    block = parameter_map[:, carrier * stride : carrier * stride + LINK_PARAMETER_COUNT]
    parameter_map[:, last * stride : last * stride + LINK_PARAMETER_COUNT] = block @ carried
    return parameter_map


def carrying_payloads(robot, model, entries):
    """``robot`` with the payload findings of ``entries`` carried by its last link the model holds (module
    docstring); ``robot`` itself when there is none, or the robot file gives no links to add them to."""
    payload = carried_payload_parameters(entries)
    found = None if payload is None or robot.links is None else flange_carrier(robot, model)
    if found is None:
        return robot
    carrier, placement = found
    moved = placement.act(pin.Inertia.FromDynamicParameters(payload))
    body = pin.Inertia.FromDynamicParameters(robot.links[carrier].dynamic_parameters() + moved.toDynamicParameters())
    links = list(robot.links)
    links[carrier] = LinkInertia(mass=body.mass, com=np.array(body.lever), inertia=np.array(body.inertia))
    return robot.with_links(links)
