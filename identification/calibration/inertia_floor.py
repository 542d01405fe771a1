"""A floor under each link's rotational inertia about its centre of mass, from the robot file's own link.

A positive-definite pseudo-inertia and a link inside its bounding ellipsoid (``envelope``) still allow a link whose
mass sits in a point: its inertia about the centre of mass near zero in directions the recordings hardly determine
(a wrist link, a joint whose torque signal holds little more than noise). Such a model fits the recordings and is
consistent, yet its forward dynamics are stiff: a small torque on that joint gives an acceleration of thousands of
rad/s^2, and a simulator or a controller using the exported model fails there.

A real link's mass is spread over its body. The floor keeps the spread of the identified mass about its centre of
mass at least ``FLOOR_SHARE`` of the robot file's in every direction, per unit mass:

    Sigma_c  >=  m F,   F = FLOOR_SHARE * Sigma_c,file / m_file     (positive semi-definite order)

with ``Sigma_c = Sigma - h h^T / m`` the second moment about the centre of mass (``pseudo_inertia``: ``Sigma = tr(I)/2
- I``). ``FLOOR_SHARE`` of the file's second moment is its mass shrunk to half its size about its centre;
CAD inertias are off by tens of percent, not by such factors. By a Schur complement the floor is the linear matrix
inequality ``J - m diag(F, 0) >= 0`` on the pseudo-inertia ``J``: the cone of consistent links moved by a matrix
proportional to the mass (as Wensing, Kim and Slotine's density conditions are linear in ``J``), so the consistent
fit keeps it the way it keeps ``J`` positive definite (``consistent_fit``, ``barrier_path``: the barrier and the
chart on ``J - margin 1 - m diag(F, 0)``). It implies the inertia about the centre of mass ``I_c = tr(Sigma_c) 1 -
Sigma_c`` is at least ``m (tr(F) 1 - F)``. A floor relative to the file's inertia rather than to the link's bounding
volume: the files' inertias per unit mass span orders of magnitude against their links' envelopes, and the file's
link must always satisfy its floor (``m_file F <= Sigma_c,file``). A link the file gives no inertia, or a flat or
point-like one, gets no floor where its second moment is zero.

:func:`inertia_share` measures a link against the file's: the largest ``t`` with ``Sigma_c / m >= t Sigma_c,file /
m_file``; a share at ``FLOOR_SHARE`` says the floor, not the data, set the link's inertia (:func:`floor_notes`).
"""

from __future__ import annotations

import numpy as np

from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT, pseudo_inertia

__all__ = [
    "AT_FLOOR",
    "FLOOR_SHARE",
    "STIFF_FACTOR",
    "com_second_moment",
    "floor_note",
    "floor_notes",
    "inertia_share",
    "link_floors",
    "principal_inertia",
    "stiff_links",
]

#: The identified link's second moment about its centre of mass, per unit mass, is at least this share of the robot
#: file's in every direction.
FLOOR_SHARE = 0.25
#: A link whose share is within this factor of ``FLOOR_SHARE`` rests on its floor (the fit stops a hair inside it).
AT_FLOOR = 1.05
#: A joint that accelerates this many times faster per N m than with the robot file's links has stiff dynamics.
STIFF_FACTOR = 2.0


def com_second_moment(link) -> np.ndarray:
    """``Sigma_c`` (3 x 3) of a link's ten standard parameters: its second moment about the centre of mass [kg m^2]
    (zeros for a massless link)."""
    matrix = pseudo_inertia(np.asarray(link, dtype=float)[:LINK_PARAMETER_COUNT])
    mass = matrix[3, 3]
    if mass <= 0:
        return np.zeros((3, 3))
    return matrix[:3, :3] - np.outer(matrix[:3, 3], matrix[:3, 3]) / mass


def principal_inertia(link) -> np.ndarray:
    """The principal moments [kg m^2] of a link's inertia about its centre of mass, smallest first."""
    sigma = com_second_moment(link)
    return np.linalg.eigvalsh(np.trace(sigma) * np.eye(3) - sigma)


