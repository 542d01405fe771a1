"""The default candidate library: every term, in the order that breaks ties in the selection, and the effects
the data cannot tell apart."""

from __future__ import annotations

from identification.diagnosis.candidates.base import CandidateLibrary
from identification.diagnosis.candidates.counterbalance import CounterbalanceTerm
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
from identification.diagnosis.candidates.torque import SpringTerm, TorqueOffsetTerm, TorqueRippleTerm

ALL_TERMS = (
    TorqueOffsetTerm,
    SpringTerm,
    CoulombAsymmetryTerm,
    LoadDependentFrictionTerm,
    FrictionDriftTerm,
    TorqueRippleTerm,
    RotorInertiaTerm,
    CouplingTerm,
    PayloadTerm,
    GravityTiltTerm,
    DelayTerm,
    BacklashTerm,
    JointElasticityTerm,
)
# every term a spec may name: the library's, the shapes a term offers as variants (a spring's gas-spring law), the
# friction shapes ``friction_rival`` offers and the counterbalance a model file writes as one finding
TERMS_BY_KEY = {cls.key: cls for cls in ALL_TERMS + (GasSpringTerm, FrictionShapeTerm, PreslidingTerm,
                                                     CounterbalanceTerm)}  # fmt: skip


def default_library() -> CandidateLibrary:
    """Every candidate term, simplest first (ties in the selection go to the earlier term)."""
    return CandidateLibrary(tuple(cls() for cls in ALL_TERMS))


# Effects that the data cannot tell apart under the nominal model (documented in the report):
# with a symmetric Coulomb term in the nominal friction, an asymmetric Coulomb level is a constant
# offset during motion.
EQUIVALENT_EFFECTS = {"coulomb_asymmetry": ("torque_offset",), "torque_offset": ("coulomb_asymmetry",)}
