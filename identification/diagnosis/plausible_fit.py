"""Findings whose final coefficients are physically meaningless are not findings, whichever fit moved them there.

The selection judges a candidate's coefficients when it qualifies (``CandidateTerm.implausibility``: a negative
stiffness, an offset beyond the joint's gravity torque, a load-dependent friction with mu >= 0.4). Later fits move
them: each term kept after it refits the earlier ones jointly, the Ipopt refinement refits every linear coefficient
with the nonlinear parameters, and the rigid-body choice refits them on a recalibrated rigid body (a load-dependent
friction refitted beside a payload reached mu = 0.54). ``implausible_terms`` judges the final coefficients by the
same rule; ``diagnose`` keeps the linearised fit when the refinement alone made a term implausible
(``refine_terms``), and ``plausible_diagnosis`` runs the selection again without a term whose final coefficients are
implausible, reported as rejected with the reason (``DiagnosisReport.rejected``).
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from identification.diagnosis.candidates import CandidateLibrary, default_library
from identification.diagnosis.carried_terms import carried_labels

__all__ = ["implausible_terms", "plausible_diagnosis"]

logger = logging.getLogger(__name__)

#: Most diagnoses run again without the terms found implausible.
MAX_ROUNDS = 3


def implausible_terms(terms, coefficients, context) -> tuple:
    """``((term, reason), ...)`` of the ``terms`` whose ``coefficients`` are physically meaningless on ``context``."""
    out = []
    for term, c in zip(terms, coefficients):
        reason = term.implausibility(np.asarray(c, dtype=float), context)
        if reason is not None:
            out.append((term, reason))
    return tuple(out)


def plausible_diagnosis(run, options, n_dof: int) -> tuple:
    """``(fit, rejected)``: ``run(options)`` -> ``(problem, selection, final, options, notes, unnamed)``, run again
    without the library's instances of a term whose final coefficients are implausible (by family and joint: a
    spring's chosen shape is one of its instance's variants), ``rejected`` the ``(label, reason)`` of those terms. The
    terms ``options.carried`` are not judged: they are the nominal model's (``carried_terms``)."""
    rejected = []
    for _ in range(MAX_ROUNDS):
        fit = run(options)
        problem, final = fit[0], fit[2]
        carried = carried_labels(
            options
        )  # a model file's counterbalance: identify's judges kept it (``carried_terms``)
        bad = [
            (t, r)
            for t, r in implausible_terms(final.terms, final.coefficients, problem.ctx_t)
            if t.label not in carried
        ]
        if not bad:
            break
        for term, reason in bad:
            logger.info(f"diagnose: {term.label} rejected after the final fit: {reason}; selecting again without it")
            rejected.append((term.label, f"{reason} (after the final fit)"))
        gone = {(term.key, term.joint) for term, _ in bad}
        instances = (options.library or default_library()).expand(n_dof)
        library = CandidateLibrary(tuple(t for t in instances if (t.key, t.joint) not in gone))
        options = replace(options, library=library)
    return fit, tuple(rejected)
