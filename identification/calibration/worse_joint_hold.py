"""A joint the robot-file check names worse: held to what the robot file predicts there, where that mends it.

The model ``psdm identify`` hands over must be no worse on any joint than the model it replaces (``robot_file_check``:
per joint the robot file's rigid body with its friction fitted, or the file alone where that predicts the held-out
recordings better). Where the check names joints worse, identify acts instead of only saying so, in two steps, each a
fit made again and judged by the same check. The check judges the model identify would write from a fit, after the
counterbalance and payload steps that follow it (``written_model``): those take torque the fit's links absorbed, and a
joint worse than the file before them need not be after.

1. **friction**: each worse joint's Coulomb and viscous friction held at its baseline's (``held_friction``): the robot
   file's fit on the training recordings (``one_way_friction.file_friction_values``, bounded as identify's own), or
   zero where the baseline is the file alone and the joint moves one way only in training, on the joints where it is
   not held there already. A friction the training recordings determine (the joint reverses) is never zeroed by a
   held-out recording: a drive without friction is not a plausible model, whatever one held-out motion prefers (the
   TX40's wrist, whose training torque is mostly friction, predicted nothing with it at zero). A joint that moves
   one way only in training has a constant friction there, which the rigid body and an offset take as well; on a
   held-out motion that reverses, the friction fitted beside them is wrong (Kinova Gen3 trained on
   opti_traj_testing2 alone: joint 1 turns one way throughout, its friction held to the file's fit at 1.26 N m
   Coulomb, and the file without friction predicts opti_traj_testing1 better);
2. **rigid body**: a joint's torque in a serial chain is carried by its own link and every link after it; the fit is
   made again with the ten inertial parameters of the worse joints' own links held at the robot file's
   (``TrajectoryOptions.held_links``; friction and offsets stay fitted), and where that does not mend them, of every
   link from the first joint still worse to the flange. A joint whose every carried link is held has its drive
   inertia held with them (``consistent_fit.held_rotors``: the last inertia of that joint the fit could move, which
   the file's rigid body, the baseline, carries); the others' stay fitted. The worse joints then predict what the
   robot file's rigid body predicts, and the links before them are fitted to what the held ones leave. Kinova, the same
   fit: joint 6 moves one way through 0.77 rad, its friction held already; links 6 and 7 were fitted to what the
   other joints ask of them (link 7 1.30 kg against the file's 1.10, its centre of mass 4 cm off), and joint 6 was
   worse than the robot file with friction fitted on opti_traj_testing1 (link 6 held alone leaves it worse).
   A link whose robot-file values are not strictly physically consistent (``pseudo_inertia.semidefinite_links``: a
   pseudo-inertia with an eigenvalue at zero, such as a point mass with no rotational inertia) is held at the file's
   lifted by the fit's consistency margin (``consistent_fit.held_standard``: each pseudo-inertia eigenvalue below
   ``TrajectoryOptions.margin`` raised to it, as every link the fit identifies stays): held at the file's own, the
   model fails the consistency check that follows (its mass matrix can be singular: a point mass on its joint's axis
   has no inertia about it) and nothing is written; left fitted, the link keeps what the fit gave it, and a joint it
   carries can stay worse than the file. The record and its sentence name the lifted links (``lifted``). The TX40's
   URDF states its link 6 as a point mass; the SCARA of ``test_worse_joint_hold`` with a point-mass link 4 stayed
   worse on joint 3 with links 1-3 held and link 4 fitted.

A step is kept only if none of the joints the check names worse with it is new (a link held for a wrist joint moves
the rigid body of the joints before it) and they are fewer than before, or the same joints each predicted better than
before the step beyond the paired margin on each held-out recording (``never_worse.compare_each``: nearer the robot
file's, which the check found better there; ``_verdict``); otherwise the fit before it stands. The record says of
every step tried whether it was kept and why, with the RMSE and margin that decided it (``steps``).
A step that brings a joint close to its baseline can leave it named worse by a hair: once its links are the file's, no
estimation allowance is left in its margin, only the paired difference's noise, and a rule of fewer joints alone
refused the step and wrote the model as far off as before. A step kept on the same joints is followed by the next, so
the friction held and then the links leave such a joint predicting what its baseline predicts. A gain within the
paired margin is the comparison's noise, not a step nearer: the TX40's joint 5, which lacks the wrist coupling, stays
far above the file with its friction or link 5 held, nearer by less than the margin; such steps let the held-out
recording decide the model for nothing, and the friction they hold is held in every refit of the model file, so
``diagnose --apply`` could not refit it beside the coupling it finds. The held-out recordings decide a kept step, so
the check that follows is not independent of them: the record (``WorseJointHold``) and its sentence say so, as
``one_way_friction``'s do. A model file states what was held (``identification.worse_joints``): the held friction is
kept by every refit of the file (``HeldFriction.of_document``). ``mode``: ``"hold"`` (default) or ``"report"`` (name
the worse joints only, ``psdm identify --worse-joint report``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

from identification.calibration.held_friction import HELD_TERMS, HeldFriction
from identification.calibration.never_worse import better_on_each
from identification.calibration.one_way_friction import held_options
from psdm_casadi.errors import ParameterError, SolverError

__all__ = [
    "WORSE_JOINT_MODES",
    "WorseJointHold",
    "carried_links",
    "check_worse_joint_mode",
    "hold_worse_joints",
]

logger = logging.getLogger(__name__)

#: ``--worse-joint``: hold a worse joint to what the robot file predicts where that mends it (default), or name it.
WORSE_JOINT_MODES = ("hold", "report")


def check_worse_joint_mode(mode: str) -> None:
    """Raise ``ParameterError`` unless ``mode`` is one of ``WORSE_JOINT_MODES``."""
    if mode not in WORSE_JOINT_MODES:
        raise ParameterError(f"--worse-joint must be one of {', '.join(WORSE_JOINT_MODES)}; got {mode!r}.")


def carried_links(joints, n_dof: int) -> tuple:
    """The links (0-based) whose parameters reach the torque of any of ``joints`` in a serial chain: from the first of
    them to the flange."""
    return tuple(range(min(joints), n_dof)) if len(joints) else ()


@dataclass(frozen=True)
class WorseJointHold:
    """What identify did about the joints the robot-file check named worse (0-based joints and links).

    ``worse``: the joints named worse first; ``held_friction``: the ``(name, value)`` friction held at the baselines'
    by this step; ``held_links``: the links held at the robot file's (empty: none); ``steps``: per fit tried,
    ``(what, joints named worse with it, kept, why)``, ``why`` the RMSE and margins that kept or refused it;
    ``numbers``: per joint named worse first, ``(joint, baseline RMSE, identified RMSE, margin)``; ``left``: the
    joints still worse; ``reason``: why, in words; ``lifted``: those of ``held_links`` the robot file states
    semi-definite (``pseudo_inertia.semidefinite_links``), held at the file's lifted by ``margin`` [kg m^2]
    (``consistent_fit.held_standard``).
    """

    mode: str = "hold"
    worse: tuple = ()
    held_friction: tuple = ()
    held_links: tuple = ()
    steps: tuple = ()
    numbers: tuple = ()
    left: tuple = ()
    reason: str = ""
    lifted: tuple = ()
    margin: float = 0.0

    @property
    def decided_by_held_out(self) -> bool:
        return bool(self.held_friction or self.held_links)

    def describe(self) -> str:
        """One sentence: nothing to do, or what was held, what it left worse, and which steps were refused."""
        if not self.worse:
            return ""
        joints = ", ".join(str(j + 1) for j in self.worse)
        numbers = "; ".join(f"joint {j + 1} {b:.3g} -> {a:.3g} N m (margin {m:.2g})" for j, b, a, m in self.numbers)
        head = f"joint(s) {joints} worse than the robot file on the held-out recording(s) ({numbers}): "
        if not self.decided_by_held_out:
            return head + self.reason
        done = []
        if self.held_friction:
            done.append(f"friction held at the robot file's baseline ({HeldFriction(self.held_friction).describe()})")
        if self.held_links:
            links = ", ".join(str(i + 1) for i in self.held_links)
            done.append(
                f"the rigid body of link(s) {links}, which carry them, held at the robot file's (with the "
                f"drive inertia of each joint whose every carried link is held){self._lifted_words()}"
            )
        return (f"{head}{' and '.join(done)}, and the model fitted again -- {self.reason}. The "
                "held-out recording(s) decided this hold: their check against the robot file that follows is not "
                "independent of it. --worse-joint report keeps the model as identified")  # fmt: skip

    def _lifted_words(self) -> str:
        if not self.lifted:
            return ""
        links = ", ".join(str(i + 1) for i in self.lifted)
        return (f"; link(s) {links} held at the robot file's lifted by {self.margin:.2g} kg m^2 to be strictly "
                "consistent (the file's are semi-definite, a pseudo-inertia eigenvalue at zero, e.g. a point mass: "
                "each eigenvalue below the fit's consistency margin raised to it)")  # fmt: skip

    def to_dict(self) -> dict:
        return {"mode": self.mode, "worse_joints": [j + 1 for j in self.worse],
                "held_friction": {n: v for n, v in self.held_friction},
                "held_links": [i + 1 for i in self.held_links], "left_worse": [j + 1 for j in self.left],
                "lifted_links": [i + 1 for i in self.lifted], "lift_margin": self.margin,
                "steps": [{"held": what, "worse_joints": [j + 1 for j in worse], "kept": kept, "why": why}
                          for what, worse, kept, why in self.steps],
                "before": {f"joint {j + 1}": {"baseline": b, "identified": a, "margin": m}
                           for j, b, a, m in self.numbers},
                "reason": self.reason, "decided_by_held_out": self.decided_by_held_out}  # fmt: skip


def _baseline_friction(options, check, joints, friction_of, fit) -> tuple:
    """The ``(name, value)`` friction of ``joints`` at their baselines' (the file's fit, or 0 for the file alone on a
    joint that moves one way only in training: module docstring) where ``options`` do not hold it there already."""
    zero = {j for j in joints if check.baselines[j] == "alone" and j in check.one_way}
    file_fit = dict(friction_of(fit, [j for j in joints if j not in zero]))
    held, out = dict(options.held_friction), []
    for j in joints:
        names = [f"{t}{j + 1}" for t in HELD_TERMS if t in options.friction]
        values = {n: (0.0 if j in zero else file_fit.get(n, 0.0)) for n in names}
        if any(n not in held or abs(held[n] - v) > 1e-12 for n, v in values.items()):
            out.extend(values.items())
    return tuple(out)


def _against_file(check, joints, words) -> str:
    """``joints`` (0-based) with their RMSE against the robot file's in ``check`` (a ``FileCheck``), after ``words``."""
    c = check.comparison
    return "; ".join(f"joint {j + 1} {words} {c.after[j]:.4g} N m against the file's {c.before[j]:.4g} (margin "
                     f"{c.margin[j]:.2g})" for j in joints)  # fmt: skip


