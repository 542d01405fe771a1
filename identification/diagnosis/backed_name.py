"""Naming a torque by the family whose claim the recording supports: a spring before a ripple over a short travel.

A torque ripple is periodic in the joint angle; over a recorded travel that covers less than one of its periods
(``CandidateTerm.name_unsupported``) a low-harmonic ripple is a smooth function of the angle, as a spring's polynomial,
a counterbalance's odd law or a gas spring's lever law is, and the two families compete for the same torque. The
selection (``selection._choose``) then names the family that claims no more than the data show (``backed_name``):
a qualifying rival whose name the recording supports, on the same joint, is named instead of the ripple when it fits
that joint about as well. "About as well" is either of:

- its validation RMSE on the joint within ``NAME_TOLERANCE`` of the ripple's (both leave about the same error), or
- it is a law of the joint's angle (``ANGLE_LAWS``: a spring's polynomial, a counterbalance's odd law, a gas
  spring's lever law) and explains at least ``1 - SHARED_TORQUE`` of the torque the ripple explains there
  (``metrics.explained_rms``: both take about the same torque as functions of the same angle). When the effect is
  large and the nominal model's other misfits (a robot file's inertia off by 10-20 %) dominate what is left, the
  two remaining errors differ by how the ripple's free phase happens to mimic those misfits, not by the effect: on a
  heavy arm's shoulder, a counterbalance of several hundred N m left 106 N m with a ripple of two periods per
  revolution over a fifth of its period and 121 N m with a linear spring of positive stiffness; the ripple kept, the
  spring then fitted on top of it came out with a negative stiffness and was refused, and the balancer went unnamed.
  A rival of another shape (a Coulomb asymmetry, a rotor inertia) may take much of the same torque on a loaded joint
  while following it worse; it is named only by the remaining error.

A ripple that fits its joint clearly better than every such rival on both counts is still named: the data then show
a shape the smooth families cannot follow. The chosen rival must still hold on the second opinion; if it does not,
the selection tries the next best candidate.
"""

from __future__ import annotations

import logging

import numpy as np

logger = logging.getLogger(__name__)

NAME_TOLERANCE = 0.1  # a rival fits a joint as well: its validation RMSE there within this fraction
SHARED_TORQUE = 0.05  # or it explains at least 1 - this of the torque the unsupported candidate explains there
ANGLE_LAWS = ("spring", "gas_spring")  # term keys of the torques of the joint's own angle the shared torque names


def fits_as_well(rival, chosen, joints) -> bool:
    """Whether ``rival`` fits ``joints`` about as well as ``chosen`` (module docstring): both carry per-joint
    ``rmse_v`` (validation RMSE with the term) and ``explained`` (validation torque the term explains,
    ``metrics.explained_rms``) arrays; the shared torque counts for a rival in ``ANGLE_LAWS`` only."""
    joints = list(joints)
    close = np.all(rival.rmse_v[joints] <= (1.0 + NAME_TOLERANCE) * chosen.rmse_v[joints])
    shared = np.all(rival.explained[joints] >= (1.0 - SHARED_TORQUE) * chosen.explained[joints])
    return bool(close or (shared and rival.term.key in ANGLE_LAWS))


def backed_name(chosen, qualified):
    """``chosen`` (a qualifying candidate of a selection round: ``unsupported``, ``term``, ``rmse_v``, ``explained``,
    ``gain``, ``k``, ``index``, ``note``), unless the recording cannot support its name and a qualifying candidate in
    ``qualified`` whose name it supports acts on the same joint and fits it about as well (``fits_as_well``): then
    the best of those (highest gain, then fewer parameters, then the earlier term), with a shape note saying why."""
    reason, joints = chosen.unsupported, list(chosen.term.joints)
    if reason is None or not joints:
        return chosen
    rivals = [
        q
        for q in qualified
        if q.unsupported is None and set(q.term.joints) & set(joints) and fits_as_well(q, chosen, joints)
    ]
    if not rivals:
        return chosen
    rival = max(rivals, key=lambda q: (q.gain, -q.k, -q.index))
    j = joints[0]
    note = (
        f"{rival.term.label} named rather than {chosen.term.label}, which fits joint {j + 1} about as well "
        f"(validation RMSE {rival.rmse_v[j]:.4g} N m, {chosen.rmse_v[j]:.4g} N m with {chosen.term.label}; torque "
        f"explained {rival.explained[j]:.4g} N m, {chosen.explained[j]:.4g} N m) but {reason}"
    )
    logger.info(f"diagnose:   {note}")
    return rival._replace(note="; ".join(x for x in (note, rival.note) if x))
