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
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from identification.calibration.consistent_fit import link_is_free
from psdm_casadi.description import LinkInertia
from psdm_casadi.oracle import build_kinematic_model

__all__ = ["carried_payload_parameters", "carrying_payloads"]


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


def carrying_payloads(robot, model, entries):
    """``robot`` with the payload findings of ``entries`` carried by its last link the model holds (module
    docstring); ``robot`` itself when there is none, or the robot file gives no links to add them to."""
    payload = carried_payload_parameters(entries)
    free = [i for i in range(robot.n_dof) if link_is_free(model, i)]
    if payload is None or robot.links is None or not free:
        return robot
    carrier = free[-1]
    kinematics, link_placements = build_kinematic_model(robot)
    data = kinematics.createData()
    pin.forwardKinematics(kinematics, data, pin.neutral(kinematics))
    frames = [data.oMi[i + 1] * link_placements[i] for i in range(robot.n_dof)]
    moved = (frames[carrier].inverse() * frames[-1]).act(pin.Inertia.FromDynamicParameters(payload))
    body = pin.Inertia.FromDynamicParameters(robot.links[carrier].dynamic_parameters() + moved.toDynamicParameters())
    links = list(robot.links)
    links[carrier] = LinkInertia(mass=body.mass, com=np.array(body.lever), inertia=np.array(body.inertia))
    return robot.with_links(links)