def link_floors(robot, free=None) -> tuple:
    """Per link, its floor ``F`` (3 x 3, per unit mass, module docstring) or None: none for the links not in ``free``
    (0-based; all), nor where the robot file gives no mass or no second moment."""
    free = range(robot.n_dof) if free is None else free
    out = [None] * robot.n_dof
    if robot.links is None:
        return tuple(out)
    prior = robot.nominal_dynamic_parameters()
    for i in free:
        sigma = com_second_moment(prior[i])
        values, vectors = np.linalg.eigh(0.5 * (sigma + sigma.T))
        if prior[i, 0] > 0 and values[-1] > 0:
            out[i] = FLOOR_SHARE * (vectors * np.maximum(values, 0.0)) @ vectors.T / prior[i, 0]
    return tuple(out)


def inertia_share(link, reference) -> float:
    """The largest ``t`` with ``Sigma_c / m >= t Sigma_c,ref / m_ref`` (``reference``: the robot file's link): the share
    of the file's spread the link keeps in its weakest direction; inf where the reference has none, 0 for a link
    without mass or spread."""
    link, reference = np.asarray(link, dtype=float), np.asarray(reference, dtype=float)
    if reference[0] <= 0 or not np.any(com_second_moment(reference)):
        return float("inf")
    if link[0] <= 0:
        return 0.0
    own = com_second_moment(link) / link[0]
    values, vectors = np.linalg.eigh(own)
    if values[0] <= 0:
        return 0.0
    whiten = vectors / np.sqrt(values)
    ref = whiten.T @ (com_second_moment(reference) / reference[0]) @ whiten
    return float(1.0 / max(np.linalg.eigvalsh(0.5 * (ref + ref.T))[-1], 1e-300))


def floor_notes(robot, standard, links=None) -> tuple:
    """One dict per link (among ``links``, 0-based; all with a floor) that rests on or below its floor: ``link``
    (0-based), ``share`` (:func:`inertia_share` against the robot file's), ``floor`` (``FLOOR_SHARE``), the principal
    moments about the centre of mass identified (``inertia``) and in the file (``file_inertia``) [kg m^2], and the
    report's ``message``."""
    if robot.links is None:
        return ()
    prior = robot.nominal_dynamic_parameters()
    standard = np.asarray(standard, dtype=float)
    out = []
    for i in range(robot.n_dof) if links is None else links:
        if not np.all(np.isfinite(standard[i, :LINK_PARAMETER_COUNT])):
            continue
        share = inertia_share(standard[i], prior[i])
        if share > FLOOR_SHARE * AT_FLOOR:
            continue
        own, file = principal_inertia(standard[i]), principal_inertia(prior[i])
        where = "below" if share < FLOOR_SHARE / AT_FLOOR else "on"
        message = (
            f"link {i + 1}'s rotational inertia about its centre of mass rests {where} its floor: principal moments "
            f"{_moments(own)} kg m^2 against the robot file's {_moments(file)} ({share:.2g} x the file's spread per "
            f"unit mass in its weakest direction; the floor is {FLOOR_SHARE:g} x). The recordings hardly determine "
            f"it, so the floor, not the data, set it; record a motion that moves joint {i + 1} with fast reversals "
            "(psdm excite), or identify with a smaller --prior-uncertainty (default 2), which pulls what the "
            "recordings hardly fix, on every link, towards the robot file"
        )
        out.append({"link": i, "share": share, "floor": FLOOR_SHARE, "inertia": own.tolist(),
                    "file_inertia": file.tolist(), "message": message})  # fmt: skip
    return tuple(out)


