"""Second opinions on a finding: more validation recordings, or a block cross-validation of the training recording.

A candidate that qualifies on the validation recording (``selection``) is kept only if it holds on a second
opinion too (``SecondOpinion.judge``):

- **validation recordings** (``diagnose(..., validation=[A, B, ...])``, ``psdm diagnose --validate A B``): the
  candidate, fitted on the training recording, must pass the selection's gates (``selection.passes_gates``) on each
  recording by itself;
- **block cross-validation** (one validation recording): the training recording is cut into ``FOLDS`` contiguous
  blocks; each is held out once, the model with and without the candidate fitted on the others predicts it. The
  candidate must lower the held-out error of its own joints and the joint-weighted error in every block, and pass the
  selection's gates on the blocks' predictions taken together. A torque offset (``REPLICATED``: one constant per
  joint) is judged there on replication, not on the selection's effect size a second time: every block lower with it
  (the offset fitted on the other blocks), its fitted value of one sign on every fold, and the blocks together lower
  by a torque above the joint's floor. The selection asked its gain (``min_improvement``) on the validation recording
  already; on the training blocks the rest of the joint's unexplained torque dilutes the relative gain of any one
  term, however real (the Kinova Gen3's joint-1 sensor offset: 0.39-0.49 N m on the four folds, every block lower,
  11 % pooled, while it takes the validation recording's joint 1 from 1.98 to 1.17 N m). Without an offset, the
  offset fitted on three blocks is noise, which lowers a held-out block only when it has the sign of that block's own
  mean residual and does not overshoot it: below one chance in two per block, below one in 16 for four blocks, on
  top of the validation recording's gain and the training BIC. A deflection (``standstill.DEFLECTIONS``: a joint
  elasticity, a backlash) is judged on the samples where its joint moves (``standstill.moving_samples``): at a
  standstill the friction holds whatever the controller asks, which neither model explains.

A load-dependent friction that holds there must also hold one coefficient on the halves of the training recording
(``load_friction_split``: slow against fast samples, light against heavy load); where it patches the friction of a
friction-dominated joint its halves disagree, and it is unstable with the four halves' numbers (``SPLIT_ROUTE``).

A candidate that fails is not kept and not reported as missing physics: it is an ``UnstableFinding`` with its numbers
(its physical parameters fitted on each recording, or on the training data without each block, and its joints'
RMSE there without and with it), listed apart in the report (``DiagnosisReport.unstable``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.held_friction import CONSTANT_FEATURE
from identification.diagnosis.candidates.base import held_offset
from identification.diagnosis.columns import BlockColumns
from identification.diagnosis.design import WeightedDesign
from identification.diagnosis.load_friction_split import SPLIT_NEXT_STEP, SPLIT_ROUTE, split_fits
from identification.diagnosis.selection import acting_joints, passes_gates
from identification.diagnosis.standstill import DEFLECTIONS, block_mask, moving_samples
from identification.metrics import rmse

FOLDS = 4  # contiguous blocks of the training recording, each held out once
#: Candidate keys judged on the training blocks by replication (module docstring): one constant per joint.
REPLICATED = ("torque_offset",)

VALIDATION_ROUTE = "validation recordings"
CROSS_VALIDATION_ROUTE = "block cross-validation"
MORE_MOTION = "record more motion to decide it"


@dataclass(frozen=True)
class OpinionNumbers:
    """A candidate on one recording or held-out block: its physical parameters fitted there (on the recording alone,
    or on the training data without the block), its joints' RMSE [N m] without and with it, and why it fails the
    gates there (None when it passes)."""

    name: str
    parameters: dict
    joints: tuple
    rmse_before: tuple
    rmse_after: tuple
    failure: str | None

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "parameters": {k: float(v) for k, v in self.parameters.items()},
            "joints": [j + 1 for j in self.joints],
            "rmse_before": list(self.rmse_before),
            "rmse_after": list(self.rmse_after),
            "holds": self.failure is None,
            "failure": self.failure,
        }

    def text(self) -> str:
        params = ", ".join(f"{k} = {v:.4g}" for k, v in self.parameters.items())
        errors = "; ".join(
            f"joint {j + 1} {a:.4g} -> {b:.4g} N m" for j, a, b in zip(self.joints, self.rmse_before, self.rmse_after)
        )
        verdict = "holds" if self.failure is None else f"fails: {self.failure}"
        return f"{self.name}: {params + ' ' if params else ''}({errors}; {verdict})"  # pooled: no parameters


@dataclass(frozen=True)
class UnstableFinding:
    """A candidate that qualified on the validation recording but does not hold on a second opinion: not kept."""

    effect: str
    label: str
    joints: tuple
    route: str
    opinions: tuple
    note: str = ""  # how its numbers read (an offset beside a model file's: ``report_assembly.held_offset_unstable``)

    def to_dict(self) -> dict:
        return {
            "effect": self.effect,
            "label": self.label,
            "joints": [j + 1 for j in self.joints],
            "route": self.route,
            "next_step": self.next_step(),
            "opinions": [o.to_dict() for o in self.opinions],
            "note": self.note,
        }

    def next_step(self) -> str:
        """What decides this candidate: more motion where recordings or blocks disagree; not where its halves do."""
        return SPLIT_NEXT_STEP if self.route == SPLIT_ROUTE else MORE_MOTION

    def sentence(self) -> str:
        failed = sum(o.failure is not None for o in self.opinions)
        return (
            f"`{self.label}` is unstable ({self.route}: it does not hold on {failed} of {len(self.opinions)}), not "
            f"missing physics{f' ({self.note})' if self.note else ''}: " + "; ".join(o.text() for o in self.opinions)
        )


class SecondOpinion:
    """The second opinion of a diagnosis (module docstring).

    Parameters
    ----------
    train_ctx : DiagnosisContext
        The training recording (the candidates' columns).
    validations : sequence of (DiagnosisContext, BlockColumns, array)
        Each validation recording's context, nominal columns and fitted torque, the selection's validation recording
        first. With one, the route is the block cross-validation of the training data.
    folds : int
    offsets : dict
        ``{joint: index}`` of a free torque offset's column among the nominal columns (a model file's data-chosen
        offset, ``carried_terms.CarriedColumns.offset_columns``): a spring fitted beside it without its constant is
        stated with that column's fit as its constant.
    """

    def __init__(self, train_ctx, validations, folds: int = FOLDS, offsets=None):
        self.train_ctx = train_ctx
        self.validations = [list(v) for v in validations]
        self.folds = int(folds)
        self.offsets = dict(offsets or {})

    @property
    def route(self) -> str:
        return VALIDATION_ROUTE if len(self.validations) > 1 else CROSS_VALIDATION_ROUTE

    def keep(self, term) -> None:
        """A kept term joins the validation recordings' base columns (as it joins the selection's design)."""
        for v in self.validations:
            v[1] = v[1].concatenate(BlockColumns.from_dense(term.columns(v[0])))

    def judge(self, design, term, limits) -> UnstableFinding | None:
        """None when ``term`` (qualified on the selection's ``design``) holds on the second opinion; otherwise the
        ``UnstableFinding`` with its numbers."""
        ct = term.columns(self.train_ctx)
        own = acting_joints(term, ct)
        if self.route == VALIDATION_ROUTE:
            opinions = self._recordings(design, term, ct, own, limits)
        else:
            opinions = self._blocks(design, term, ct, own, limits)
        route = self.route
        if all(o.failure is None for o in opinions):
            halves = self._halves(design, term, limits)
            if all(o.failure is None for o in halves):
                return None
            opinions, route = halves, SPLIT_ROUTE
        p = design.G.shape[0]
        beta = design.fit(ct, np.zeros((design.y_val.shape[0],) + ct.shape[1:]))[0]
        effect = term.interpret(beta[p:])[0]
        return UnstableFinding(effect, term.label, tuple(own) or tuple(term.joints), route, tuple(opinions),
                               note=self._held_note(term))  # fmt: skip

    def _held_constant(self, term) -> tuple:
        """``(index, offset)``: the term's constant (``CONSTANT_FEATURE``: a spring's, which holds its rest angle) and
        the torque offset the nominal model holds on its joint (a model file's, ``candidates.base.held_offset``);
        ``(None, 0.0)`` without either."""
        joint = getattr(term, "joint", None)
        names = list(term.feature_names()) if joint is not None else []
        constant = [k for k, name in enumerate(names) if CONSTANT_FEATURE.fullmatch(name)]
        offset = held_offset(self.train_ctx, int(joint)) if constant else 0.0
        return (constant[0], offset) if offset else (None, 0.0)

    def _beside_offset(self, term) -> int | None:
        """The nominal column of the free offset a spring without its constant was fitted beside (``offsets``)."""
        if term.key != "spring" or getattr(term, "constant", True):
            return None
        return self.offsets.get(int(term.joint))

    def _stated(self, term, beta, p: int) -> tuple:
        """``(term, coefficients)`` of the term's part of a fit's ``beta`` (its ``p`` nominal coefficients first) as a
        kept term's are stated (``report_assembly.with_held_offset``): the term's constant plus the offset the nominal
        model holds on its joint (``_held_constant``: the two are one column, so the fit's constant alone is what the
        term adds to the offset, and a spring's rest angle without it is not the spring's); a spring fitted without
        its constant beside a free offset (``_beside_offset``) with the held offset plus that offset's fit as its
        constant. Unchanged without a held offset or coefficients."""
        beta = np.asarray(beta, dtype=float)
        stated = beta[p:].copy()
        column = self._beside_offset(term)
        if column is not None and stated.size:
            offset = held_offset(self.train_ctx, int(term.joint)) + float(beta[column])
            return replace(term, constant=True), np.append(stated, offset)
        index, offset = self._held_constant(term)
        if index is not None and stated.size:
            stated[index] += offset
        return term, stated

    def _held_note(self, term) -> str:
        """How an unstable term's numbers read beside a held offset (``_stated``); "" without one."""
        joint = getattr(term, "joint", None)
        if self._beside_offset(term) is not None:
            return (f"the model file holds a torque offset of {held_offset(self.train_ctx, int(joint)):+.4g} N m on "
                    f"joint {int(joint) + 1}, fitted again beside the term in each fit: each constant below is the "
                    "file's offset plus that fit's part, the rest angle read from it, as a kept term's is")  # fmt: skip
        index, offset = self._held_constant(term)
        if index is None:
            return ""
        return (f"the model file holds a torque offset of {offset:+.4g} N m on joint {int(term.joint) + 1}: each "
                f"fit's constant {term.feature_names()[index]} includes it (the two are one column), and its "
                "parameters below are stated with it, as a kept term's are")  # fmt: skip

    def _halves(self, design, term, limits) -> list:
        """A load-dependent friction's ``mu`` refitted on the slow and the fast, the light- and the heavy-load halves
        of the training recording (``load_friction_split``); [] for any other term."""
        n, n_dof = design.y_train.shape
        fits = split_fits(design, term, self.train_ctx, n * n_dof / limits.n_eff_total)
        return [OpinionNumbers(f.name, {"coefficient": f.mu, "standard_error": f.error}, (int(term.joint),),
                               (f.rmse_before,), (f.rmse_after,), f.failure) for f in fits]  # fmt: skip

    def _recordings(self, design, term, ct, own, limits) -> list:
        """The candidate fitted on the training data, judged on each validation recording by the selection's gates;
        its parameters fitted on each recording alone."""
        p = design.G.shape[0]
        beta0 = design.fit()[0]
        beta1 = design.fit(ct, np.zeros((design.y_val.shape[0],) + ct.shape[1:]))[0]
        shown = list(own) or list(range(ct.shape[1]))
        out = []
        for i, (ctx, base, y) in enumerate(self.validations):
            cv = term.columns(ctx)
            before = rmse(y, base.predict(beta0))
            after = rmse(y, base.predict(beta1[:p]) + cv @ beta1[p:])
            failure = passes_gates(before, after, own, limits.floor, limits.min_improvement, limits.sigma)
            alone = WeightedDesign(base, base, y, y, limits.sigma).fit(cv, cv)[0]
            name = f"validation recording {i + 1}" + (f" ({ctx.name})" if ctx.name else "")
            out.append(_numbers(name, *self._stated(term, alone, p), shown, before, after, failure))
        return out

    def _blocks(self, design, term, ct, own, limits) -> list:
        """Each contiguous block of the training data held out once: the model with and without the candidate fitted
        on the others predicts it (its own joints and the weighted error must improve in every block; a deflection's
        on the samples where its joint moves, ``standstill``); the blocks' predictions together pass the selection's
        gates (for a ``REPLICATED`` term: its fold estimates of one sign and
        an explained torque above the floor, without the relative gain; module docstring)."""
        n = design.y_train.shape[0]
        p = design.G.shape[0]
        y = design.y_train
        pooled0, pooled1 = np.empty_like(y), np.empty_like(y)
        shown = list(own) or list(range(ct.shape[1]))
        out, judged = [], []
        t = self.train_ctx.t
        signs = set()
        moving = moving_samples(self.train_ctx, term.joints[0]) if term.key in DEFLECTIONS and term.joints else None
        for k, block in enumerate(np.array_split(np.arange(n), self.folds)):
            rest = np.setdiff1d(np.arange(n), block)
            fold = WeightedDesign(
                design.base_train.take(rest), design.base_train.take(block), y[rest], y[block], design.sigma
            )
            pooled0[block] = fold.fit(full=True)[5]
            beta, _, _, _, _, pooled1[block] = fold.fit(ct[rest], ct[block], full=True)
            kept = block if moving is None else block[block_mask(moving, block)]
            judged.append(kept)
            before, after = rmse(y[kept], pooled0[kept]), rmse(y[kept], pooled1[kept])
            failure = passes_gates(before, after, own, 0.0, 0.0, design.sigma)
            name = f"training block {k + 1} of {self.folds} (t {t[block[0]]:.1f}-{t[block[-1]]:.1f} s)"
            out.append(_numbers(name, *self._stated(term, beta, p), shown, before, after, failure))
            signs |= set(np.sign(beta[p:]).tolist())
        replicated = term.key in REPLICATED
        gain = 0.0 if replicated else limits.min_improvement
        judged = np.concatenate(judged)
        pooled_before, pooled_after = rmse(y[judged], pooled0[judged]), rmse(y[judged], pooled1[judged])
        pooled = passes_gates(pooled_before, pooled_after, own, limits.floor, gain, limits.sigma)
        if replicated and pooled is not None and pooled.startswith("lowers no"):
            pooled = "explains less torque than the joint's floor on the blocks taken together"
        if pooled is None and replicated and len(signs) > 1:
            pooled = "its fitted value changes sign between the blocks"
        together = _numbers("all blocks held out", term, (), shown, pooled_before, pooled_after, pooled)
        return out + [together]


def _numbers(name, term, coefficients, shown, before, after, failure) -> OpinionNumbers:
    """The ``OpinionNumbers`` of ``term`` with ``coefficients`` (none: no parameters) on the joints ``shown``."""
    parameters = term.physical_parameters(np.asarray(coefficients, dtype=float)) if len(coefficients) else {}
    return OpinionNumbers(
        name=name,
        parameters=dict(parameters),
        joints=tuple(int(j) for j in shown),
        rmse_before=tuple(float(before[j]) for j in shown),
        rmse_after=tuple(float(after[j]) for j in shown),
        failure=failure,
    )
