"""What a parameter the fit holds back most likely absorbs, from the evidence the fit has (``held_back``).

A parameter the data want away from the fit (``held_back``) is named with the effect it most likely holds, in the
envelope check's vocabulary (``ABSORBED_EFFECTS``). A rule on the link and the sign alone named "a
counterbalance" for any inertia the data want smaller on a link other than the last two: on the unseen slow-gravity
arm with its tool stated (seed 2) an inertia of link 3 the data want at -0.73 +/- 0.22 was called a counterbalance
where there is none. The effect follows here from the evidence, and the others that fit it too are listed as
alternatives:

- the sign an effect can give the parameter. Each rigid-body effect has a direction in the base parameters: a body
  at the flange (a point mass at the last body's frame, at its origin or 0.1 m along one of its axes: a tool's place
  is not known) ``P pi_payload``, an inertia about joint ``j`` (a rotor, a drive) the column of ``Im_j`` (or the
  drive's own column ``Ia_j``). An effect is a candidate only if one of its directions moves the parameter the way
  the data want (an added rotor cannot make an inertia about a joint smaller);
- which joints carry the torque of the difference (``d = x_ols - x_fit`` over every column, per joint in noise
  levels through the training data's normal equations): a counterbalance or a drive acts on its own joint
  (``LOCAL``: at least 80 % of the squared torque on one joint), a body at the flange on every joint that carries it;
- gravity or inertial, and the motion: a counterbalance is a torque of the angle, seen as a gravity term of either
  sign or, on a periodic motion (``qdd = -w^2 q``: ``angle_following`` >= ``FOLLOWING``), as an inertia the data
  want smaller, never larger. On moves between rests a torque of the angle does not pass for an inertia; less
  inertia on one joint is then first a dynamic of its drive the model lacks (``"drive_dynamics"``: friction that
  lags through the reversals, an elastic transmission, a delay), the counterbalance the alternative;
- where: a parameter of the last two links with mass is moved by a tool at the flange either way (its centre of mass
  and inertia shift), so a payload comes first there, as the envelope check names it.

Where no effect fits the evidence the parameter is named ``"unexplained"`` (:func:`absorbed_phrase` says so): the
data want something none of a payload, extra inertia or a counterbalance gives. The evidence is stated beside the
effect (``likely_effects``' third value: "less inertia; its torque on joint 4 (97%); an acceleration that follows
the angle (0.90: periodic); no body at the flange gives it", a cam on joint 4).
"""

from __future__ import annotations

import numpy as np

from identification.calibration.prior_pull import prior_scale
from identification.data.excitation_check import joint_label
from psdm_casadi.description import physical_to_dynamic

__all__ = [
    "ABSORBED_EFFECTS",
    "FLANGE_OFFSET",
    "FOLLOWING",
    "LOCAL",
    "UNEXPLAINED",
    "absorbed_phrase",
    "angle_following",
    "effect_phrase",
    "likely_effects",
    "owned_columns",
    "parameter_words",
    "torque_shares",
]

#: What the data most likely hold where the fit refuses them: the vocabulary of the envelope check and the parameters
#: the fit holds back (``drive_dynamics`` and ``UNEXPLAINED`` where the evidence fits none of these).
ABSORBED_EFFECTS = ("counterbalance", "payload", "drive_inertia")

#: A difference whose squared torque (in noise levels) sits on one joint by at least this share acts on that joint.
LOCAL = 0.8
#: [m] Where a tool's body may sit from the flange's origin, along each of its axes.
FLANGE_OFFSET = 0.1
#: A joint whose acceleration follows its angle by this correlation moves periodically (``angle_following``).
FOLLOWING = 0.5
#: The name of an effect that none of ``ABSORBED_EFFECTS`` (nor a drive's dynamics) explains.
UNEXPLAINED = "unexplained"


def effect_phrase(absorbs: str, joint: int, robot=None) -> str:
    """What an effect of ``ABSORBED_EFFECTS`` is, in the report's words, at ``joint`` (0-based): one vocabulary for the
    envelope's findings and the parameters the fit holds back (``held_back``)."""
    return {
        "payload": "a payload or tool at the flange that the robot file does not hold (or a stated one that is off)",
        "counterbalance": f"a counterbalance or spring on {joint_label(joint, robot)}",
        "drive_inertia": (
            f"extra inertia on {joint_label(joint, robot)}: a rotor or drive inertia the robot file does "
            "not state (or states off), or a tool, cables or a coupled load it does not hold"
        ),
    }[absorbs]