def floor_note(robot, standard, bounds) -> tuple:
    """The ``envelope_bounds`` entry of a fit (``TrajectoryFit``) whose links have floors (``bounds``:
    ``consistent_fit.FitBounds``): ``("inertia_floor", {"share": FLOOR_SHARE, "links": [1-based links with one],
    "at_floor": floor_notes})``; none without floors."""
    floors = getattr(bounds, "floors", ()) or ()
    links = [i for i, floor in enumerate(floors) if floor is not None]
    if not links:
        return ()
    notes = [{**note, "link": note["link"] + 1} for note in floor_notes(robot, standard, links)]
    return (("inertia_floor", {"share": FLOOR_SHARE, "links": [i + 1 for i in links], "at_floor": notes}),)


def stiff_links(robot, standard) -> tuple:
    """One sentence per link of a model (``standard``, (n_dof, 11)) below its floor (share under ``FLOOR_SHARE /
    AT_FLOOR``): a model written without the floor (``--no-envelope``, a file written before it). Each names the
    link, its principal moments about the centre of mass against the robot file's and the floor, how fast its joint
    accelerates per N m at the middle of the joint limits against the file's model (its mass matrix), and what to
    do. Empty without the robot file's links."""
    from psdm_casadi.oracle import PinocchioOracle

    if robot.links is None:
        return ()
    standard = np.asarray(standard, dtype=float)
    prior = robot.nominal_dynamic_parameters()
    below = [
        (i, inertia_share(standard[i], prior[i]))
        for i in range(robot.n_dof)
        if np.all(np.isfinite(standard[i, :LINK_PARAMETER_COUNT]))
        and standard[i, 0] > 0
        and link_floors(robot, [i])[i] is not None
    ]
    below = [(i, share) for i, share in below if share < FLOOR_SHARE / AT_FLOOR]  # fmt: skip
    if not below:
        return ()
    low, high = (np.clip(np.asarray(v, dtype=float), -np.pi, np.pi) for v in (robot.q_min, robot.q_max))
    q = 0.5 * (low + high)
    model, file = (np.linalg.pinv(PinocchioOracle(robot, p).crba(q)) for p in (standard, prior))  # a massless tip
    out = []
    for i, share in below:
        floor = principal_inertia(np.concatenate([[standard[i, 0]], standard[i, 1:4], _floor_link(standard[i],
                                                  link_floors(robot, [i])[i])]))  # fmt: skip
        faster = model[i, i] / file[i, i]
        speed = f"{model[i, i]:.3g} rad/s^2 per N m at the middle of its limits (robot file: {file[i, i]:.3g})"
        effect = (
            f"Its forward dynamics are stiff: joint {i + 1} accelerates {speed}, {faster:.3g} x faster, so a "
            "simulation or a controller using this model needs tiny steps there"
            if faster >= STIFF_FACTOR
            else f"Joint {i + 1} accelerates {speed}: the links it carries hide it there, but a simulation that "
            "moves this link about its weakest axis sees it spin too easily"
        )
        out.append(
            f"link {i + 1}'s rotational inertia about its centre of mass is below its plausible floor: principal "
            f"moments {_moments(principal_inertia(standard[i]))} kg m^2, the floor {_moments(floor)} ({FLOOR_SHARE:g} "
            f"x the robot file's {_moments(principal_inertia(prior[i]))} per unit mass; this link keeps {share:.2g} x "
            f"in its weakest direction). {effect}. Identify it again with the inertia floor (the default; not "
            f"--no-envelope) and a recording that moves joint {i + 1} with fast reversals (psdm excite), or with a "
            "smaller --prior-uncertainty (default 2), which pulls what the recordings hardly fix towards the robot file"
        )
    return tuple(out)


def _floor_link(link, floor) -> np.ndarray:
    """The six inertia entries about the link frame's origin of a link with ``link``'s mass and centre of mass and
    its floor's spread (``m floor``) about the centre of mass: the floor as a link, for its principal moments."""
    mass, h = float(link[0]), np.asarray(link[1:4], dtype=float)
    sigma = mass * floor + np.outer(h, h) / max(mass, 1e-300)
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return inertia[[0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]


def _moments(values) -> str:
    return "/".join(f"{v:.2g}" for v in values)
