"""Drive losses of a torque measured as motor current: a gearbox whose efficiency depends on the power flow.

A torque computed from motor currents (``kt * i``) is what the motor gives, not what reaches the link. A gearbox
loses a share of the power it passes on: when the motor drives the load (power flows to the link, ``qd * tau > 0``)
it must give ``tau / eta``; when the load drives the motor (a link lowered under gravity, a braked motion) it gives
``eta * tau``. The current-based torque of a joint is then steeper than the link torque when driving and flatter when
back-driven (the Kinova Gen3's currents against its joint-torque sensors: slope 1.04-1.19 driving, 0.92-0.99
back-driven). A rigid body fitted to such a signal cannot follow it and pushes links to their bounds.

With ``tau_b`` the model's own torque (rigid body, friction and drive inertia, the part of the torque the current
carries), the signal is ``tau_b (1 + mu s)`` with ``s = sign(qd tau_b)``::

    kt i = tau_b + mu |tau_b| tanh(qd / v),      mu = (1 - eta^2) / (1 + eta^2),   eta = sqrt((1 - mu) / (1 + mu))

(driving over back-driven: ``(1 + mu) / (1 - mu) = 1 / eta^2``; the mean of the two factors is absorbed by the rigid
body's scale). It is the calibrated model's load-dependent friction (``findings.term_values``: the column
``|tau_b| tanh(qd / v)`` of the model's own torque, never the measurement), linear in ``mu`` once ``tau_b`` is
fixed. So identify stores a chosen drive loss as a ``load_dependent_friction`` entry of the file's ``findings``
(``source`` ``"identify"``), which ``CalibratedModel.predict``, ``psdm validate``, ``psdm diagnose MODEL`` and the
exported code (``codegen.calibrated``: ``inverse_dynamics`` gives the motor-side torque ``kt i``, and
``forward_dynamics`` inverts the factor exactly) all apply. The URDF and MJCF exports cannot hold it and name it in
their warning (``codegen.target_holds``).

Whether a joint has it is decided from the data (``column_choice``: information criterion and held-out error, the
coefficient inside ``(0, MAX_LOAD_FRICTION)``), only when currents are the torque source: a joint-torque sensor sits
behind the gearbox and sees none of it. The fit (:func:`identify_with_drive_loss`) takes ``tau_b`` from the robot
file's rigid body first, then from its own result (two passes, as ``recalibrate`` does for a diagnosed load-dependent
friction).
"""

from __future__ import annotations

import copy

import numpy as np

from identification.calibration.coulomb_width import joint_width
from identification.calibration.findings import FindingColumns, FindingTerm, filled_entries
from identification.calibration.lugre_recordings import split_findings
from identification.calibration.trajectory_fit import identify_trajectories, predict_torque

__all__ = ["DRIVE_LOSS_SOURCE", "PASSES", "coefficient", "drive_loss_entries", "drive_loss_summary", "efficiency",
           "identify_with_drive_loss", "loss_columns", "prior_theta", "with_drive_loss"]  # fmt: skip

#: ``findings[].source`` of a drive loss chosen by identify (a diagnosis' findings have none).
DRIVE_LOSS_SOURCE = "identify"
#: What a drive-loss entry of the findings is.
CAUSE = ("drive loss: a gearbox efficiency that depends on the power flow (the current torque is the link's / eta "
         "when the motor drives, x eta when it is back-driven)")  # fmt: skip
#: Fits with the reference torque: the robot file's rigid body, then the fit's own.
PASSES = 2