def _verdict(found, left, check, nearer) -> tuple:
    """``(kept, why)``: whether a step mends the joints ``left`` (0-based) the check named worse, and the numbers that
    decided it. Refused where a joint it names worse (``found``, of ``check``: the step's model against the robot
    file) is new; kept where they are fewer, or each is predicted better than before the step beyond the paired margin
    on every held-out recording (``nearer()``: one ``never_worse.JointComparison`` per recording, of the model before
    the step and the step's; asked only then). A gain within the margin is the comparison's noise, not a mend: holding
    by it lets the held-out recordings decide the model for nothing."""
    new = [j for j in found if j not in left]
    if new:
        return False, "refused: " + _against_file(check, new, "newly worse,")
    if set(found) < set(left):
        return True, "kept: fewer worse, " + _against_file(check, [j for j in left if j not in found], "within,")
    comparisons = nearer()
    kept = better_on_each(comparisons, found) == tuple(found)
    steps = "; ".join(f"joint {j + 1} {c.before[j]:.4g} -> {c.after[j]:.4g} N m (margin {c.margin[j]:.2g})"
                      for j in found for c in comparisons)  # fmt: skip
    head = "kept: each nearer" if kept else "refused: not each nearer"
    return kept, f"{head} beyond the paired margin on each held-out recording, {steps}"


