"""The physical envelope of each link in the consistent fit: a bounding ellipsoid, and mass and drive-inertia bounds.

A positive-definite pseudo-inertia ``J`` (``pseudo_inertia``) says that *some* mass distribution has the
identified parameters, not that it fits in the link: a 580 kg link whose centre of mass is 1.8 m from its
joint is consistent. Wensing, Kim and Slotine (IEEE RA-L 2017, "Linear matrix inequalities for physically
consistent inertial parameter identification") give the condition for a distribution inside an ellipsoid
``{x : (x - c)^T Q (x - c) <= 1}``:

    tr(J Q_hat) >= 0,   Q_hat = [[-Q, Q c], [c^T Q, 1 - c^T Q c]]

(``tr(J Q_hat)`` is the integral of ``1 - (x - c)^T Q (x - c)`` over the mass); with ``J`` positive definite
it is necessary and sufficient. It is linear in the ten standard parameters (:func:`density_weights`), so
the fit adds it as one constraint per link. It also holds the centre of mass in the ellipsoid.

Each link's ellipsoid (:func:`link_envelopes`) is, in this order: the robot file's (``envelope`` in a
``[[link]]`` table); else the one through the corners of the box around the link's URDF collision (else
visual) geometry, oriented along its principal axes (:func:`geometry_envelope`); else the one around the
link's kinematic segment (the joint axes it connects, from the DH rows or the URDF's joint placements) with a
margin (:func:`kinematic_envelope`). It is enlarged, if needed, until the robot file's own link fills at most
``PRIOR_FILL`` of it, so that the prior is always inside.

The ellipsoid around a link's segment reaches well beyond the next joint's origin (its tip holds the capsule's rim),
so a wrist link could put its centre of mass past the joint it carries, taking a tool's weight that hangs further
out. Physically the mass beyond the next joint's origin is that joint's housing, centred on it: the centre of mass
lies at most at the next joint's origin. So a link the next joint's origin bounds (not the last link, whose tool
may sit beyond it; of a length of its own, at least ``REACH_MARGIN`` of the arm's reach; one next joint) has a
``CentreReach`` (:func:`centre_reach`): along the direction from its joint to the next joint's origin its centre of
mass stays within that distance plus ``NEXT_JOINT_MARGIN`` of it (or the robot file's own centre plus as much, if
that lies further out). It is linear in the ten standard parameters, ``m (limit + u . o) - u . h >= 0`` for the
direction ``u`` and joint origin ``o`` (:func:`reach_weights`): one more constraint of the link. A robot file's
own envelope is its statement and gets none.

Masses stay within ``mass_ratio`` times the robot file's (default 0.5-2: CAD masses are off by tens of
percent, not by factors), and drive inertias within ``drive_inertia_ratio`` times the file's where it gives
one. The fit's bounds are options of ``TrajectoryOptions``; what the data push against is read by
``envelope_report``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT
from psdm_casadi.errors import ParameterError
from psdm_casadi.link_envelope import CentreReach, LinkEnvelope
from psdm_casadi.oracle import build_kinematic_model
from psdm_casadi.urdf_geometry import link_geometry_points

__all__ = [
    "LENGTH_MARGIN",
    "NEXT_JOINT_MARGIN",
    "PRIOR_FILL",
    "REACH_MARGIN",
    "centre_reach",
    "check_ratio",
    "density_weights",
    "ellipsoid_fill",
    "envelope_fill",
    "ellipsoid_matrix",
    "geometry_envelope",
    "kinematic_envelope",
    "link_envelopes",
    "reach_weights",
]

#: A link's envelope reaches this fraction of its own length beyond its joint axes ...
LENGTH_MARGIN = 0.25
#: ... and at least this fraction of the arm's reach (wrist links have no length of their own).
REACH_MARGIN = 0.08
#: A link's centre of mass lies at most this fraction of its length beyond the next joint's origin (``CentreReach``):
#: the robot files' centres lie within their links' lengths, a synthetic arm's a little beyond.
NEXT_JOINT_MARGIN = 0.1
#: The robot file's link fills at most this share of its envelope (``envelope_fill``); larger ones are enlarged.
PRIOR_FILL = 0.5


def ellipsoid_matrix(envelope: LinkEnvelope) -> np.ndarray:
    """``Q_hat`` (4 x 4) of the module docstring."""
    q, c = envelope.shape_matrix, envelope.center
    out = np.empty((4, 4))
    out[:3, :3] = -q
    out[:3, 3] = out[3, :3] = q @ c
    out[3, 3] = 1.0 - c @ q @ c
    return out


def density_weights(envelope: LinkEnvelope) -> np.ndarray:
    """``w`` (10,) with ``tr(J Q_hat) = w @ link`` for a link's ten standard parameters (Pinocchio's order).

    With ``Sigma = tr(I)/2 - I``: ``tr(J Q_hat) = tr(Q I) - tr(Q) tr(I) / 2 + 2 h^T Q c + m (1 - c^T Q c)``.
    """
    q, c = envelope.shape_matrix, envelope.center
    half = 0.5 * np.trace(q)
    return np.array([1.0 - c @ q @ c, *(2.0 * q @ c), q[0, 0] - half, 2 * q[0, 1], q[1, 1] - half, 2 * q[0, 2],
                     2 * q[1, 2], q[2, 2] - half])  # fmt: skip


def reach_weights(envelope: LinkEnvelope) -> np.ndarray | None:
    """``w`` (10,) with ``w @ link >= 0`` exactly when the link's centre of mass is within the envelope's ``reach``
    (``m (limit + u . o) - u . h``, over ``limit``: in masses, as ``density_weights``); None without a reach."""
    reach = envelope.reach
    if reach is None:
        return None
    u = reach.direction
    return np.concatenate([[reach.limit + u @ reach.origin], -u, np.zeros(6)]) / reach.limit


def ellipsoid_fill(link, envelope: LinkEnvelope) -> float:
    """The mass-weighted mean of ``(x - c)^T Q (x - c)`` of a link: 1 on the ellipsoid's boundary, > 1 outside."""
    link = np.asarray(link, dtype=float)[:LINK_PARAMETER_COUNT]
    return float(1.0 - density_weights(envelope) @ link / max(link[0], 1e-300))


