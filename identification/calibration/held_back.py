"""What the data want that the consistent fit does not give: its parameters against the data's own least squares.

The consistent fit (``consistent_fit``) is pulled towards the robot file (``prior_pull``) and held inside each link's
envelope (``envelope``). Its findings about an unmodelled effect come from the envelope's active bounds
(``envelope_report``); but the pull can refuse what the data want without any bound being active (the Kinova Gen3's
sensor fit keeps an inertia of link 7 at the file's 0.36 kg m^2 where the data's least squares want 1.78 +/- 0.30:
the tool at its flange, and nothing was said). So after the
fit each base parameter (and each drive inertia of a column of its own) is compared with the unconstrained weighted
least-squares estimate and its standard deviation (``TrajectoryFit.theta_ols``, ``theta_std``: the sandwich covariance,
which counts the recordings' correlated samples).

A disagreement is reported where all three hold:

- the marginal difference ``|theta_fit - theta_ols| / std`` is at least ``HELD_BACK_SIGMA``;
- the difference matters: its RMS torque along the parameter's column is at least ``MIN_REFUSED_SIGMA`` (1) noise
  level of a joint, the envelope check's size for a refused torque. A clean virtual Denso with LuGre friction, which
  the fitted friction only approximates, gave 4.4 standard deviations on an inertia of link 2 (seed 1) at 0.6 noise
  levels; a hidden inertia about its joint 1 (the tests) gives 240, the Kinova's link-7 inertia 2.5;
- the data's estimate differs from the robot file's value by as much (where the data agree with the file, the fit
  moved the parameter as a side effect of another one it holds back: not an effect of its own).

One unmodelled effect moves several parameters, so they are picked greedily, the largest difference first. Each pick
is then taken at the data's value, and the others' differences are conditioned on it: the data's estimates move with
it by their covariance, ``d -= C[:, k] / C[k, k] d[k]``. Picking stops when no difference reaches the threshold, which
gives the fewest parameters that explain the refusal (at most ``MAX_HELD``). A conditional score was tried instead
(``|g_k| / sqrt(F_kk)``, ``g = F d``, ``F`` the data's information: the chi^2 that freeing one column alone explains,
the others held at the fit). It found nothing on the Kinova Gen3's sensors: its base parameters are so correlated
there that no single column, with the others held, explains much (scores 0.1-2.4). Yet the marginal differences reach
4.8 standard deviations, and the whole difference has chi^2 133 on 64 columns.

One effect can fill the ``MAX_HELD`` picks: on the heavy virtual arm (seed 0) a 100-200 kg tool gave three
parameters of link 5 (343, 39 and 21 standard deviations) while the gravity torque of link 2 the data want at 291 +/-
14 against the fit's 26 (the cam counterbalance on joint 2, held inside link 2's envelope by the pull: 100 times its
size in the robot file) was never named. Up to ``MAX_HELD`` more are picked where a parameter's torque sits on a
joint none of the first picks' does and the data ask for more than a rough robot file explains (``ROUGH_FILE``): a
second effect, not a side effect of the first (a 4 kg tool alone moves parameters of links 2-3 by 0.04-0.9 of their
sizes; none is picked). Each pick's joints are those of the difference left once the earlier picks are taken at
the data's values. The envelope's findings are named from these picks (``causes``).

Each is named in words (:func:`parameter_words`: the inertia about a joint, the gravity torque of a link, an inertia
of a link, a drive inertia) with the likely absorbed effect in the envelope check's vocabulary
(``absorbed_effect.ABSORBED_EFFECTS`` and ``effect_phrase``), chosen from the evidence and with the alternatives that
fit it too (``absorbed_effect``: the sign an effect can give the parameter, the joints whose torque the difference
moves, gravity or inertial), and the route that finds it: ``psdm diagnose`` against the robot file, or (where no
bound is active, only the pull) a weaker pull, ``--prior-uncertainty``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import cache, partial

import numpy as np

from identification.calibration.absorbed_effect import (
    absorbed_phrase,
    angle_following,
    likely_effects,
    parameter_words,
    torque_shares,
)
from identification.calibration.clear_ask import angle_refused, named_where_asked, refused_noise
from identification.calibration.consistent_fit import held_rotors
from identification.calibration.departure_ask import departed_noise
from identification.calibration.envelope_report import (
    DIAGNOSE_ROUTE,
    MIN_REFUSED_SIGMA,
    named_by_departure,
    named_from_evidence,
    pressed_findings,
)
from identification.calibration.gravity_departure import theta_departures
from identification.calibration.inertia_departure import inertia_departures, inertia_note, yielded_findings
from identification.calibration.prior_pull import prior_scale
from identification.data.excitation_check import joint_label

__all__ = [
    "HELD_BACK_SIGMA",
    "MAX_HELD",
    "ROUGH_FILE",
    "HeldBack",
    "held_back",
    "held_note",
    "causes",
    "parameter_words",
    "stored_held_back",
]

#: Standard deviations (of the data's own estimate) by which the fit must differ, and of chi^2 the parameter's column
#: must explain, to be reported. Clean virtual Denso fits stay below 2 on every parameter.
HELD_BACK_SIGMA = 3.0
#: At most this many parameters are named (the greedy pick stops earlier when the rest is explained).
MAX_HELD = 3
#: The prior uncertainty suggested where only the pull holds a parameter back (``--prior-uncertainty``).
WEAKER_PULL = 5
#: A robot file may be this many times its parameters' sizes off (the weaker pull's); beyond, an effect explains what
#: the data want better than a rough file, and a weaker pull is not suggested: the Kinova Gen3's link-7 inertia asks
#: for 10 sizes, and ``--prior-uncertainty 5`` moved it from 0.357 to 0.403 of the 1.78 kg m^2 the data want.
ROUGH_FILE = float(WEAKER_PULL)


@dataclass(frozen=True)
class HeldBack:
    """A parameter the consistent fit keeps away from what the data want (module docstring).

    Attributes
    ----------
    parameter : str
        Its name (``theta10``, or a drive column ``Ia3``).
    words : str
        What it is, for a robotics engineer (``the inertia about joint 1``).
    joint : int
        0-based joint it acts on most (the joint of the inertia; the link's for a gravity or inertia term).
    fitted, data, data_std, file : float
        The fit's value, the data's unconstrained least-squares value and its standard deviation, the robot file's.
    sigma_off : float
        ``(data - fitted) / data_std``.
    torque_sigma : float
        The RMS torque of the difference along its column, in noise levels of the joint where it is largest.
    file_sizes : float
        ``|data - file|`` in the parameter's size as the pull measures it (``prior_pull.prior_scale`` of the standard
        parameters it combines, ``sqrt(sum((c_p scale_p)^2))``): the relative uncertainty a pull would have to state
        to let the data have it.
    absorbs : str
        One of ``absorbed_effect.ABSORBED_EFFECTS`` (or ``absorbed_effect.UNEXPLAINED``): what the data most likely
        hold there (``absorbed_effect.likely_effects``; ``clear_ask.UNNAMED``: they do not clearly ask for one).
    holder : str
        ``"envelope"`` (a bound of the link or drive is active) or ``"pull"`` (the pull towards the robot file alone).
    message : str
        The report's sentence.
    alternatives : tuple of str
        Other effects the evidence fits too, likelier first (none in files written before they were stored).
    effect_joint : int
        0-based joint the effect acts on (where the difference's torque sits); -1: ``joint`` (files written before).
    evidence : str
        What the effects were chosen from, in words (``absorbed_effect.likely_effects``).
    kind : str
        ``parameter_words``' kind: ``"gravity"`` (a term of the gravity torque: a torque of the angle, as a
        counterbalance gives, identify's counterbalance route takes it), ``"axis"`` or ``"inertia"``; "" in files
        written before it was stored.
    """

    parameter: str
    words: str
    joint: int
    fitted: float
    data: float
    data_std: float
    file: float
    sigma_off: float
    torque_sigma: float
    file_sizes: float
    absorbs: str
    holder: str
    message: str = ""
    alternatives: tuple = ()
    effect_joint: int = -1
    evidence: str = ""
    kind: str = ""

    def to_dict(self) -> dict:
        return asdict(self)


def _picks(d, covariance, candidates, threshold: float, home) -> list:
    """Greedy: the candidate columns farthest from the data's estimate, each then taken at the data's value and the
    others conditioned on it (module docstring). ``[(column, difference left when it was picked)]``: ``MAX_HELD``, then
    up to ``MAX_HELD`` more whose column's torque sits on a joint (``home``; -1: not one of these) none of the first
    ones' does: a second effect elsewhere is not crowded out by the parameters one effect moves (the heavy arm's
    payload fills the first three with link 5's; the counterbalance's gravity torque of link 2 is next, on joint 2)."""
    picks, d, std, seen = [], d.copy(), np.sqrt(np.diag(covariance)), set()
    while len(picks) < 2 * MAX_HELD:
        z = np.zeros(d.size)
        z[candidates] = np.abs(d[candidates]) / std[candidates]
        z[[k for k, _ in picks] + [k for k in candidates if len(picks) >= MAX_HELD and home[k] in seen | {-1}]] = 0.0
        k = int(np.argmax(z))
        if z[k] < threshold:
            break
        picks.append((k, d.copy()))
        seen |= {int(home[k])} if len(picks) <= MAX_HELD else set()
        d = d - covariance[:, k] / covariance[k, k] * d[k]
    return picks


def _held_by_choice(model, robot, held_links, names) -> np.ndarray:
    """Per base parameter then drive column ``names``: whether it combines only parameters of ``held_links`` (0-based)
    and their rotors the fit holds (``consistent_fit.held_rotors``), which it holds at the robot file's by choice
    (``worse_joint_hold``): not a parameter the data are held back on."""
    rotors = held_rotors(robot, held_links)
    rows = np.abs(model.parameter_map).reshape(model.n_base, robot.n_dof, -1) > 0
    held = np.zeros(rows.shape[1:], dtype=bool)
    held[list(held_links), :10] = True
    held[list(rotors), 10] = True
    drive = [name.startswith("Ia") and name[2:].isdigit() and int(name[2:]) - 1 in rotors for name in names]
    return np.array([*(bool(np.any(row)) and not np.any(row & ~held) for row in rows), *drive], dtype=bool)


def held_back(robot, model, fitted, covariance, names, envelope=(), threshold: float = HELD_BACK_SIGMA,
              held_links=()) -> tuple:  # fmt: skip
    """The parameters the consistent fit holds away from the data's own estimate (module docstring).

    Parameters
    ----------
    robot, model : RobotDescription, PSDMModel
        As fitted (``model.n_base`` base parameters, then the drive columns ``names``).
    fitted : tuple
        ``(x_fit, x_ols, equations, sigma[, prepared])``: the consistent fit's and the unconstrained weighted least
        squares' (base, drive) parameters, the training data's normal equations over them (``trajectory_data``), the
        joints' noise levels [N m] and the prepared training recordings (whether the motion is periodic,
        ``absorbed_effect.angle_following``; without them a torque of the angle may pass for less inertia).
    covariance : array
        Of ``x_ols`` over the same columns (0 rows and columns: a column held at 0).
    names : sequence of str
        The drive columns' names (``Ia<j>`` are compared; friction and offsets, bounded only by 0, are not).
    envelope : tuple of EnvelopeFinding
        The fit's active bounds: a parameter of a link or drive among them is held by the envelope, else by the pull.
    held_links : tuple of int
        Links (0-based) the fit holds at the robot file's (``TrajectoryOptions.held_links``): a base parameter of
        theirs alone is held there by choice, not named, and taken at the data's value before the others are judged
        (the torque it leaves is no evidence for another parameter's effect).

    Returns
    -------
    tuple of HeldBack
    """
    if robot.links is None:
        return ()
    x_fit, x_ols, equations, noise, *prepared = fitted
    n = model.n_base + len(names)
    d = np.asarray(x_fit, dtype=float)[:n] - np.asarray(x_ols, dtype=float)[:n]
    covariance = np.asarray(covariance, dtype=float)[:n, :n]
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    chosen = _held_by_choice(model, robot, held_links, names)
    for k in np.flatnonzero(chosen & (std > 0)):  # taken at the data's values, as a pick is: no evidence left there
        d = d - covariance[:, k] / covariance[k, k] * d[k]
    drives = [model.n_base + k for k, name in enumerate(names) if name.startswith("Ia") and name[2:].isdigit()]
    prior = robot.nominal_dynamic_parameters()
    theta_file = model.base_parameters(prior)
    file = np.concatenate([theta_file, [prior[int(name[2:]) - 1, -1] if k + model.n_base in drives else np.nan
                                        for k, name in enumerate(names)]])  # fmt: skip
    off = np.abs(np.asarray(x_ols, dtype=float)[:n] - file)  # the data against the file: a side effect agrees with it
    rms = np.sqrt(np.diagonal(equations.gram, axis1=1, axis2=2)[:, :n].T / np.maximum(equations.count, 1))
    torque = np.max(np.abs(d)[:, None] * rms / np.asarray(noise, dtype=float), axis=1)  # in noise levels, worst joint
    candidates = [k for k in [*range(model.n_base), *drives] if std[k] > 0 and torque[k] >= MIN_REFUSED_SIGMA
                  and min(abs(d[k]), off[k]) >= threshold * std[k] and not chosen[k]]  # fmt: skip
    if not candidates:
        return ()
    sizes = off / np.concatenate([np.sqrt(np.sum((model.parameter_map * prior_scale(prior).ravel()) ** 2, axis=1)),
                                  np.maximum(np.abs(file[model.n_base :]), 1e-3)])  # fmt: skip
    masses = [i for i in range(robot.n_dof) if prior[i, 0] > 0]
    pressed = {(f.link, any(b.startswith("drive") for b in f.bounds)) for f in pressed_findings(envelope)}
    following = angle_following(prepared[0], robot.n_dof) if prepared else None
    columns = {int(names[k - model.n_base][2:]) - 1: k for k in drives}
    out = []
    home = np.argmax(rms / np.asarray(noise, dtype=float), axis=1)  # the joint each column's torque sits on most
    home[sizes[:n] <= ROUGH_FILE] = -1  # beyond MAX_HELD only what a rough file does not explain: a second effect
    for k, left in _picks(d, covariance, candidates, threshold, home):
        shares = torque_shares(-left, equations, noise)  # what is left once the earlier picks are at the data's values
        if k < model.n_base:
            words, joint, kind = parameter_words(model, robot, k)
            name = model.base_names[k]
            held = (joint, False) in pressed or (kind == "axis" and (joint, True) in pressed)
        else:
            joint = int(names[k - model.n_base][2:]) - 1
            words, kind, name = f"the drive inertia of {joint_label(joint, robot)}", "axis", names[k - model.n_base]
            held = (joint, True) in pressed
        values = (float(v) for v in (x_fit[k], x_ols[k], std[k], file[k], -d[k] / std[k], torque[k], sizes[k]))
        evidence = {"kind": kind, "joint": joint, "wanted": -d, "shares": shares, "drives": columns,
                    "distal": masses[-2:], "following": following}  # fmt: skip
        effects, at, why = likely_effects(model, robot, k, evidence)
        item = HeldBack(name, words, joint, *values, effects[0], "envelope" if held else "pull",
                        alternatives=effects[1:], effect_joint=at, evidence=why, kind=kind)  # fmt: skip
        out.append(HeldBack(**{**item.to_dict(), "message": _message(item, robot)}))
    return tuple(out)


def _message(item: HeldBack, robot) -> str:
    """The report's sentence: what the data want, what the model keeps and why, what it most likely is, what to run."""
    more = "more" if item.data > item.fitted else "less"
    effects, at = (item.absorbs, *item.alternatives), item.effect_joint if item.effect_joint >= 0 else item.joint
    why = (
        "the robot file's links cannot give " + more + " inside their envelopes and bounds"
        if item.holder == "envelope"
        else "the pull towards the robot file holds it there"
    )
    route = DIAGNOSE_ROUTE.format(what="it")
    if item.holder == "pull":
        if item.file_sizes <= ROUGH_FILE:
            route += (f", or, if the robot file's values are that rough, identify with --prior-uncertainty "
                      f"{WEAKER_PULL} (a weaker pull)")  # fmt: skip
        else:
            why += (f" (the data ask for {item.file_sizes:.3g} times its size in the robot file: more than a rough "
                    "file explains)")  # fmt: skip
    return (
        f"{item.words} ({item.parameter}): the data want {item.data:.4g} +/- {item.data_std:.2g}, the model keeps "
        f"{item.fitted:.4g} (robot file {item.file:.4g}; {abs(item.sigma_off):.1f} standard deviations apart, "
        f"{item.torque_sigma:.2g} x the noise in RMS torque) because "
        f"{why}. The data most likely hold {absorbed_phrase(effects, at, robot)}"
        f"{f' ({item.evidence})' if item.evidence else ''}; {route}."
    )


def causes(robot, model, fitted, covariance, names, envelope, kt=None, held_links=(), noise=None) -> tuple:
    """``(envelope, note)``: the fit's envelope findings named from the same evidence as the parameters it holds back
    (``envelope_report.named_from_evidence``: a pushed link takes the effects of its most significant parameter among
    them) and the ``held_note`` of those (``held_back``'s arguments; ``kt``: the torque constants where the torque
    is motor current, None for joint torques). A proximal link the bounds name a payload is then named a counterbalance
    where the fitted gravity torque of a joint it carries departs from the robot file's alone on the prepared training
    recordings (``envelope_report.named_by_departure``, ``gravity_departure``), unless the data's own least squares
    say that departure is an inertia about the joint the fit holds back (``inertia_departure``): the links pushed on
    its behalf are then named after it, and the departure is stored with the bounds. Last, a counterbalance or payload
    held by a bound that the data do not clearly ask for (``clear_ask.NAMING_RULE``: the torque the bounds refuse, or
    on a joint whose departure named a link, the departure of the data's own least squares there, ``departure_ask``)
    is named as none, or on motor currents as the joint's rotor inertia. The joints' noise it is judged against is
    ``fitted``'s, or where ``noise`` (a callable, asked only when something is judged:
    ``angle_noise.effect_free_noise``) gives less, that; where it says the data hold a torque offset the model lacks,
    the finding says so."""
    items = held_back(robot, model, fitted, covariance, names, envelope, held_links=held_links)
    named, inertias = named_from_evidence(envelope, items, model, robot, kt is not None), {}
    departed = {}  # the bounded fit's departures, where a link could be named after one (read lazily)
    if len(fitted) > 4:  # a link still named a payload beside one: a joint's gravity departing alone says balancer
        theta = np.asarray(fitted[0], dtype=float)[: model.n_base]
        inertias = inertia_departures(robot, model, fitted[4], theta, np.asarray(fitted[1])[: model.n_base], items)

        def departures() -> dict:
            found = theta_departures(robot, model, fitted[4], theta)
            departed.update({j: d for j, d in found.items() if j not in inertias})
            return departed

        named = named_by_departure(named, departures, robot, kt is not None)
        named = yielded_findings(named, inertias)  # a departure the held-back inertia made names no balancer
    noise = None if noise is None else cache(noise)
    sigma = fitted[3] if noise is None else cache(lambda: np.minimum(fitted[3], noise().noise))  # it only takes out
    refused = partial(refused_noise, fitted[2], fitted[0], fitted[1], sigma)
    recordings = fitted[4] if len(fitted) > 4 else ()
    asked = partial(departed_noise, robot, model, recordings, fitted[1], departed, sigma)  # read where refused less
    angle = None if noise is None else partial(angle_refused, fitted[2], fitted[0], fitted[1], noise)
    named, items = named_where_asked(named, items, refused, robot, kt is not None, noise, asked, angle)  # they ask
    return named, (*held_note(items), *inertia_note(inertias))


def held_note(items) -> tuple:
    """The ``(name, value)`` pair stored with the fit's bounds (``TrajectoryFit.envelope_bounds``, the model file's
    ``standard.envelope.held_back``: absent in files written before, read as none)."""
    return (("held_back", [item.to_dict() for item in items]),)


def stored_held_back(envelope_bounds) -> tuple:
    """The ``HeldBack`` of a fit's ``envelope_bounds`` pairs or a model file's ``standard.envelope`` dict (none in a
    file written before they were stored)."""
    unstated = {"torque_sigma": float("nan"), "file_sizes": float("nan")}  # written before these were stored
    entries = [{**unstated, **entry} for entry in dict(envelope_bounds or {}).get("held_back", ())]
    return tuple(HeldBack(**{**e, "alternatives": tuple(e.get("alternatives", ()))}) for e in entries)
