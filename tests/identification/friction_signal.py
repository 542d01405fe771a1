"""Friction-experiment signals and synthetic LuGre data for the friction tests (known truth)."""

from pathlib import Path

import numpy as np

from identification.experiments import tuned_friction_signal
from identification.friction import LuGreParameters, simulate_lugre
from psdm_casadi.robot import load_robot

DENSO = Path(__file__).resolve().parents[2] / "robots" / "denso_vs6556g.toml"


def denso_truth(joint):
    """Paper Table 2 LuGre parameters of Denso joint ``joint`` (0-based) and its speed limit."""
    robot = load_robot(DENSO)
    return LuGreParameters.from_drive(robot.drives[joint]), float(robot.qd_max[joint])


def sine_series(parameters, qd_max, rate=1000.0, frequency_scale=1.0, pause=0.2):
    """``t, qd`` of the tuned friction experiment (pre-sliding, Stribeck and sliding segments)."""
    t, _, qd = tuned_friction_signal(parameters, qd_max, rate=rate, frequency_scale=frequency_scale, pause=pause)
    return t, qd


def synthetic_record(joint, rng=None, noise=0.0, frequency_scale=2.0, substeps=32):
    """``(truth, t, qd, tau)`` with tau from a fine-step LuGre simulation plus ``noise * fc`` white noise."""
    truth, qd_max = denso_truth(joint)
    t, qd = sine_series(truth, qd_max, frequency_scale=frequency_scale)
    tau, _ = simulate_lugre(truth, t, qd, substeps=substeps)
    if noise:
        tau = tau + noise * truth.fc * rng.standard_normal(t.size)
    return truth, t, qd, tau
