"""The paper's calibration: four identification steps, a joint refinement, a consistency check.

``estimator`` (the least-squares estimator base), ``inputs`` (checks shared by the steps),
``steps`` (torque constants, gravity, inertial), ``friction_step`` (the LuGre step on the friction
experiments), ``payload`` (the calibration mass's torques), ``refinement`` (all parameters
together with Ipopt), ``consistency`` (positive-definite mass matrix), ``pipeline`` (the steps in
order), ``report`` (the validation table, the paper's Table 3) and ``result``
(:class:`IdentifiedModel` and its files).
"""
