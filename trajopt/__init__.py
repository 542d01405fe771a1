"""trajopt: excitation trajectory design (paper eqs. 22-23) with CasADi and Ipopt, and the calibration experiments.

Flow: ``DynamicsFunctions.regressor`` -> ``optimize_excitation`` -> ``ExcitationTrajectory`` (sample,
to_csv). The paper's other calibration experiments have one designer, here: ``motor_experiment``,
``gravity_experiment``, ``friction_experiment`` (shaped by a ``FrictionDesign``),
``oscillation_experiment`` and ``sine_experiment`` give ``ExperimentTrajectory`` values, the motions a
user records and the virtual robot tracks; ``CalibrationPlan`` gathers one whole calibration.
"""

from trajopt.calibration_plan import CalibrationPlan
from trajopt.constraints import JointLimits, KeepOut, build_dh_point_function, limit_margins, verify_limits
from trajopt.criteria import condition_number, stack_regressor
from trajopt.excitation import ExcitationOptions, ExcitationTrajectory
from trajopt.experiment_trajectory import ExperimentTrajectory
from trajopt.experiments import (
    choose_motor_pose,
    friction_experiment,
    gravity_experiment,
    motor_experiment,
    oscillation_experiment,
    sine_experiment,
)
from trajopt.friction_design import FrictionDesign
from trajopt.optimize import optimize_excitation, random_feasible_parameters
from trajopt.parametrization import FourierTrajectory, SumOfSinesTrajectory
from trajopt.plot import plot_trajectory
from trajopt.problem import ExcitationProblem, build_excitation_problem

__all__ = [
    "CalibrationPlan",
    "ExcitationOptions",
    "ExcitationProblem",
    "ExcitationTrajectory",
    "ExperimentTrajectory",
    "FourierTrajectory",
    "FrictionDesign",
    "JointLimits",
    "KeepOut",
    "SumOfSinesTrajectory",
    "build_dh_point_function",
    "build_excitation_problem",
    "choose_motor_pose",
    "condition_number",
    "friction_experiment",
    "gravity_experiment",
    "limit_margins",
    "motor_experiment",
    "optimize_excitation",
    "oscillation_experiment",
    "plot_trajectory",
    "random_feasible_parameters",
    "sine_experiment",
    "stack_regressor",
    "verify_limits",
]
