"""Candidate physics terms: what a nominal model may have left out, as columns, CasADi expressions and words.

Terms compose as a library (``SpringTerm() + TorqueOffsetTerm()`` gives a ``CandidateLibrary``), like the
feature libraries of pysindy; one module per family of effects:

- ``base``: ``CandidateTerm`` (the interface), ``CandidateLibrary`` and the smooth-sign width; the plausibility
  bounds ``MAX_*`` of fitted parameters are ``identification.physical_bounds``' (shared with identify), named here too;
- ``torque``: spring, torque offset, torque ripple (torques of position);
- ``gas_spring``: the gas-spring lever law, a spring shape offered beside the polynomial ones;
- ``counterbalance``: a counterbalance as one term (a constant and a low harmonic of the angle), not offered: the shape
  a model file writes for the balancer it held as a torque offset (``calibration.counterbalance_finding``);
- ``neutral_angle``: where a counterbalance's odd law is centred (the spring's odd shape, fitted by variable
  projection; ``counterbalance_law`` in ``torque`` chooses its order for identify);
- ``friction``: Coulomb asymmetry, load-dependent friction, friction drift, the friction shapes a Coulomb-viscous
  model lacks (Stribeck, smooth Coulomb, pre-sliding; friction-like columns);
- ``inertial``: rotor inertia, joint coupling, payload, gravity tilt (rigid-body and mounting effects);
- ``delay``: a delay between the torque and the motion signals;
- ``deflection``: backlash and joint elasticity (a transmission that is not rigid);
- ``library``: ``ALL_TERMS``, ``TERMS_BY_KEY``, ``EQUIVALENT_EFFECTS`` and ``default_library``.
"""

from identification.diagnosis.candidates.base import (
    SMOOTH_VELOCITY,
    CandidateLibrary,
    CandidateTerm,
    joint_columns,
    joint_expression,
)
from identification.diagnosis.candidates.deflection import BacklashTerm, JointElasticityTerm
from identification.diagnosis.candidates.delay import DelayTerm
from identification.diagnosis.candidates.friction import (
    CoulombAsymmetryTerm,
    FrictionDriftTerm,
    FrictionShapeTerm,
    LoadDependentFrictionTerm,
    PreslidingTerm,
)
from identification.diagnosis.candidates.gas_spring import GasSpringTerm
from identification.diagnosis.candidates.inertial import CouplingTerm, GravityTiltTerm, PayloadTerm, RotorInertiaTerm
from identification.diagnosis.candidates.library import ALL_TERMS, EQUIVALENT_EFFECTS, TERMS_BY_KEY, default_library
from identification.diagnosis.candidates.torque import (
    SpringTerm,
    TorqueOffsetTerm,
    TorqueRippleTerm,
    counterbalance_law,
)
from identification.physical_bounds import (
    MAX_BACKLASH_RAD,
    MAX_DEFLECTION_RAD,
    MAX_DELAY_S,
    MAX_LOAD_FRICTION,
    MAX_PAYLOAD_REACH,
    MIN_DRIFT_TIME_CONSTANT_S,
)

__all__ = [
    "MAX_BACKLASH_RAD",
    "MAX_DEFLECTION_RAD",
    "MAX_DELAY_S",
    "MAX_LOAD_FRICTION",
    "MAX_PAYLOAD_REACH",
    "MIN_DRIFT_TIME_CONSTANT_S",
    "SMOOTH_VELOCITY",
    "CandidateLibrary",
    "CandidateTerm",
    "joint_columns",
    "joint_expression",
    "BacklashTerm",
    "JointElasticityTerm",
    "DelayTerm",
    "CoulombAsymmetryTerm",
    "FrictionDriftTerm",
    "FrictionShapeTerm",
    "PreslidingTerm",
    "LoadDependentFrictionTerm",
    "GasSpringTerm",
    "CouplingTerm",
    "GravityTiltTerm",
    "PayloadTerm",
    "RotorInertiaTerm",
    "ALL_TERMS",
    "EQUIVALENT_EFFECTS",
    "TERMS_BY_KEY",
    "default_library",
    "SpringTerm",
    "TorqueOffsetTerm",
    "TorqueRippleTerm",
    "counterbalance_law",
]
