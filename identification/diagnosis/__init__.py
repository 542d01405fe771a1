"""Missing-physics diagnosis: locate where a model misses the recordings, name the effect, add it, show the fit improve.

Recording(s) + RobotDescription -> ``diagnose`` -> DiagnosisReport (findings, validation RMSE before/after,
residual analysis, augmented model). Modules, in the order ``diagnose`` uses them: ``context`` (nominal
signals per recording), ``nominal`` (friction and rigid-body choices), ``columns`` (the fit's columns
stored per joint, used in chunks of rows), ``candidates/`` (the physics library, one module per family of
effects, with plausibility bounds), ``design`` (the weighted least squares), ``selection`` (forward selection
on held-out data, spring shapes by BIC, a backward check), ``signal_fit``
(exact fit of the kept delay, backlash and joint elasticity by variable projection), ``refine`` (Ipopt fit
of the nonlinear parameters of the kept terms), ``residual_tests``, ``joint_changes`` (why a joint fits worse),
``confounding`` (what the nominal parameters absorb), ``report``, ``augmented``; ``diagnose``
runs the steps. Progress is logged (loggers under
``identification.diagnosis``). The command is ``psdm diagnose`` (``psdm_casadi.cli.diagnose``).
"""

from identification.diagnosis.augmented import AugmentedModel
from identification.diagnosis.candidates import (
    ALL_TERMS,
    EQUIVALENT_EFFECTS,
    TERMS_BY_KEY,
    BacklashTerm,
    CandidateLibrary,
    CandidateTerm,
    CoulombAsymmetryTerm,
    CouplingTerm,
    DelayTerm,
    FrictionDriftTerm,
    GravityTiltTerm,
    JointElasticityTerm,
    LoadDependentFrictionTerm,
    PayloadTerm,
    RotorInertiaTerm,
    SpringTerm,
    TorqueOffsetTerm,
    TorqueRippleTerm,
    default_library,
)
from identification.diagnosis.diagnose import DiagnosisOptions, diagnose
from identification.diagnosis.report import NO_FINDING, DiagnosisReport, Finding

__all__ = [
    "AugmentedModel",
    "ALL_TERMS",
    "EQUIVALENT_EFFECTS",
    "TERMS_BY_KEY",
    "BacklashTerm",
    "CandidateLibrary",
    "CandidateTerm",
    "CouplingTerm",
    "CoulombAsymmetryTerm",
    "DelayTerm",
    "FrictionDriftTerm",
    "GravityTiltTerm",
    "JointElasticityTerm",
    "LoadDependentFrictionTerm",
    "PayloadTerm",
    "RotorInertiaTerm",
    "SpringTerm",
    "TorqueOffsetTerm",
    "TorqueRippleTerm",
    "default_library",
    "DiagnosisOptions",
    "diagnose",
    "NO_FINDING",
    "DiagnosisReport",
    "Finding",
]
