"""Confounding said aloud: how much of an effect's torque the nominal model's own parameters would absorb.

An effect whose torque lies in the span of the nominal model's free columns (friction, and the base parameters
when the rigid body is identified) cannot be told apart from a change of those parameters on the recordings: a
tilted base moves the gravity parameters, a payload the last links' mass and first moments, a drive inertia the
joint's ``Im``. ``assess_confounding`` projects, on the training recording with the selection's joint weights,

- each kept finding's fitted torque (``columns @ coefficients``), and
- every library candidate that was not kept (all its columns together, and each column),

onto the nominal columns (``WeightedDesign.project``) and returns a ``Confound`` for each whose absorbed fraction
reaches ``threshold``: the fraction and the nominal parameters that absorb most of it (their share of the
absorbed part, each parameter's change squared times its column's weighted norm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.diagnosis.candidates.library import default_library
from identification.diagnosis.design import WeightedDesign, joint_weights
from identification.diagnosis.nominal import friction_feature_names

CONFOUND_THRESHOLD = 0.5  # absorbed fraction from which an effect is reported as confounded
TOP_PARAMETERS = 4  # parameters named per confounded effect


@dataclass(frozen=True)
class Confound:
    """One effect the nominal parameters absorb: ``fraction`` of its torque, mostly through ``absorbed_by``.

    Attributes
    ----------
    label : str
        The candidate's label (``payload``, ``rotor_inertia[j3]``).
    effect : str
    fraction : float
        Share (0..1) of the effect's weighted squared torque in the span of the nominal columns (for a candidate
        that was not kept, of all its columns together).
    absorbed_by : tuple of (str, float)
        Nominal parameters and their share of the absorbed part, largest first.
    kept : bool
        Whether the effect is a kept finding (its fitted torque was projected) or a candidate (its columns).
    columns : tuple of (str, float)
        For a candidate, the absorbed fraction of each of its columns (feature name, fraction).
    """

    label: str
    effect: str
    fraction: float
    absorbed_by: tuple
    kept: bool
    columns: tuple = ()

    def parameters_text(self) -> str:
        """The absorbing parameters with their shares (those of at least 5 %, at least one)."""
        shown = [item for k, item in enumerate(self.absorbed_by) if k == 0 or item[1] >= 0.05]
        return ", ".join(f"`{name}` {share:.0%}" for name, share in shown)

    def sentence(self) -> str:
        if self.kept:
            return (
                f"`{self.label}` (kept): {self.fraction:.0%} of its fitted torque could also be produced by the "
                f"nominal parameters ({self.parameters_text()}); only the rest tells it apart on these recordings"
            )
        absorbed = [f"`{name}` {fraction:.0%}" for name, fraction in self.columns if fraction >= CONFOUND_THRESHOLD]
        detail = f" (columns {', '.join(absorbed)})" if len(self.columns) > 1 else ""
        return (
            f"`{self.label}`: {self.fraction:.0%} of its torque lies in the span of the nominal parameters{detail}, "
            f"taken mostly by {self.parameters_text()}; on these recordings such an effect is absorbed by them (a "
            "change of those parameters) rather than reported as missing physics"
        )

    def to_dict(self) -> dict:
        return {
            "label": self.label,
            "effect": self.effect,
            "fraction": self.fraction,
            "absorbed_by": [{"parameter": name, "share": share} for name, share in self.absorbed_by],
            "kept": self.kept,
            "columns": [{"feature": name, "fraction": fraction} for name, fraction in self.columns],
        }


def nominal_parameter_names(robot, model, friction: str, rigid_body: str) -> list:
    """Names of the nominal model's free columns in the order of the fit (friction, LuGre bristle dynamics with a
    LuGre prior, base parameters when identified)."""
    n = robot.n_dof
    names = list(friction_feature_names(friction, n))
    if friction == "lugre" and robot.drives is not None:
        names += [f"lugre_dynamics_{j + 1}" for j in range(n)]
    if rigid_body == "identified":
        names += list(model.base_names)
    return names


def _shares(design: WeightedDesign, change, names) -> tuple:
    """The nominal parameters that absorb most, with their share of the absorbed part."""
    change = np.asarray(change, dtype=float).reshape(design.G.shape[0], -1)
    energy = np.sum(change**2, axis=1) * np.diag(design.G)
    total = float(np.sum(energy))
    if total <= 0.0:
        return ()
    order = np.argsort(-energy)[:TOP_PARAMETERS]
    return tuple((names[i] if i < len(names) else f"column {i}", float(energy[i] / total)) for i in order)


def _candidate_confound(design: WeightedDesign, term, columns, names, threshold: float):
    """The ``Confound`` of a candidate that was not kept, or None: reported when its columns together reach
    ``threshold``, or, for a robot-wide term (payload, tilt), when one of its columns is almost fully absorbed."""
    if not np.any(columns):
        return None
    fraction, _ = design.project(columns)
    per_column = [design.project(columns[:, :, c : c + 1]) for c in range(columns.shape[2])]
    absorbed = [c for c, (f, _) in enumerate(per_column) if f >= threshold]
    if not absorbed or (fraction < threshold and (term.joints or max(f for f, _ in per_column) < 0.9)):
        return None
    change = np.column_stack([per_column[c][1] for c in absorbed])
    features = term.feature_names()
    return Confound(
        term.label,
        term.key,
        fraction,
        _shares(design, change, names),
        False,
        tuple((features[c], float(f)) for c, (f, _) in enumerate(per_column)),
    )


def assess_confounding(
    instances, kept_terms, coefficients, ctx_t, base_t, y_t, sigma, names, threshold=CONFOUND_THRESHOLD
) -> tuple:
    """The kept findings and the candidates not kept whose torque the nominal parameters absorb (``Confound`` each).

    Parameters
    ----------
    instances : sequence of CandidateTerm
        The library's instances that were screened.
    kept_terms, coefficients : sequences
        The kept terms and their fitted coefficients (None for a term whose torque is not ``columns @
        coefficients``: it is then not projected).
    ctx_t : DiagnosisContext
        The training recording.
    base_t : BlockColumns
        The nominal model's free columns on it.
    y_t : array (n_samples, n_dof)
    sigma : array (n_dof,)
        Joint weights (the selection's).
    names : sequence of str
        Names of the nominal columns (``nominal_parameter_names``).
    threshold : float
        Least absorbed fraction reported.

    Returns
    -------
    tuple of Confound
        Kept findings first, then candidates, each group by decreasing fraction.
    """
    design = WeightedDesign(base_t, base_t, y_t, y_t, np.asarray(sigma, dtype=float))
    kept_labels = {term.label for term in kept_terms}  # a kept term is judged by its fitted torque, not its columns
    found, candidates = [], []
    for term, c in zip(kept_terms, coefficients):
        if c is None:
            continue
        fraction, change = design.project(term.columns(ctx_t), c)
        if fraction >= threshold:
            found.append(Confound(term.label, term.key, fraction, _shares(design, change, names), True))
    for term in instances:
        if term.label in kept_labels or term.key in {t.key for t in kept_terms if not t.joints}:
            continue
        confound = _candidate_confound(design, term, term.columns(ctx_t), names, threshold)
        if confound is not None:
            candidates.append(confound)
    found.sort(key=lambda x: -x.fraction)
    candidates.sort(key=lambda x: -x.fraction)
    return tuple(found) + tuple(candidates)


def confounding_of(robot, model, problem, final, n_kept: int, options) -> tuple:
    """``assess_confounding`` of a diagnosis: the library's instances (``options.library``), the first ``n_kept``
    terms of ``final`` (a ``FinalFit``: the selection's terms, refined) and the nominal columns of ``problem`` (a
    ``DiagnosisProblem``) on its training recording, with the selection's joint weights."""
    ctx_t, base_t = problem.ctx_t, problem.base_t
    names = nominal_parameter_names(robot, model, options.friction, "prior")
    if base_t.n_columns != len(names):
        names = nominal_parameter_names(robot, model, options.friction, "identified")
    library = options.library if options.library is not None else default_library()
    # terms with nonlinear parameters (delay, backlash, elasticity, drift) hold those, not column coefficients
    terms = final.terms[:n_kept]
    coefficients = [None if t.label in final.nonlinear else c for t, c in zip(terms, final.coefficients)]
    return assess_confounding(
        library.expand(robot.n_dof),
        terms,
        coefficients,
        ctx_t,
        base_t,
        problem.y_t,
        joint_weights(ctx_t.tau),
        names,
    )
