"""A model file's torque findings in ``diagnose MODEL``'s nominal model: kept from the file, not selected again.

``DiagnosisOptions.carried`` (from ``model_file.model_file_options``: the springs identify took and every torque
finding an earlier ``diagnose --apply`` wrote, ``calibration.model_file_holds``) -> the selection's nominal columns ->
the first kept steps of its result.

Left out of the nominal model, identify's counterbalance is back in the residual, and the diagnosis's first rigid-body
fit (``rigid_body_choice``: the full recalibration it judges the prior's findings against) takes it into the links'
first moments again, inside or outside their envelope; the spring the selection then finds no longer helps, and the
counterbalance identify found is lost (issue 25: the heavy arm's balancer, found 2 of 6 times by ``diagnose MODEL``).
So the carried terms are columns of the nominal model in every fit of the diagnosis (the prior's, the recalibrated
rigid body's, the second opinion's, the stand-in check's): their coefficients are fitted again with the friction (and
the rigid body, when it is identified), their shape is the file's. The library offers no other spring on their joints
(one counterbalance, not two sharing its torque). They are reported first among the findings, with the validation
RMSE without and with them and a shape note that says they were kept from the model file
(``CarriedColumns.selection``); the stand-in check does not drop them (``rigid_body_choice.drop_stand_ins``), and the
plausibility check does not judge them as a new spring (``plausible_fit``: identify's judges kept them).

Every other torque finding the file holds (a ripple, a coupling, a Coulomb asymmetry, a friction shape ... that an
earlier ``diagnose --apply`` wrote) is carried the same way (``carried_candidates``): left out of the nominal model,
its torque was back in the residual and the diagnosis of the applied model found it again, told the user to add what
the model already has, and a second ``--apply`` would have split its torque. Carried, it is a column of the nominal
model, kept and reported first, and the library offers no term of the same label beside it (``CarriedColumns.covers``:
a ripple of another harmonic, a coupling from another joint are still offered).

A model file's drive columns are carried the same way (``drive_columns``: a free rotor inertia beside each, the library
offering no other rotor inertia on its joint, but still its springs: ``CarriedColumns.covers``); they are the file's
parameters, not findings, and neither put the rigid body in question (``rigid_body_choice.inertia_in_question``) nor
stay in the report's findings. So is a torque offset the file chose from the data (``file_offsets``: a free offset
beside the file's held value); a spring on its joint then has no constant of its own (``CarriedColumns.shaped``: the
two would be one column, the rest angle split between them at random), and the report gives it the combined constant
back (``CarriedColumns.with_constants``), the one ``diagnose --apply`` writes (it leaves the offset to the spring).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.diagnosis.columns import BlockColumns
from identification.diagnosis.design import WeightedDesign, joint_weights, left_out
from identification.metrics import rmse

__all__ = ["KEPT_NOTE", "CarriedColumns", "carried_candidates", "carried_labels"]

#: Candidate families that would take a carried counterbalance's torque on its joint (``model_file_holds``'s too).
COUNTERBALANCE_KEYS = ("spring", "gas_spring", "counterbalance")
#: The shape note of a carried term's step (and so of its finding).
KEPT_NOTE = (
    "kept from the model file (identify's counterbalance, or a finding an earlier 'diagnose --apply' wrote): a column "
    "of the diagnosis's nominal model (its shape the file's, its coefficients fitted again), not a candidate; the "
    "RMSE pair is the nominal model without and with it"
)


def carried_candidates(terms) -> tuple:
    """The diagnosis's candidate term of each ``findings.FindingTerm`` in ``terms`` (a model file's torque findings,
    ``ModelFileHolds.torque_terms``): the term its spec describes, the linear spring, or the library's term of its
    effect with its joint (and a coupling's source joint, a ripple's harmonic): the columns the file's finding has."""
    from identification.diagnosis.candidates import SpringTerm
    from identification.diagnosis.term_spec import term_from_spec

    def candidate(term):
        if term.spec is not None:
            return term.candidate
        if term.effect == "spring":
            return SpringTerm(joint=term.joint, order=1)
        options = {"source": term.source, "harmonic": term.harmonic}
        return term_from_spec({"key": term.effect, "joint": term.joint,
                               **{k: v for k, v in options.items() if v is not None}})  # fmt: skip

    return tuple(candidate(t) for t in terms)


def carried_labels(options, key: str | None = None) -> set:
    """The labels of the terms ``options`` (``DiagnosisOptions``) carry (of effect ``key`` only, when given: the
    carried torque offsets of ``"torque_offset"``)."""
    return {term.label for term in getattr(options, "carried", ()) if key is None or term.key == key}