def _trial_options(kind, what, options, n_dof) -> tuple:
    """``(options, label)`` of a step: ``options`` with the friction ``what`` (``(name, value)`` pairs) held at the
    baselines' (free in the data's own fit), or with the links ``what`` held at the robot file's."""
    if kind == "friction":
        merged = {**dict(options.held_friction), **dict(what)}
        trial_options = held_options(options, tuple(merged.items()), n_dof)
        chosen = tuple(dict.fromkeys((*options.baseline_friction, *(n for n, _ in what))))
        trial_options = replace(trial_options, baseline_friction=chosen)  # free in the data's own fit
        return trial_options, "friction " + ", ".join(f"{n} {v:.3g}" for n, v in what)
    return replace(options, held_links=what), "links " + ", ".join(str(i + 1) for i in what)


def _link_candidates(left, options, n_dof, tried) -> list:
    """The ``("links", links)`` steps still to try for the joints ``left``, their own links, then every link they carry
    (``carried_links``), each with the links ``options`` hold already and none ``tried`` (which they join)."""
    out = []
    for links in (set(left), set(carried_links(left, n_dof))):
        links = tuple(sorted(set(options.held_links) | links))
        if links != tuple(options.held_links) and links not in tried:
            out.append(("links", links))
            tried.add(links)
    return out


