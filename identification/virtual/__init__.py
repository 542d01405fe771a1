"""The virtual robot: recordings simulated with known truth, for tests, benchmarks and the demo.

``simulation`` (Pinocchio rigid body, LuGre friction, drives, controller, sensor noise),
``lugre_exact`` (the exact LuGre step it integrates with), ``truth`` (the true parameters of a run,
written beside its recording), ``effects`` and ``transmission_effects`` (hidden physics to conceal
in a recording), ``current_arm`` (an arm logging motor currents, its user's robot file with torque constants
off, for the torque-scale check) and ``calibration`` (the paper's four experiments simulated into a calibration data
set, along reference motions it is given: their designer is ``trajopt``). Estimators never import
this package.
"""