def envelope_fill(link, envelope: LinkEnvelope) -> float:
    """1 on the envelope's boundary, > 1 outside: the larger of the mass-weighted mean of ``(x - c)^T Q (x - c)`` of a
    link (the ellipsoid's fill) and how far its centre of mass lies along its ``reach`` (a share of its limit)."""
    link = np.asarray(link, dtype=float)[:LINK_PARAMETER_COUNT]
    fill = ellipsoid_fill(link, envelope)
    if envelope.reach is None or link[0] <= 0:
        return fill
    return max(fill, envelope.reach.along(link[1:4] / link[0]))


def _segment_points(robot) -> list:
    """Per link, the origins of the joints it connects, in the link frame, shape (k, 3) each."""
    model, placements = build_kinematic_model(robot)
    out = []
    for i in range(robot.n_dof):
        jid = i + 1
        points = [np.zeros(3)] + [model.jointPlacements[k].translation.copy()
                                  for k in range(jid + 1, model.njoints) if model.parents[k] == jid]  # fmt: skip
        out.append(np.array([placements[i].actInv(p) for p in points]))
    return out


def kinematic_envelope(points, radius: float, source: str = "kinematic lengths") -> LinkEnvelope:
    """The ellipsoid around the capsule of radius ``radius`` [m] about the segment through ``points`` (k, 3).

    The segment runs along the points' principal direction; the capsule of half-length ``h`` and radius ``r``
    lies in the ellipsoid of semi-axes ``sqrt(2) (h + r)`` along it and ``sqrt(2) r`` across (its rim,
    ``(h, r)``, and its tip, ``(h + r, 0)``, are on or inside).
    """
    points = np.atleast_2d(np.asarray(points, dtype=float))
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    spread = points - centre
    _, _, vt = np.linalg.svd(spread if len(points) > 1 else np.eye(3))
    rotation = vt.T if np.linalg.det(vt) > 0 else vt.T * np.array([1.0, 1.0, -1.0])
    local = spread @ rotation
    half = float(np.abs(local[:, 0]).max(initial=0.0))
    across = float(np.linalg.norm(local[:, 1:], axis=1).max(initial=0.0))
    r = radius + across
    return LinkEnvelope(centre, np.sqrt(2.0) * np.array([half + r, r, r]), rotation, source)


