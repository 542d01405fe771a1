"""Unnamed (sparse) terms that only stand in for a wrong prior: with ``rigid_body="auto"``, when the prior model needed
an inertial finding, a sparse term beyond the library is judged against the diagnosis with the rigid body identified
(``rigid_body_choice.standing_in``), as the library's findings are.

The problems are synthetic with a known truth: the prior fit's residual on joint 2 carries a law the sparse library
writes exactly (``sin(2 q2) sign(qd2)``); in the diagnosis with the rigid body identified it is either gone (the
recalibration explained it: the term stands in for the robot file's inertia) or still there (the term is needed
whichever rigid body is used)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.diagnosis import DiagnosisOptions
from identification.diagnosis.beyond_library import look_beyond_library
from identification.diagnosis.candidates import PayloadTerm, SpringTerm
from identification.diagnosis.context import build_context
from identification.diagnosis.diagnose import DiagnosisProblem, FinalFit
from identification.diagnosis.nominal import friction_blocks, friction_feature_names
from identification.diagnosis.rigid_body_choice import IdentifiedDiagnosis
from identification.diagnosis.sparse_terms import SparseTerm, sparse_features
from tests.identification.diagnosis_data import recording_pair

OPTIONS = DiagnosisOptions(friction="coulomb_viscous")
LAW = "sin(2q2) sign(qd2)"
AMPLITUDE = 20.0  # [N m], well above the sparse stage's floors on the Denso's joint 2
NOISE = 0.05  # [N m]


@pytest.fixture(scope="module")
def contexts(denso, denso_model):
    train, val = recording_pair(denso, [], seed=11, train_s=6.0, val_s=4.0)
    # a 50 Hz grid (the signals are low-pass filtered at 5 Hz): the sparse search is the costly part, per sample
    options = PreprocessOptions(cutoff_hz=5.0)
    return tuple(build_context(denso, denso_model, preprocess(r, options), 50.0, 5.0) for r in (train, val))


def _problem(robot, contexts, amplitude: float, seed: int) -> DiagnosisProblem:
    """A problem whose residual is ``amplitude`` times the law on joint 2 plus white noise (zero on the other joints),
    the nominal friction's columns as its base."""
    feature = next(f for f in sparse_features() if f.name(1) == LAW)
    rng = np.random.default_rng(seed)
    y = []
    for ctx in contexts:
        law = SparseTerm(joint=1, features=(feature,)).columns(ctx)[:, :, 0] * amplitude
        law[:, 1] += NOISE * rng.standard_normal(ctx.n_samples)  # the other joints are explained exactly
        y.append(law)
    base = [friction_blocks(robot, OPTIONS.friction, ctx) for ctx in contexts]
    return DiagnosisProblem(ctx_t=contexts[0], ctx_v=contexts[1], base_t=base[0], base_v=base[1], y_t=y[0], y_v=y[1])


def _fit(robot, problem, steps) -> tuple:
    """A selection with ``(term, named joints)`` steps and its final fit: every coefficient zero (the kept terms add
    nothing on joint 2, so what the beyond-library stage sees there is the law alone)."""
    selection = SimpleNamespace(steps=tuple(SimpleNamespace(term=t, joints=j) for t, j in steps), dropped=())
    final = FinalFit(
        terms=tuple(t for t, _ in steps),
        coefficients=tuple(np.zeros(len(t.feature_names())) for t, _ in steps),
        friction_coefficients=np.zeros(len(friction_feature_names(OPTIONS.friction, robot.n_dof))),
        prediction_t=np.zeros_like(problem.y_t),
        prediction_v=np.zeros_like(problem.y_v),
        nonlinear={},
    )
    return selection, final


def _identified(robot, contexts, amplitude: float) -> IdentifiedDiagnosis:
    """The diagnosis with the rigid body identified, which kept no library term: its residual on joint 2 carries
    ``amplitude`` times the law."""
    problem = _problem(robot, contexts, amplitude, seed=2)
    return IdentifiedDiagnosis(problem, *_fit(robot, problem, ()), replace(OPTIONS, rigid_body="identified"))


PAYLOAD = (PayloadTerm(), (0, 1, 2))


def test_an_unnamed_term_the_identified_rigid_body_does_not_need_is_left_out(denso, contexts):
    problem = _problem(denso, contexts, AMPLITUDE, seed=1)
    selection, final = _fit(denso, problem, (PAYLOAD,))
    # without the identified diagnosis to judge it against (``rigid_body="prior"``), the law is an unnamed effect
    _, kept_final, unnamed, notes = look_beyond_library(problem, selection, final, OPTIONS)
    assert [(f.effect, f.joints) for f in unnamed] == [("unnamed_effect", (1,))] and notes == ()
    assert unnamed[0].validation_gain > 0.9
    # the recalibrated rigid body explains it (its residual on joint 2 is noise): it stands in for the wrong inertia
    identified = _identified(denso, contexts, 0.0)
    _, dropped_final, unnamed, notes = look_beyond_library(problem, selection, final, OPTIONS, identified)
    assert unnamed == () and len(notes) == 1
    assert "`unnamed_effect[j2]` not reported as missing physics" in notes[0] and "robot file's inertia" in notes[0]
    assert dropped_final.terms == final.terms and np.all(dropped_final.prediction_v == 0.0)
    assert kept_final.terms[-1].label == "unnamed_effect[j2]"


def test_an_unnamed_term_needed_with_the_rigid_body_identified_too_is_reported(denso, contexts):
    problem = _problem(denso, contexts, AMPLITUDE, seed=1)
    selection, final = _fit(denso, problem, (PAYLOAD,))
    identified = _identified(denso, contexts, AMPLITUDE)  # the law is there whichever rigid body is used
    _, _, unnamed, notes = look_beyond_library(problem, selection, final, OPTIONS, identified)
    assert [(f.effect, f.joints) for f in unnamed] == [("unnamed_effect", (1,))] and notes == ()


def test_without_an_inertial_finding_the_unnamed_term_is_not_judged(denso, contexts):
    problem = _problem(denso, contexts, AMPLITUDE, seed=1)
    selection, final = _fit(denso, problem, ((SpringTerm(joint=0), (0,)),))  # the prior's inertia not in question
    _, _, unnamed, notes = look_beyond_library(problem, selection, final, OPTIONS, _identified(denso, contexts, 0.0))
    assert [(f.effect, f.joints) for f in unnamed] == [("unnamed_effect", (1,))] and notes == ()
