"""How a judge out of sample sees identify's counterbalance spring: each held-out part, and the parts together.

``counterbalance_column`` fits a spring set on the training recordings and asks its judges (the held-out recordings,
and the block cross-validation of the training recordings, ``counterbalance_folds``) for an ``Opinion``: the models
without and with the springs compared on every part (held-out recording or block) taken together, where the
never-worse rule applies to every joint, and on each part, where the spring's own joint must drop. A ``Trial`` is a
spring set with its opinions and says, for the report, where a spring does not lower its joint.

The block cross-validation asks more of the spring's own joint than "lower": taken together, its blocks must lower it
**beyond their noise margin** (``Opinion.beyond_margin``; the never-worse margin, whose standard error is at least the
spread of the blocks' changes, ``counterbalance_folds.with_fold_spread``). The blocks are the training recording
judging itself: each fold's models are fitted on most of the same samples, and a spring that lowers every block but
owes its gain to one of them has fitted that stretch of the motion, not a torque the arm carries everywhere. On the
heavy virtual arm at seed 1 (a cam on joint 2 beside an unmodelled 100-200 kg tool), the linear spring lowered all
four blocks, one by nearly half and three by less than their own margins, and raised joint 2 on the unseen recording
by a tenth; where the cam holds (seeds 0 and 2) every block drops by a like share and the mean drop clears the
margin. A held-out recording is a motion the fit never saw: there "lower" on each recording is the rule, as for a
diagnosis's finding (``diagnosis.second_opinion``).
"""

from __future__ import annotations

from dataclasses import dataclass

from identification.calibration.never_worse import JointComparison

__all__ = ["HELD_OUT_ROUTE", "Opinion", "Trial"]

#: ``Opinion.route`` of the held-out recordings (``counterbalance_column.CounterbalanceChoice.route``).
HELD_OUT_ROUTE = "held-out recordings"


@dataclass(frozen=True, eq=False)
class Opinion:
    """One judge's comparison of the models without and with the springs: every part (held-out recording or block)
    taken together (the never-worse rule on every joint), and each part (the spring's own joint must drop in each).

    ``beyond_margin``: the parts taken together must lower the spring's joint by more than ``together.margin`` (the
    block cross-validation's rule, module docstring), not only lower it."""

    route: str
    together: JointComparison
    parts: tuple
    beyond_margin: bool = False

    def shortfalls(self, joint: int, before: float | None = None) -> list:
        """Where the springs do not lower ``joint``'s held-out RMSE, as ``(where, without, with, note)`` [N m]: each
        part, then the parts taken together (against ``before`` when given: the model with the other springs; one
        part without ``before`` is its own together; with ``beyond_margin``, a drop within the margin, ``note``
        giving the margin and each part's change)."""
        out = [(self.part_name(k), p.before[joint], p.after[joint], "")
               for k, p in enumerate(self.parts) if p.after[joint] >= p.before[joint]]  # fmt: skip
        if before is not None or len(self.parts) != 1:
            limit = self.together.before[joint] if before is None else before
            drop = self.together.margin[joint] if self.beyond_margin and before is None else 0.0
            if self.together.after[joint] >= limit - drop:
                out.append((f"the {self.route}", limit, self.together.after[joint], self._within(joint, drop)))
        return out

    def _within(self, joint: int, drop: float) -> str:
        """The note of a drop within the margin: the margin and each part's change [N m]."""
        if drop <= 0.0 or self.together.after[joint] >= self.together.before[joint]:
            return ""
        changes = ", ".join(f"{p.after[joint] - p.before[joint]:+.3g}" for p in self.parts)
        kind = "recording" if self.route == HELD_OUT_ROUTE else "block"
        return f", a drop within its noise margin of {drop:.3g} N m (each {kind}'s change: {changes} N m)"

    def lowers(self, joint: int, before: float | None = None) -> bool:
        """Whether the springs lower ``joint``'s held-out RMSE taken together (below ``before`` when given: the model
        with the other springs; with ``beyond_margin``, by more than the margin) and on every part."""
        return not self.shortfalls(joint, before)

    def part_name(self, k: int) -> str:
        """``recording 1 of 2`` or ``block 3 of 4``."""
        return f"{'recording' if self.route == HELD_OUT_ROUTE else 'block'} {k + 1} of {len(self.parts)}"

    def part_dicts(self, joints) -> list:
        """Per part, the RMSE [N m] of ``joints`` without and with the springs (the report's numbers)."""
        return [{"route": self.route, "part": self.part_name(k), "joints": [j + 1 for j in joints],
                 "rmse_without": [float(p.before[j]) for j in joints], "rmse_with": [float(p.after[j]) for j in joints]}
                for k, p in enumerate(self.parts)]  # fmt: skip


@dataclass(frozen=True, eq=False)
class Trial:
    """A spring set fitted on the training recordings (``plain``: the fit without its coefficients, ``document``:
    the model file with its entries) and the judges' opinions (``complete``: every judge gave one)."""

    plain: object
    document: dict
    opinions: tuple
    complete: bool = True

    def failures(self, joints) -> str:
        """Where each of ``joints``' springs does not lower its joint's error (``Opinion.shortfalls``): ``joint 2:
        block 1 of 4 2.203 -> 2.338 N m``."""
        out = [
            f"joint {j + 1}: {where} {without:.4g} -> {after:.4g} N m{note}"
            for j in joints
            for opinion in self.opinions
            for where, without, after, note in opinion.shortfalls(j)
        ]
        return "; ".join(out) or "each lowers it only beside the other springs"
