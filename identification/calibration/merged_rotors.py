"""Drive inertias inside the base parameters: their place in the standard-to-base map, for the consistent fit.

The PSDM model's base parameters are the rigid body's: its map from the standard parameters has no drive-inertia
columns. Where a joint's drive inertia ``Ia_j qdd_j`` is not a column of its own (``separate_inertia_joints``) it
lies in the span of the base regressor (the first joint's, about a vertical axis, adds to its link's Izz; a joint
parallel to its neighbours adds to a lumped ZZ), and the free fit identifies it inside those base parameters. The
consistent fit splits them into standard parameters: without the drive inertia in the map, the links absorb it and
are pushed up their envelopes (a virtual UR5 on motor currents, rotors 0.4 kg m^2: its link 2 came out 14.3 kg for
8.4). :func:`with_merged_rotors` writes into the map's drive-inertia columns the combination of base parameters
that reproduces ``Ia_j qdd_j`` exactly, so the consistent fit holds each such drive inertia within
``drive_inertia_ratio`` of the robot file's and pulled towards it, and the links keep their own share.

Only motor currents hold the rotors' inertia (a torque measured behind the gearbox does not), and only a robot file
that states a joint's rotor inertia gives the fit something to hold it to: other joints keep the map as derived.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT

logger = logging.getLogger(__name__)

__all__ = ["merged_rotor_map", "with_merged_rotors"]

SPAN_TOLERANCE = 1e-8  # relative residual below which Ia_j qdd_j is taken as inside the base regressor's span


def merged_rotor_map(model, robot, joints, seed: int = 0) -> dict:
    """{joint: base-parameter coefficients (n_base,)} of the drive inertias of ``joints`` (0-based) that lie in the
    span of the base regressor on random states (the others are left out)."""
    rng = np.random.default_rng(seed)
    n_states = 4 * (model.n_base + robot.n_dof)
    q = rng.uniform(robot.q_min, robot.q_max, size=(n_states, robot.n_dof))
    qd, qdd = rng.normal(size=(2, n_states, robot.n_dof))
    stacked = model.regressor(q, qd, qdd).reshape(-1, model.n_base)
    out = {}
    for j in joints:
        target = np.zeros((n_states, robot.n_dof))
        target[:, j] = qdd[:, j]
        target = target.reshape(-1)
        coefficients = np.linalg.lstsq(stacked, target, rcond=None)[0]
        if np.linalg.norm(stacked @ coefficients - target) <= SPAN_TOLERANCE * np.linalg.norm(target):
            coefficients[np.abs(coefficients) < 1e-9 * np.abs(coefficients).max()] = 0.0
            out[int(j)] = coefficients
    return out


def with_merged_rotors(model, robot, options, currents: bool):
    """``model`` with the drive inertias of the base parameters in its map (module docstring); ``model`` itself
    when there are none: no drive inertia asked for (``options.drive_inertia``), torques measured behind the
    gearbox (``currents`` False), or no rotor inertia in the robot file."""
    rotor = np.asarray(robot.rotor_inertia, dtype=float)
    columns = model.parameter_map[:, LINK_PARAMETER_COUNT :: LINK_PARAMETER_COUNT + 1]
    joints = [j for j in range(robot.n_dof) if rotor[j] > 0 and not np.any(columns[:, j])]
    if not (options.drive_inertia and currents and joints):
        return model
    merged = merged_rotor_map(model, robot, joints)
    if not merged:
        return model
    parameter_map = np.array(model.parameter_map, dtype=float)
    for j, coefficients in merged.items():
        parameter_map[:, j * (LINK_PARAMETER_COUNT + 1) + LINK_PARAMETER_COUNT] = coefficients
    logger.info("identify: drive inertias of joints %s inside the base parameters, held near the robot file's "
                "in the consistent fit", ", ".join(str(j + 1) for j in sorted(merged)))  # fmt: skip
    return replace(model, parameter_map=parameter_map)