def hold_worse_joints(problem, fit, judges, friction_of, mode: str = "hold", semidefinite=()) -> tuple:
    """``(fit, options, WorseJointHold)``: ``fit`` (made with ``options``) as it is, or made again with its worse joints
    held to what the robot file predicts there, step by step, each kept where it leaves none new and fewer joints
    worse, or the same ones each nearer (module docstring). ``problem = (refit, options, n_dof)``, ``refit(options)``
    the fit made again (identify: carried to the model it writes, ``written_model.WrittenModel``, so that the check
    judges that model); ``judges = (judge, compare)``: ``judge(fit) -> robot_file_check.FileCheck`` on the held-out
    recordings, ``compare(before, after)`` the model of one fit against another's, one ``never_worse.JointComparison``
    per held-out recording; ``friction_of(fit, joints)``: the ``(name, value)`` Coulomb-viscous friction of the robot
    file's fit on the training recordings; ``semidefinite``: the links (0-based) the robot file states not strictly
    consistent (``consistent_fit.lifted_links``: semi-definite, free in the model), which the fit holds lifted
    (``consistent_fit.held_standard``) and the record names."""
    refit, options, n_dof = problem
    judge, compare = judges
    check = judge(fit)
    left = tuple(check.worse)
    if not left:
        return fit, options, WorseJointHold(mode=mode)
    c = check.comparison
    numbers = tuple((j, float(c.before[j]), float(c.after[j]), float(c.margin[j])) for j in left)
    record = WorseJointHold(mode=mode, worse=left, numbers=numbers, left=left)
    if mode == "report":
        return fit, options, replace(record, reason="named only (--worse-joint report)")
    steps, added = [], ()
    friction = _baseline_friction(options, check, left, friction_of, fit)
    candidates, tried = ([("friction", friction)] if friction else []), set()
    while left:
        if not candidates:  # the worse joints' own links first, then every link they carry
            candidates = _link_candidates(left, options, n_dof, tried)
            if not candidates:
                break  # every link the joints left carry is held already
        kind, what = candidates.pop(0)
        trial_options, label = _trial_options(kind, what, options, n_dof)
        if kind == "links" and (lifting := [str(i + 1) for i in what if i in set(semidefinite)]):
            label += f" ({', '.join(lifting)} lifted)"  # semi-definite in the file: ``consistent_fit.held_standard``
        logger.info("identify: joint%s %s worse than the robot file: fitting again with %s held ...",
                    "s" if len(left) > 1 else "", ", ".join(str(j + 1) for j in left), label)  # fmt: skip
        try:
            trial = refit(trial_options)
        except SolverError as error:  # the fit before stands, and the record says why
            steps.append((label, left, False, f"refused: the fit did not converge ({error})"))
            logger.info("identify: the fit with %s held did not converge (%s)", label, error)
            break
        trial_check = judge(trial)
        found = tuple(trial_check.worse)
        kept, why = _verdict(found, left, trial_check, lambda: compare(fit, trial))  # noqa: B023 (called here)
        steps.append((label, found, kept, why))
        logger.info("identify: with %s held: %s", label, why)
        if not kept:
            if kind == "links" and not candidates:
                break
            continue  # the friction did not mend them: the rigid body next
        fit, options, left = trial, trial_options, found
        added = added + (what if kind == "friction" else ())
    held_links = tuple(options.held_links)
    lifted = tuple(i for i in held_links if i in set(semidefinite))
    record = replace(record, held_friction=added, held_links=held_links, steps=tuple(steps), left=left,
                     lifted=lifted, margin=float(options.margin) if lifted else 0.0)  # fmt: skip
    tried = "; ".join(f"with {label} held: joint(s) {', '.join(str(j + 1) for j in found) or 'none'} worse ({why})"
                      for label, found, _, why in steps)  # fmt: skip
    if not record.decided_by_held_out:
        reason = f"{tried or 'nothing left to hold'}; the model stands as identified"
    else:
        joints = ", ".join(str(j + 1) for j in left)
        reason = f"{tried}; " + (f"joint(s) {joints} still worse" if left else "no joint worse")
    return fit, options, replace(record, reason=reason)