@dataclass(frozen=True, eq=False)
class CarriedColumns:
    """The carried ``terms`` (candidate terms with a joint) of a ``DiagnosisProblem`` (module docstring)."""

    terms: tuple = ()

    def covers(self, term) -> bool:
        """Whether the library's ``term`` would take a carried term's torque: a spring on a carried counterbalance's
        joint, or a carried term itself (its label: a model file's drive column, ``drive_columns``, or finding). A
        carried drive column leaves its joint's springs offered: a rotor inertia takes the joint's acceleration, not
        a torque of its angle; a carried ripple leaves its joint's other harmonics offered, a carried coupling the
        joint's other sources."""
        balanced = {j for carried in self.terms if carried.key in COUNTERBALANCE_KEYS for j in carried.joints}
        spring = term.key in COUNTERBALANCE_KEYS and bool(set(term.joints) & balanced)
        return spring or term.label in {carried.label for carried in self.terms}

    @property
    def offset_joints(self) -> tuple:
        """The joints (0-based) of the carried free torque offsets (a model file's data-chosen ones)."""
        return tuple(j for carried in self.terms if carried.key == "torque_offset" for j in carried.joints)

    def shaped(self, term):
        """The library's ``term`` as the selection fits it: a spring on a carried offset's joint without its constant
        (module docstring); any other term unchanged."""
        if term.key == "spring" and getattr(term, "constant", False) and set(term.joints) & set(self.offset_joints):
            return replace(term, constant=False)
        return term

    def offset_columns(self, problem) -> dict:
        """``{joint: index}`` of each carried offset's column among ``problem``'s nominal columns (the base
        model's, then the carried terms')."""
        start = problem.base_t.n_columns
        out = {}
        for carried in self.terms:
            if carried.key == "torque_offset":
                out[carried.joints[0]] = start
            start += len(carried.feature_names())
        return out

    def with_constants(self, final):
        """``final`` (``diagnose.FinalFit``) with each spring fitted without its constant beside a carried offset
        (``shaped``) given that offset's coefficient as its constant, the offset's coefficient then 0: the same
        torque, the spring's rest angle read from the combined constant (the file's held offset is added where the
        report states it, ``report_assembly.with_held_offset``)."""
        labels = {c.label for c in self.terms if c.key == "torque_offset"}
        offsets = {t.joints[0]: k for k, t in enumerate(final.terms) if t.label in labels}
        springs = [k for k, t in enumerate(final.terms)
                   if t.key == "spring" and not getattr(t, "constant", True) and t.joints[0] in offsets]  # fmt: skip
        if not springs:
            return final
        terms, coefficients = list(final.terms), [np.asarray(c, dtype=float) for c in final.coefficients]
        for k in springs:
            offset = offsets[terms[k].joints[0]]
            terms[k] = replace(terms[k], constant=True)
            coefficients[k] = np.append(coefficients[k], coefficients[offset][0])
            coefficients[offset] = np.zeros(1)
        return replace(final, terms=tuple(terms), coefficients=tuple(coefficients))

    def columns(self, context) -> BlockColumns | None:
        """The carried terms' columns on ``context`` (None without terms)."""
        if not self.terms:
            return None
        return BlockColumns.from_dense(np.concatenate([t.columns(context) for t in self.terms], axis=2))

    def bases(self, problem) -> tuple:
        """``(base_t, base_v, extra_v)`` of ``problem`` with the carried columns after the nominal ones."""
        if not self.terms:
            return problem.base_t, problem.base_v, problem.extra_v
        base_t = problem.base_t.concatenate(self.columns(problem.ctx_t))
        base_v = problem.base_v.concatenate(self.columns(problem.ctx_v))
        extra = tuple((ctx, base.concatenate(self.columns(ctx)), y) for ctx, base, y in problem.extra_v)
        return base_t, base_v, extra

    def selection(self, result, problem, effective_samples=None):
        """The ``SelectionResult`` of a selection run on ``bases``: the carried coefficients out of the nominal ones,
        each carried term a kept step before the selection's, its RMSE pair the nominal model without and with the
        carried terms (``KEPT_NOTE``)."""
        if not self.terms:
            return result
        from identification.diagnosis.selection import SelectionStep

        p0 = problem.base_t.n_columns
        sizes = [len(t.feature_names()) for t in self.terms]
        bounds = np.cumsum([p0, *sizes])
        beta = np.asarray(result.friction_coefficients, dtype=float)
        coefficients = tuple(beta[a:b].copy() for a, b in zip(bounds[:-1], bounds[1:]))
        sigma = joint_weights(problem.ctx_t.tau, left_out(problem.ctx_t))
        design = WeightedDesign(problem.base_t, problem.base_v, problem.y_t, problem.y_v, sigma)
        _, sse0, rmse_t0, rmse_v0, _, _ = design.fit(full=True)
        rmse_t1, rmse_v1 = rmse(problem.y_t, result.nominal_train), rmse(problem.y_v, result.nominal_validation)
        sse1 = max(float(np.sum(((problem.y_t - result.nominal_train) / sigma) ** 2)), 1e-300)
        n = float(problem.y_t.shape[0] if effective_samples is None else effective_samples) * problem.y_t.shape[1]
        delta_bic = n * np.log(sse1 / sse0) + sum(sizes) * np.log(n)
        wval0, wval1 = (float(np.sum(r**2 / sigma**2)) for r in (rmse_v0, rmse_v1))
        steps = tuple(
            SelectionStep(term=t, joints=tuple(t.joints), rmse_before=rmse_v0, rmse_after=rmse_v1,
                          rmse_train_before=rmse_t0, rmse_train_after=rmse_t1, delta_bic=float(delta_bic),
                          validation_gain=(wval0 - wval1) / max(wval0, 1e-300), shape_note=KEPT_NOTE)
            for t in self.terms
        )  # fmt: skip
        return replace(result, steps=steps + tuple(result.steps), friction_coefficients=beta[:p0].copy(),
                       coefficients=coefficients + tuple(result.coefficients))  # fmt: skip
