"""trajopt: excitation trajectory design (paper eqs. 22-23) with CasADi and Ipopt, and calibration experiments.

Flow: ``DynamicsFunctions.regressor`` -> ``optimize_excitation`` -> ``ExcitationTrajectory`` (sample,
to_csv), plus ``motor_experiment``, ``gravity_experiment``, ``friction_experiment``.
"""

from trajopt.constraints import JointLimits, KeepOut, build_dh_point_function, limit_margins, verify_limits
from trajopt.criteria import condition_number, stack_regressor
from trajopt.experiments import ExperimentTrajectory, friction_experiment, gravity_experiment, motor_experiment
from trajopt.optimize import ExcitationOptions, ExcitationTrajectory, optimize_excitation, random_feasible_parameters
from trajopt.parametrization import FourierTrajectory, SumOfSinesTrajectory
from trajopt.plot import plot_trajectory
from trajopt.problem import ExcitationProblem, build_excitation_problem

__all__ = [
    "ExcitationOptions", "ExcitationProblem", "ExcitationTrajectory", "ExperimentTrajectory", "FourierTrajectory",
    "JointLimits", "KeepOut", "SumOfSinesTrajectory", "build_dh_point_function", "build_excitation_problem",
    "condition_number", "friction_experiment", "gravity_experiment", "limit_margins", "motor_experiment",
    "optimize_excitation", "plot_trajectory", "random_feasible_parameters", "stack_regressor", "verify_limits",
]
