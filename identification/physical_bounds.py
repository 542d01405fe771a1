"""The physical bounds a fitted effect must stay inside to be one: shared by identify and the diagnosis.

Identify's column choice keeps a gear-loss column (``calibration.column_choice``), the consistent fit bounds a
finding's coefficient (``calibration.findings``, ``FindingTerm.lower_bounds``), the refit of a finding is judged
(``calibration.finding_value``), a payload's reach is checked (``calibration.payload_route``), and the diagnosis's
candidate terms refuse a fitted parameter (``diagnosis.candidates.base``, ``CandidateTerm.implausibility``) against
the same numbers; they live here, below both stages, so that neither imports the other for them.
"""

from __future__ import annotations

MAX_LOAD_FRICTION = 0.4  # load-dependent friction coefficient mu (gear tooth friction: efficiency above 60 %)
MAX_TORQUE_SHARE = 1.0  # a term's torque on its joint at most this times the joint's ``torque_bound``
MAX_DELAY_S = 0.1  # torque-to-position delay [s]
MAX_BACKLASH_RAD = 0.05  # total play [rad] (about 3 degrees)
MAX_DEFLECTION_RAD = 0.05  # joint torsion at the peak torque [rad]
MAX_PAYLOAD_REACH = 0.5  # distance of a payload's centre of mass from the flange [m]
MAX_TILT_DEG = 10.0  # tilt of the robot's base off level [deg]
# shortest time constant [s] of a friction drift: gears, lubricant and motors warm up over minutes (thermal time
# constants of 5-30 min); a change within seconds is a start-up transient of the recording, not a drift
MIN_DRIFT_TIME_CONSTANT_S = 30.0
# the friction shapes (``FrictionShapeTerm.shape``, a ``friction_shape`` finding's) whose coefficient is > 0: a
# Stribeck peak above the Coulomb level (not a dip), a smooth Coulomb friction above zero (not one falling with speed)
POSITIVE_FRICTION_SHAPES = ("stribeck", "smooth_coulomb")
