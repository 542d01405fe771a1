"""The virtual robot: recordings simulated with known truth, for tests, benchmarks and the demo.

``simulation`` (Pinocchio rigid body, LuGre friction, drives, controller, sensor noise),
``lugre_exact`` (the exact LuGre step it integrates with), ``effects`` and
``transmission_effects`` (hidden physics to conceal in a recording), ``experiments`` (reference
motions of the calibration experiments) and ``calibration`` (the four experiments simulated into
a calibration data set). Estimators never import this package.
"""