def efficiency(mu):
    """The gear efficiency ``eta = sqrt((1 - mu) / (1 + mu))`` of a load-dependent coefficient ``mu`` (module
    docstring); nan outside ``[0, 1)``."""
    mu = np.asarray(mu, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where((mu >= 0) & (mu < 1), np.sqrt((1 - mu) / (1 + mu)), np.nan)


def coefficient(eta):
    """The load-dependent coefficient ``mu = (1 - eta^2) / (1 + eta^2)`` of a gear efficiency ``eta``."""
    eta = np.asarray(eta, dtype=float)
    return (1 - eta**2) / (1 + eta**2)


def prior_theta(robot, model) -> np.ndarray | None:
    """The robot file's base parameters (its links and rotor inertias), or None when it has no links."""
    if robot.links is None:
        return None
    return model.base_parameters(robot.nominal_dynamic_parameters())


def loss_columns(rigid, qd, theta, joints, coulomb_velocity) -> np.ndarray:
    """The drive-loss columns ``|Y theta|_j tanh(qd_j / v)`` of ``joints`` (0-based), (n_samples, n_dof, len(joints)):
    ``rigid`` is the base regressor (n_samples, n_dof, n_base) of the samples, ``theta`` the reference rigid body."""
    torque = np.abs(np.asarray(rigid) @ np.asarray(theta, dtype=float))
    out = np.zeros((*torque.shape, len(joints)))
    for k, j in enumerate(joints):
        out[:, j, k] = torque[:, j] * np.tanh(qd[:, j] / joint_width(coulomb_velocity, j))
    return out


def _terms(joints, coulomb_velocity) -> tuple:
    return tuple(FindingTerm("load_dependent_friction", int(j), velocity=joint_width(coulomb_velocity, j))
                 for j in joints)  # fmt: skip


def _prior_reference(model, theta):
    def torque(q, qd, qdd):
        return model.inverse_dynamics(q, qd, qdd, theta)

    return torque


def _own_reference(model, fit):
    def torque(q, qd, qdd):
        return predict_torque(model, fit, q, qd, qdd)

    return torque


def identify_with_drive_loss(robot, model, recordings, options, joints, configurations=None) -> tuple:
    """(fit without the loss columns, FindingColumns, (values, ols, std) of the coefficients) of the recordings-route
    fit with a drive loss on ``joints`` (0-based; module docstring): ``PASSES`` fits, the reference torque of each
    the previous one's (the robot file's rigid body first; without links, the fit without the loss)."""
    terms = _terms(joints, options.coulomb_velocity)
    theta = prior_theta(robot, model)
    if theta is None:
        plain = identify_trajectories(robot, model, recordings, options, configurations=configurations)
        reference = _own_reference(model, plain)
    else:
        reference = _prior_reference(model, theta)
    for _ in range(PASSES):
        columns = FindingColumns(terms, reference)
        fit = identify_trajectories(robot, model, recordings, options, columns, configurations)
        plain, extra = split_findings(fit, len(columns.names))
        reference = _own_reference(model, plain)
    return plain, columns, extra


def drive_loss_entries(columns: FindingColumns, extra) -> list:
    """The ``findings`` entries of a fitted drive loss: one ``load_dependent_friction`` per joint, with its
    coefficient ``mu`` and the gear efficiency ``eta`` (``parameters.efficiency``)."""
    entries = []
    for term in columns.terms:
        entries.append({"effect": term.effect, "label": term.label, "kind": "torque", "joints": [term.joint + 1],
                        "source": DRIVE_LOSS_SOURCE, "term": term.to_dict(),
                        "cause": CAUSE})  # fmt: skip
    out = filled_entries(entries, list(columns.terms), columns, extra)
    for entry in out:
        mu = entry["parameters"]["coefficient"]
        entry["parameters"] = {**entry["parameters"], "efficiency": float(efficiency(mu))}
        entry["applied"] = ("part of the model's torque (the motor-side torque kt i: tau_b + mu |tau_b| "
                            "tanh(qd / v)); exported code holds it, URDF/MJCF do not")  # fmt: skip
    return out


def drive_loss_summary(document: dict) -> list:
    """Per joint with a drive loss chosen by identify: ``{"joint", "mu", "mu_std", "efficiency", "efficiency_range"}``
    (joint 1-based; the range is the efficiency at ``mu -+ 2 std``) from a calibrated-model document."""
    out = []
    for entry in document.get("findings") or []:
        if entry.get("source") != DRIVE_LOSS_SOURCE or entry.get("effect") != "load_dependent_friction":
            continue
        mu, std = float(entry["coefficients"][0] or 0.0), float(entry["std"][0] or 0.0)
        low, high = efficiency(min(mu + 2 * std, 0.999)), efficiency(max(mu - 2 * std, 0.0))
        out.append({"joint": entry["joints"][0], "mu": mu, "mu_std": std, "efficiency": float(efficiency(mu)),
                    "efficiency_range": [float(low), float(high)]})  # fmt: skip
    return out


def with_drive_loss(document: dict, columns: FindingColumns, extra) -> dict:
    """``document`` (a calibrated-model document) with the drive-loss entries among its findings."""
    out = copy.deepcopy(document)
    out["findings"] = [*(out.get("findings") or []), *drive_loss_entries(columns, extra)]
    return out
