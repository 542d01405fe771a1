"""Links a model file holds at the robot file's inertia stay held when the diagnosis identifies the rigid body.

``DiagnosisOptions.held_links`` (from ``model_file.model_file_options``: identify's ``worse_joint_hold``,
``calibration.model_file_holds``) -> the rigid-body columns of every recalibration of the diagnosis
(``rigid_body_choice.recalibration_parts``, ``diagnose`` with ``rigid_body="identified"``, the enveloped recalibration
of ``envelope_check``) -> the base parameters it reports.

Identify held those links because, fitted, they made joints worse than the robot file on the held-out recordings; a
diagnosis that frees them again fits them to what the other joints ask of them (and to an effect they may absorb), as
identify's fit did before the hold. The base parameters are ``theta = P s`` (``PSDMModel.parameter_map``, ``s`` the
standard parameters, 11 per link); with the ten inertial parameters of the held links at the robot file's values (a
link the file states semi-definite lifted by the fit's consistency margin, as identify holds it:
``consistent_fit.held_standard``), and the drive inertia of each joint whose every carried link is held (as identify
holds them: ``consistent_fit.held_rotors``), ``theta = B c + theta_held``: ``B`` an orthonormal basis of what the free
standard parameters reach, ``theta_held`` the held links' share. The fit's rigid-body columns are the regressor
times ``B``, its torque is the measured less the regressor times ``theta_held``, and ``theta`` of the coefficients
gives the base parameters back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.consistent_fit import held_rotors, held_standard

__all__ = ["HeldLinks", "held_links"]

LINK_SIZE = 11  # standard parameters per link in ``parameter_map`` (the ten inertial ones, then the drive inertia)
RANK_TOLERANCE = 1e-9  # singular values of the free map below this fraction of the largest are no direction


@dataclass(frozen=True, eq=False)
class HeldLinks:
    """The rigid body with ``links`` (0-based) held: ``basis`` (n_base, r) and ``theta_held`` (n_base,)."""

    links: tuple
    basis: np.ndarray
    theta_held: np.ndarray

    def columns(self, regressor) -> np.ndarray:
        """The rigid-body columns (n_samples, n_dof, r) of a PSDM ``regressor`` (n_samples, n_dof, n_base)."""
        return np.asarray(regressor, dtype=float) @ self.basis

    def torque(self, regressor) -> np.ndarray:
        """The held links' torque (n_samples, n_dof)."""
        return np.asarray(regressor, dtype=float) @ self.theta_held

    def theta(self, coefficients) -> np.ndarray:
        """The base parameters (n_base,) of the fit's rigid-body ``coefficients`` (r,)."""
        return self.basis @ np.asarray(coefficients, dtype=float) + self.theta_held


def held_links(model, robot, links) -> HeldLinks | None:
    """The ``HeldLinks`` of ``links`` (0-based) at ``robot``'s link inertias, or None (no link held, or a robot file
    without link inertias: nothing to hold them at)."""
    links = tuple(sorted({int(i) for i in links if 0 <= int(i) < robot.n_dof}))
    if not links or robot.links is None:
        return None
    mapping = np.asarray(model.parameter_map, dtype=float)
    standard = np.zeros(mapping.shape[1])
    prior = held_standard(robot, links, model=model)  # as identify holds them: a semi-definite link free in it lifted
    held = np.zeros(mapping.shape[1], dtype=bool)
    for i in links:
        held[i * LINK_SIZE : i * LINK_SIZE + 10] = True
        standard[i * LINK_SIZE : i * LINK_SIZE + 10] = prior[i, :10]
    for i in held_rotors(robot, links):  # with every link it carries, as identify holds it
        held[i * LINK_SIZE + 10], standard[i * LINK_SIZE + 10] = True, prior[i, 10]
    u, singular, _ = np.linalg.svd(mapping[:, ~held], full_matrices=False)
    rank = int(np.sum(singular > RANK_TOLERANCE * max(float(singular[0]), 1e-300))) if singular.size else 0
    return HeldLinks(links=links, basis=u[:, :rank], theta_held=mapping[:, held] @ standard[held])