def geometry_envelope(points, source: str) -> LinkEnvelope:
    """The ellipsoid through the corners of the box around ``points`` (k, 3), aligned with their principal axes."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    mean = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - mean, full_matrices=True)
    rotation = vt.T if np.linalg.det(vt) > 0 else vt.T * np.array([1.0, 1.0, -1.0])
    local = (points - mean) @ rotation
    low, high = local.min(axis=0), local.max(axis=0)
    half = np.maximum(0.5 * (high - low), 1e-3)  # a flat plate still has a thickness
    return LinkEnvelope.from_box(mean + rotation @ (0.5 * (low + high)), half, rotation, source)


def centre_reach(points, reach: float, com=None) -> CentreReach | None:
    """The ``CentreReach`` of a link whose segment ``points`` (the joint's origin, then the next joints', link frame)
    has one next joint at least ``REACH_MARGIN`` of the arm's ``reach`` [m] away: that distance plus
    ``NEXT_JOINT_MARGIN`` of it, or further out to hold the robot file's centre of mass ``com`` with the same margin;
    None for a link without one next joint (the last link, a branching one) or without a length of its own."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    if len(points) != 2:
        return None
    span = points[1] - points[0]
    length = float(np.linalg.norm(span))
    if length < REACH_MARGIN * reach:
        return None
    u = span / length
    farthest = length if com is None else max(length, float(u @ (np.asarray(com, dtype=float) - points[0])))
    return CentreReach(points[0], u, farthest + NEXT_JOINT_MARGIN * length)


def link_envelopes(robot, free=None) -> tuple:
    """Per link, its ``LinkEnvelope`` (module docstring), or None for the links not in ``free`` (0-based; all).

    The robot file's links (when it has them) are held inside: an envelope they fill more than ``PRIOR_FILL``
    of is enlarged about its centre until they fill that share, and a link's ``reach`` holds its centre of mass.
    """
    free = range(robot.n_dof) if free is None else free
    given = getattr(robot, "envelopes", None) or (None,) * robot.n_dof
    shapes, kind = link_geometry_points(robot)
    segments = _segment_points(robot)
    lengths = [float(np.ptp(p, axis=0).max(initial=0.0)) if len(p) > 1 else 0.0 for p in segments]
    reach = max(sum(lengths), 1e-3)
    prior = robot.nominal_dynamic_parameters() if robot.links is not None else None
    out = [None] * robot.n_dof
    for i in free:
        envelope = given[i]
        if envelope is None and shapes[i] is not None:
            envelope = geometry_envelope(shapes[i], f"URDF {kind} geometry")
        if envelope is None:
            points = segments[i]
            if prior is not None and prior[i, 0] > 0:
                points = np.vstack([points, prior[i, 1:4] / prior[i, 0]])
            envelope = kinematic_envelope(points, max(LENGTH_MARGIN * lengths[i], REACH_MARGIN * reach))
        if prior is not None and prior[i, 0] > 0:
            envelope = _holding(envelope, prior[i])
        if given[i] is None:
            com = prior[i, 1:4] / prior[i, 0] if prior is not None and prior[i, 0] > 0 else None
            envelope = replace(envelope, reach=centre_reach(segments[i], reach, com))
        out[i] = envelope
    return tuple(out)


def _holding(envelope: LinkEnvelope, link) -> LinkEnvelope:
    """``envelope`` enlarged about its centre until ``link`` fills at most ``PRIOR_FILL`` of it."""
    fill = ellipsoid_fill(link, envelope)
    if fill <= PRIOR_FILL:
        return envelope
    grow = np.sqrt(fill / PRIOR_FILL)
    return replace(envelope, semi_axes=envelope.semi_axes * grow)


def check_ratio(owner: str, value) -> None:
    """Refuse a bound ``value`` that is not ``(low, high)`` with ``0 <= low <= 1 <= high`` (multiples of the robot
    file's values; ``high`` may be inf), naming ``owner`` (the option or the command-line flag)."""
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        low = high = float("nan")
    if not (0.0 <= low <= 1.0 <= high):
        raise ParameterError(
            f"{owner} must be (low, high) with 0 <= low <= 1 <= high (multiples of the robot file's values); got "
            f"{value!r}. For example (0.5, 2)."
        )