def parameter_words(model, robot, k: int, seed: int = 0) -> tuple:
    """``(words, joint, kind)`` of base parameter ``k``: ``kind`` ``"axis"`` (the inertia about a joint: its column
    only ever enters that joint's own mass-matrix entry, with a constant coefficient), ``"gravity"`` (it enters the
    gravity torque: a mass times a centre-of-mass offset) or ``"inertia"`` (another inertia of a link)."""
    rng = np.random.default_rng(seed)
    n = robot.n_dof
    q = rng.uniform(robot.q_min, robot.q_max, size=(6, n))
    zero = np.zeros_like(q)
    gravity = model.regressor(q, zero, zero)[:, :, k]
    size = np.abs(model.regressor(q, zero, np.ones_like(q))[:, :, k]).max() + 1e-300
    owner = _owner_link(model, robot, k)
    if np.abs(gravity).max() > 1e-9 * max(size, 1.0):
        return f"the gravity torque of link {owner + 1} (its mass times its centre of mass)", owner, "gravity"
    entries = np.stack([model.regressor(q, zero, np.eye(n)[j] + zero)[:, :, k] for j in range(n)], axis=-1)
    nonzero = np.abs(entries).max(axis=0) > 1e-9 * size  # (n_dof, n_dof): the mass-matrix entries it enters
    j = int(np.argmax(np.diag(np.abs(entries).max(axis=0))))
    if nonzero.sum() == 1 and nonzero[j, j] and np.ptp(entries[:, j, j]) <= 1e-9 * size:
        return f"the inertia about {joint_label(j, robot)}", j, "axis"
    return f"an inertia of link {owner + 1}", owner, "inertia"


def _owner_link(model, robot, k: int) -> int:
    """The link whose standard parameters weigh most in base parameter ``k``, each measured in its size in the robot
    file (``prior_pull.prior_scale``: a link's mass times a squared offset counts as much as the inertia it gives)."""
    sizes = np.abs(model.parameter_map[k]).reshape(-1, 11) * prior_scale(robot.nominal_dynamic_parameters())
    return int(np.argmax(sizes.sum(axis=1)))


def torque_shares(difference, equations, noise) -> np.ndarray:
    """Each joint's share of the squared torque ``Y d`` of ``difference`` (base and drive columns), in noise levels
    of the joint, from the training data's normal equations (``equations.gram`` per joint, ``equations.count``)."""
    d = np.asarray(difference, dtype=float)
    gram = np.asarray(equations.gram, dtype=float)[:, : d.size, : d.size]
    power = np.einsum("i,jik,k->j", d, gram, d) / np.maximum(equations.count, 1) / np.asarray(noise, float) ** 2
    power = np.clip(power, 0.0, None)
    return power / power.sum() if power.sum() > 0 else power


def _payload_directions(model, robot) -> np.ndarray:
    """(n_positions, n_base): the base parameters a 1 kg point mass adds at the flange, at the origin of the last link
    the model gives a body (a massless wrist's body is carried by the link before it) and ``FLANGE_OFFSET`` along
    each of its axes either way."""
    bodies = np.abs(model.parameter_map).reshape(model.n_base, robot.n_dof, 11)[:, :, :10].max(axis=(0, 2))
    last = int(np.flatnonzero(bodies > 0)[-1])
    block = slice(11 * last, 11 * last + 10)
    positions = [np.zeros(3)] + [s * FLANGE_OFFSET * e for e in np.eye(3) for s in (1.0, -1.0)]
    return np.array([model.parameter_map[:, block] @ physical_to_dynamic(1.0, p, np.zeros((3, 3))) for p in positions])


def _inertia_directions(model, robot, n_columns: int, drives: dict) -> dict:
    """``{joint: direction}`` (over the base and drive columns) of 1 kg m^2 more inertia about each joint: the column of
    its rotor inertia ``Im_j`` in the base parameters, or its drive's own column where the fit has one."""
    out = {}
    names = list(model.standard_names)
    for j in range(robot.n_dof):
        direction = np.zeros(n_columns)
        if j in drives:
            direction[drives[j]] = 1.0
        elif f"Im{j + 1}" in names:
            direction[: model.n_base] = model.parameter_map[:, names.index(f"Im{j + 1}")]
        out[j] = direction
    return out


