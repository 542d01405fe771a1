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

Only a torque measured on the motor side of the gearbox holds the rotors' inertia (:func:`holds_rotors`): motor
currents, torques the robot file's ``[recording] side`` states on the motor side, or torques that most separate
drive-inertia columns (``Ia<j>``, which ``column_choice`` keeps only where the data want them positive) show to hold
it, such as the Staubli TX40's currents times its gear ratios. A joint-torque sensor behind the gearbox does not (the
Panda's: its separate columns come out negative and are dropped; the Kinova Gen3's: one kept ``Ia7`` of six, a tool's
inertia), and the map stays as derived. A robot
file rarely states rotor inertias (a URDF has none): for a merged joint without one, :func:`sibling_rotors` takes the
drive inertias the same fit identifies as columns of their own (``Ia<j>``) on the joints with the same torque constant
(the same actuator: the Kinova Gen3's joints 1-4 share 9.13 N m/A) as the reference the fit holds it to, each fitted
with the robot file's rigid body held (:func:`file_drive_columns`: the unconstrained fit trades a drive inertia against
the links, and on the Kinova's currents gave joint 4's as 0.02 kg m^2 for the consistent fit's 0.42). The same stated
actuator is an assumption the data may override (:func:`siblings_apart`: a datasheet often lists one torque constant
for base and wrist motors of different sizes): where the training BIC is strongly against the siblings' band, that is
a proposal, recorded with the fit; identify takes the rotor from the data as below only where held-out data confirm it
(``rotors_apart``, which lists the joints in ``TrajectoryOptions.rotors_apart``), and says so. Without a stated
value or such a sibling, :func:`data_rotors` takes what the training data give the drive inertia beside the robot
file's links (the base parameter holding it, less the file's link), held >= 0 only. On the Kinova's currents the links
2 and 4 sat at their upper mass bounds absorbing the rotors of joints 1-2 (link 2's ZZ holds joint 2's rotor: its axis
is normal to joint 1's); held to joints 3-4's the fit keeps them off the links, and the joint-torque sensors give 0.52
and 0.48 kg m^2 for the difference between current and sensor torque (``benchmarks/kinova_gen3.py``,
``sensor_check``). On the TX40's motor-side torques links 1-3 sat at twice their masses on their envelopes
(``benchmarks/real_identification.py``); with the rotors of joints 1 and 2 held near the data's 0.60 and 0.49 kg m^2
(fitted 0.61 and 0.59; ``psdm diagnose`` of the robot file finds 0.60 and 0.51 on its own) they keep 10.7, 3.8 and
3.8 kg (file: 10.5, 3.6, 4.1) and no link is pushed. The diagnosis's enveloped refit (``diagnosis.envelope_check``)
takes its map from :func:`with_merged_rotors` too, on its own normal equations, where a ``rotor_inertia`` finding's
column is a drive-inertia column ``Ia<j>``: both routes hold the same rotors.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np

from identification.calibration.column_verdict import STRONG_BIC
from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT
from identification.calibration.separate_inertia import SPAN_TOLERANCE, random_states, separate_inertia_joints

logger = logging.getLogger(__name__)

__all__ = [
    "MergedRotors",
    "file_drive_columns",
    "holds_rotors",
    "merged_rotor_map",
    "robot_file_theta",
    "sibling_rotors",
    "siblings_apart",
    "with_merged_rotors",
    "without_lone_inertia",
]

SAME_ACTUATOR = 1e-6  # relative difference of two torque constants below which their drives are the same actuator
#: A rotor held to its siblings stays within their values' spread widened by this factor: the same actuator has the
#: same rotor (the robot file's wider ``drive_inertia_ratio`` is for a stated value; on the Kinova's currents it let
#: joints 1-2's rotors reach 2x their siblings', 1.0 kg m^2 against the sensors' 0.52 and 0.48).
SIBLING_SPREAD = 1.25


@dataclass(frozen=True)
class MergedRotors:
    """What identify holds the drive inertias inside the base parameters to: the ``model`` with them in its map, the
    ``robot`` with the reference of each (the file's, or its siblings': :func:`sibling_rotors`), and per joint whose
    reference came from siblings ``(joint, reference, sibling joints, low, high)`` (0-based; [kg m^2]: the band the fit
    holds it in, ``SIBLING_SPREAD``); ``apart``: {joint: (siblings' reference, sibling joints, training BIC change)}
    of the joints taken from the training data rather than the same-actuator reference (``options.rotors_apart``);
    ``proposed``: the same of the joints still held whose training BIC is strongly against the hold
    (:func:`siblings_apart`), for identify to judge on held-out data (``rotors_apart``)."""

    model: object
    robot: object
    from_siblings: tuple = ()
    apart: dict = field(default_factory=dict)
    proposed: dict = field(default_factory=dict)

    def __iter__(self):
        """``model, robot, self``: unpacked where the fit goes on with them."""
        return iter((self.model, self.robot, self))

    def fit_bounds(self, options):
        """``consistent_fit.fit_bounds`` of ``options`` with each sibling-held rotor in its siblings' band."""
        from identification.calibration.consistent_fit import fit_bounds

        bounds = fit_bounds(self.robot, self.model, options)
        if not (options.envelope and self.from_siblings):
            return bounds
        lower, upper = bounds.rotor_lower.copy(), bounds.rotor_upper.copy()
        for j, _, _, low, high in self.from_siblings:
            if j not in bounds.held_rotors:  # held with its links at the reference (``consistent_fit.held_rotors``)
                lower[j], upper[j] = low, high
        return replace(bounds, rotor_lower=lower, rotor_upper=upper)

    def note(self) -> tuple:
        """The ``envelope_bounds`` entry naming the references taken from siblings (empty when none)."""
        if not self.from_siblings:
            return ()
        entries = [{"joint": j + 1, "kg_m2": value, "from_joints": [s + 1 for s in sib],
                    "from": "same actuator" if sib else "training data",
                    "bounds": [low, high if np.isfinite(high) else None],
                    **self._apart_entry(j)}
                   for j, value, sib, low, high in self.from_siblings]  # fmt: skip
        return (("drive_inertia_reference", entries),)

    def _apart_entry(self, j) -> dict:
        """``same_actuator``: the siblings' reference, their joints, the training BIC change and whether the rotor was
        ``taken`` apart (False: a proposal the fit held)."""
        taken = j in self.apart
        if not taken and j not in self.proposed:
            return {}
        reference, siblings, delta = (self.apart if taken else self.proposed)[j]
        return {"same_actuator": {"kg_m2": reference, "joints": [s + 1 for s in siblings], "delta_bic": delta,
                                  "taken": taken}}  # fmt: skip


def merged_rotor_map(model, robot, joints, seed: int = 0) -> dict:
    """{joint: base-parameter coefficients (n_base,)} of the drive inertias of ``joints`` (0-based) that lie in the
    span of the base regressor on random states (``separate_inertia.random_states``; the others are left out)."""
    joints = [int(j) for j in joints]
    if not joints:
        return {}
    q, qd, qdd = random_states(model, robot, seed)
    n_states = q.shape[0]
    stacked = model.regressor(q, qd, qdd).reshape(-1, model.n_base)
    targets = np.zeros((n_states, robot.n_dof, len(joints)))
    for k, j in enumerate(joints):
        targets[:, j, k] = qdd[:, j]
    targets = targets.reshape(-1, len(joints))
    solved = np.linalg.lstsq(stacked, targets, rcond=None)[0]  # one factorisation for every joint
    out = {}
    for k, j in enumerate(joints):
        coefficients, target = solved[:, k].copy(), targets[:, k]
        if np.linalg.norm(stacked @ coefficients - target) <= SPAN_TOLERANCE * np.linalg.norm(target):
            coefficients[np.abs(coefficients) < 1e-9 * np.abs(coefficients).max()] = 0.0
            out[j] = coefficients
    return out


def sibling_rotors(robot, model, kt, drive) -> tuple:
    """``(joint, reference, siblings)`` per merged joint without a rotor inertia in the robot file whose torque constant
    ``kt`` another joint shares that has a drive-inertia column of its own: the median of those columns' values
    (``drive``: {column name: value}, :func:`file_drive_columns`; only positive ones count) is its reference, and their
    spread widened by ``SIBLING_SPREAD`` its band ``(joint, reference, siblings, low, high)``."""
    rotor = np.asarray(robot.rotor_inertia, dtype=float)
    columns = model.parameter_map[:, LINK_PARAMETER_COUNT :: LINK_PARAMETER_COUNT + 1]
    out = []
    for j in range(robot.n_dof):
        if rotor[j] > 0 or np.any(columns[:, j]) or f"Ia{j + 1}" in drive:
            continue
        same = [s for s in range(robot.n_dof) if abs(kt[s] - kt[j]) <= SAME_ACTUATOR * abs(kt[j]) and s != j]
        siblings = [s for s in same if drive.get(f"Ia{s + 1}", 0.0) > 0]
        if siblings:
            values = [drive[f"Ia{s + 1}"] for s in siblings]
            low, high = min(values) / SIBLING_SPREAD, max(values) * SIBLING_SPREAD
            out.append((j, float(np.median(values)), tuple(siblings), float(low), float(high)))
    return tuple(out)


def siblings_apart(robot, model, equations, names, siblings, correlation=None, taken=()) -> tuple:
    """``(siblings, apart, proposed)``: the ``siblings`` entries (:func:`sibling_rotors`) held at their siblings'
    reference, {joint: (reference, sibling joints, BIC change)} of those taken apart (the joints ``taken``, 0-based:
    ``TrajectoryOptions.rotors_apart``), and the same of the held ones the training data want apart. A datasheet
    that states one torque constant and gear ratio for base and wrist does not make their rotors equal (a belt-driven
    cobot's joints 1-2 carry 3x its joint 3's rotor): with the robot file's links held, each merged rotor's value is
    fitted freely beside the drive columns (``names`` of ``equations``, a ``trajectory_data.NormalEquations``), and
    where it lies outside its siblings' band the training BIC of that fit against the one holding it at the
    reference (per joint over the effective samples, the count over the residual's ``correlation`` time, as
    ``column_choice`` counts them) says whether the data want it apart: strong evidence (``column_verdict.STRONG_BIC``)
    proposes it, and identify takes it apart, from the training data (:func:`data_rotors`), where held-out data confirm
    it (``rotors_apart``). A training BIC alone is no finding: beside the file's links the free rotor also takes up
    what the file's link inertias miss, and the hold it is compared with is fitted on the same samples."""
    merged = merged_rotor_map(model, robot, [entry[0] for entry in siblings])
    entries = [entry for entry in siblings if entry[0] in merged]
    if not entries:
        return siblings, {}, {}
    columns = [merged[entry[0]] for entry in entries]
    free_sums = _rotor_residuals(robot, model, equations, len(names), columns)
    factor = np.ones(robot.n_dof) if correlation is None else np.maximum(np.asarray(correlation, dtype=float), 1.0)
    effective = np.maximum(equations.count / factor, 1.0)
    measured = (equations.count > 0) & (free_sums > 0)
    free = _beside_file_links(robot, model, equations, len(names), columns)[0]
    apart, proposed = {}, {}
    for k, (j, reference, sib, low, high) in enumerate(entries):
        if low <= free[k] <= high and j not in taken:
            continue
        others = [c for i, c in enumerate(columns) if i != k]
        held_sums = _rotor_residuals(robot, model, equations, len(names), others, reference * columns[k])
        delta = float(np.sum(effective[measured] * np.log(held_sums[measured] / free_sums[measured]))
                      - np.log(np.sum(effective[measured])))  # fmt: skip
        if j in taken:
            apart[j] = (reference, sib, delta)
        elif delta > STRONG_BIC and not low <= free[k] <= high:
            proposed[j] = (reference, sib, delta)
    return tuple(e for e in siblings if e[0] not in apart), apart, proposed


def _rotor_residuals(robot, model, equations, n_drive, rotor_columns, shift=0.0) -> np.ndarray:
    """Per joint, the training residual sum of squares of :func:`_beside_file_links` (its base parameters shifted by
    ``shift``, a held rotor's share)."""
    theta = robot_file_theta(robot, model) + shift
    rotors, drive = _beside_file_links(robot, model, equations, n_drive, rotor_columns, shift)
    x = np.zeros(equations.n_columns)
    x[: theta.size] = theta + (np.column_stack(rotor_columns) @ rotors if len(rotor_columns) else 0.0)
    x[theta.size : theta.size + n_drive] = drive
    return equations.residual_sum(x)


def file_drive_columns(robot, model, equations, names) -> dict:
    """{column name: value} of the drive columns ``names`` (those after the base parameters in ``equations``, a
    ``trajectory_data.NormalEquations``) fitted by least squares with the robot file's rigid body held: each joint's
    friction, offset and drive inertia explain what the file's links leave of its torque."""
    return dict(zip(names, _beside_file_links(robot, model, equations, len(names))[1].tolist()))


def data_rotors(robot, model, equations, names, joints) -> dict:
    """{joint: drive inertia [kg m^2]} of the merged drive inertias of ``joints`` (0-based) the training data want
    positive with the robot file's rigid body held: the least squares of those drive inertias and the drive columns
    ``names`` on what the file's links leave of the torque (a base parameter holding a rotor, such as the first joint's
    ZZ, takes the file's link and the rest is the rotor's). Joints whose value comes out <= 0 are left out."""
    merged = merged_rotor_map(model, robot, joints)
    if not merged:
        return {}
    rotors, _ = _beside_file_links(robot, model, equations, len(names), list(merged.values()))
    return {j: float(v) for j, v in zip(merged, rotors) if v > 0}


def _beside_file_links(robot, model, equations, n_drive, rotor_columns=(), shift=0.0) -> tuple:
    """(rotor values, drive values) of the least squares with the robot file's rigid body held: the ``n_drive`` drive
    columns that follow the base parameters in ``equations`` and, for each of ``rotor_columns`` (a drive inertia's
    coefficients in the base parameters, ``merged_rotor_map``), its value, on what the file's links leave of the
    torque (``shift``: added to the file's base parameters, a held rotor's share)."""
    theta = robot_file_theta(robot, model) + shift
    size, n_rotors = theta.size + n_drive, len(rotor_columns)
    gram, moment, _ = equations.weighted(np.ones(robot.n_dof))
    gram, moment = gram[:size, :size], moment[:size]
    transform = np.zeros((size, n_rotors + n_drive))
    if n_rotors:
        transform[: theta.size, :n_rotors] = np.column_stack(rotor_columns)
    transform[theta.size :, n_rotors:] = np.eye(n_drive)
    start = np.concatenate([theta, np.zeros(n_drive)])
    values = np.linalg.lstsq(transform.T @ gram @ transform, transform.T @ (moment - gram @ start), rcond=None)[0]
    return values[:n_rotors], values[n_rotors:]


def holds_rotors(model, robot, kt, names) -> bool:
    """Whether the torque signal holds the rotors' inertia (is measured on the motor side of the gearbox): motor
    currents (``kt``), torques the robot file's ``[recording] side`` states on the motor side, or else the fit's own
    drive-inertia columns (``Ia<j>``: ``column_choice`` keeps only those the data want positive, as motor-side torques
    give them) kept on at least half of the joints that have one (``separate_inertia.separate_inertia_joints``), and
    on two at least where two can be had. A single kept column among several is no evidence: on the Kinova Gen3's
    joint-torque sensors (link side) a kept ``Ia7`` stood in for a tool's inertia, and taking the signal for a
    motor-side one fitted the rotors of joints 1-2 from the data and released joint 2's inertia from the pull
    (validation 2.77 -> 6.85 N m)."""
    layout = getattr(robot, "recording_layout", None)
    if kt is not None or (layout is not None and layout.side("tau") == "motor"):
        return True
    kept = {int(name[2:]) - 1 for name in names if name.startswith("Ia") and name[2:].isdigit()}
    if not kept:
        return False
    separate = separate_inertia_joints(model, robot)
    return 2 * len(kept) >= len(separate) and len(kept) >= min(2, len(separate))


def without_lone_inertia(robot, model, evidence) -> list:
    """``evidence`` (``column_choice.Evidence`` of a torque signal) with the drive-inertia columns the held-out data
    alone kept (``departs``) dropped where too few columns are kept to show a motor-side torque (:func:`holds_rotors`):
    behind the gearbox such a column stands for something else (the Kinova Gen3's sensors: ``Ia7``, BIC -0.93, a
    tool's inertia; kept, joint 7 0.17 -> 0.26 N m held out). A column the training data want too stays (no rotor is
    inferred from it)."""
    names = [f"Ia{e.joint + 1}" for e in evidence if e.term == "Ia" and e.kept]
    if not names or holds_rotors(model, robot, None, names):
        return evidence
    reason = (f"kept by the held-out data alone, on {len(names)} of the {len(separate_inertia_joints(model, robot))} "
              "joints with a column: too few for a torque that holds the rotors' inertia (a sensor behind the "
              "gearbox)")  # fmt: skip
    lone = {e.joint for e in evidence if e.term == "Ia" and e.kept and e.departs}
    return [replace(e, kept=False, reason=reason, departs=False) if e.term == "Ia" and e.joint in lone else e
            for e in evidence]  # fmt: skip


def with_merged_rotors(
    model, robot, options, kt=None, columns=None, log: bool = True, correlation=None
) -> MergedRotors:
    """The drive inertias of the base parameters in ``model``'s map, each held to a reference: the robot file's rotor
    inertia, else (currents) its siblings' (:func:`sibling_rotors` of :func:`file_drive_columns`), else what the
    training data want with the file's links held (:func:`data_rotors`; bounded below by 0 only). ``kt``: the torque
    constants of recordings of currents; ``columns``: the normal equations and the drive columns' names of the fit.
    ``model`` and ``robot`` unchanged when there are none: no drive inertia asked for (``options.drive_inertia``;
    ``options`` None asks for it), a signal that holds no rotor inertia (:func:`holds_rotors`), or no reference.
    ``log`` False says what it holds at DEBUG only (the diagnosis's refits, ``envelope_check``, make many)."""
    unchanged = MergedRotors(model, robot)
    names = () if columns is None else tuple(columns[1])
    if not ((options is None or options.drive_inertia) and holds_rotors(model, robot, kt, names)):
        return unchanged
    drive = {} if columns is None or robot.links is None else file_drive_columns(robot, model, *columns)
    siblings = () if kt is None else sibling_rotors(robot, model, np.asarray(kt, dtype=float), drive)
    apart, proposed = {}, {}
    if siblings and drive:
        taken = () if options is None else tuple(options.rotors_apart)
        siblings, apart, proposed = siblings_apart(robot, model, *columns, siblings, correlation, taken)
    rotor = np.array(robot.rotor_inertia, dtype=float)
    for j, value, *_ in siblings:
        rotor[j] = value
    mapped = model.parameter_map[:, LINK_PARAMETER_COUNT :: LINK_PARAMETER_COUNT + 1]
    unstated = [
        j for j in range(robot.n_dof) if rotor[j] <= 0 and not np.any(mapped[:, j]) and f"Ia{j + 1}" not in names
    ]
    wanted = (
        {} if columns is None or robot.links is None or not unstated else data_rotors(robot, model, *columns, unstated)
    )
    for j, value in wanted.items():
        rotor[j] = value
    joints = [j for j in range(robot.n_dof) if rotor[j] > 0 and not np.any(mapped[:, j])]
    merged = merged_rotor_map(model, robot, joints) if joints else {}
    if not merged:
        return unchanged
    say = logger.info if log else logger.debug
    for j, value, sib, *_ in siblings:
        say("identify: joint %d's drive inertia lies inside the base parameters and the robot file states "
                    "none; held near %.3g kg m^2, the drive inertias of joints %s (the same torque constant)", j + 1,
                    value, ", ".join(str(s + 1) for s in sib))  # fmt: skip
    for j, (reference, sib, delta) in apart.items():
        say("identify: joint %d's drive inertia: the same torque constant as joints %s gave it %.3g kg m^2, but it is "
            "taken apart, from the training data (BIC %+.3g beside the file's links)", j + 1,
            ", ".join(str(s + 1) for s in sib), reference, delta)  # fmt: skip
    for j, (_, sib, delta) in proposed.items():  # judged by identify on held-out data (``rotors_apart``)
        logger.debug("identify: joint %d's drive inertia: the training data want it apart from joints %s (BIC %+.3g "
                     "beside the file's links)", j + 1, ", ".join(str(s + 1) for s in sib), delta)  # fmt: skip
    for j, value in wanted.items():
        say("identify: joint %d's drive inertia lies inside the base parameters and the robot file states "
                    "none; the training data give it %.3g kg m^2 beside the file's links: the consistent fit holds it "
                    ">= 0 there rather than in link %d", j + 1, value, j + 1)  # fmt: skip
    parameter_map = np.array(model.parameter_map, dtype=float)
    for j, coefficients in merged.items():
        parameter_map[:, j * (LINK_PARAMETER_COUNT + 1) + LINK_PARAMETER_COUNT] = coefficients
    say("identify: drive inertias of joints %s inside the base parameters, held near their reference "
                "in the consistent fit", ", ".join(str(j + 1) for j in sorted(merged)))  # fmt: skip
    kept = tuple(entry for entry in siblings if entry[0] in merged)
    kept += tuple((j, value, (), 0.0, float("inf")) for j, value in wanted.items() if j in merged)
    robot = replace(robot, rotor_inertia=np.where([j in merged for j in range(robot.n_dof)], rotor,
                                                  robot.rotor_inertia))  # fmt: skip
    apart = {j: entry for j, entry in apart.items() if j in merged and j in wanted}
    proposed = {j: entry for j, entry in proposed.items() if j in merged}
    return MergedRotors(replace(model, parameter_map=parameter_map), robot, kept, apart, proposed)


def robot_file_theta(robot, model, kt=None) -> np.ndarray:
    """The robot file's base parameters in the map identify fits in: on motor currents (``kt`` given) with the rotor
    inertias the file states on joints whose drive inertia the base parameters merge (:func:`with_merged_rotors`),
    else the derived map's (the rigid body, and the drive inertias the model was derived with). The diagnosis's
    baselines use it, so that a robot file's prediction, its enveloped recalibration and identify agree on currents.
    """
    merged = with_merged_rotors(model, robot, None, kt).model
    return merged.base_parameters(robot.nominal_dynamic_parameters())