def likely_effects(model, robot, k: int, evidence: dict) -> tuple:
    """``(effects, joint, evidence)``: the effects (``ABSORBED_EFFECTS``, ``"drive_dynamics"`` or ``UNEXPLAINED``)
    that fit what the data want of column ``k``, most likely first (module docstring), the joint to look at, and the
    evidence in words.

    ``evidence``: ``kind`` (``held_back.parameter_words``: ``"axis"``, ``"gravity"``, ``"inertia"``), ``joint`` (its
    0-based joint or link), ``wanted`` (``x_ols - x_fit`` over every column), ``shares`` (``torque_shares`` of it),
    ``drives`` (``{joint: column}`` of the drive inertias fitted on their own), ``distal`` (the last two links with
    mass), ``following`` (``angle_following`` per joint, or None: unknown, periodic assumed)."""
    kind, joint, wanted = evidence["kind"], evidence["joint"], np.asarray(evidence["wanted"], dtype=float)
    sign = np.sign(wanted[k])
    size = np.abs(model.parameter_map).max() * 1e-9
    payload = k < model.n_base and bool(np.any(sign * _payload_directions(model, robot)[:, k] > size))
    inertia = _inertia_directions(model, robot, wanted.size, evidence["drives"])
    about = [j for j, direction in inertia.items() if sign * direction[k] > size]
    shares = np.asarray(evidence["shares"], dtype=float)
    local = int(np.argmax(shares)) if shares.size and shares.max() >= LOCAL else None
    look = local if local is not None else joint
    less = sign < 0 and kind != "gravity"  # less inertia than the fit keeps
    following = evidence.get("following")
    periodic = following is None or following[look] >= FOLLOWING
    ranked = []
    if payload and (joint in evidence["distal"] and kind != "axis" or local is None):
        ranked.append("payload")  # the last links' parameters, or a difference every joint carries
    if about and kind != "gravity":  # more inertia about a joint (a gravity term is no inertia)
        ranked.append("drive_inertia")
    if kind == "gravity" or less and periodic:  # a torque of the angle: gravity-like, or less inertia if periodic
        ranked.append("counterbalance")
    if less:
        ranked += ["drive_dynamics"] + ([] if periodic else ["counterbalance"])
    if payload and "payload" not in ranked:
        ranked.append("payload")
    if ranked[:1] == ["drive_inertia"] and look not in about:
        look = joint if joint in about else about[0]
    periodicity = None if following is None or not less else float(following[look])
    clause = _clause(("more" if sign > 0 else "less", kind), shares, periodicity, payload)
    return (tuple(ranked) or (UNEXPLAINED,)), int(look), clause


def _clause(wanted: tuple, shares, periodicity, payload: bool) -> str:
    """The evidence in words: what the data want, which joints carry its torque, whether the motion is periodic (for
    less inertia), whether a body at the flange gives that sign."""
    more, kind = wanted
    words = [f"{more} {'gravity torque' if kind == 'gravity' else 'inertia'}"]
    top = [j for j in np.argsort(shares)[::-1] if shares[j] >= 0.1]
    if top and shares[top[0]] >= LOCAL:
        words.append(f"its torque on joint {top[0] + 1} ({shares[top[0]]:.0%})")
    elif top:
        words.append("its torque over joints " + ", ".join(f"{j + 1} ({shares[j]:.0%})" for j in top))
    if periodicity is not None:
        words.append(
            f"an acceleration that follows the angle ({periodicity:.2f}: periodic)"
            if periodicity >= FOLLOWING
            else f"moves between rests (acceleration against angle {periodicity:.2f})"
        )
    words.append("a body at the flange can give it" if payload else "no body at the flange gives it")
    return "; ".join(words)


def angle_following(prepared, n_dof: int) -> np.ndarray:
    """Per joint, ``-corr(qdd, q - mean(q))`` over the prepared training recordings: near 1 where the acceleration
    follows the angle (a periodic motion, ``qdd = -w^2 q``: a torque of the angle passes for less inertia), near 0 on
    moves between rests (gravity poses)."""
    out = np.zeros(n_dof)
    if not prepared:
        return out
    q = np.concatenate([r.q - np.mean(r.q, axis=0) for r in prepared])
    qdd = np.concatenate([r.qdd for r in prepared])
    scale = np.sqrt(np.sum(q**2, axis=0) * np.sum(qdd**2, axis=0))
    return np.divide(-np.sum(q * qdd, axis=0), scale, out=out, where=scale > 0)


def absorbed_phrase(effects, joint: int, robot=None) -> str:
    """The report's words for ``effects`` (``likely_effects``): the first, then the alternatives."""
    own = {
        UNEXPLAINED: "an effect the model lacks that no payload, extra inertia or counterbalance gives this sign",
        "drive_dynamics": (
            f"a dynamic of the drive of {joint_label(joint, robot)} the model lacks (friction that lags through the "
            "reversals, an elastic transmission, or a delay between torque and position)"
        ),
    }
    words = [own[e] if e in own else effect_phrase(e, joint, robot) for e in effects]
    return words[0] + "".join(f", or {w}" for w in words[1:])


def owned_columns(model, robot, link: int) -> set:
    """The base parameters of ``link``: those whose standard parameters weigh most in that link (``parameter_words``'
    owner), as the report names them ("the gravity torque of link 2", "an inertia of link 5")."""
    block = np.abs(model.parameter_map[:, 11 * link : 11 * link + 10]).max(axis=1) > 0
    return {k for k in range(model.n_base) if block[k] and _owner_link(model, robot, k) == link}
