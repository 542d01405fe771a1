"""Friction-experiment signals and synthetic LuGre data for the friction tests (known truth)."""

from pathlib import Path

import numpy as np

from identification.friction import LuGreParameters, simulate_lugre
from psdm_casadi.robot import load_robot

DENSO = Path(__file__).resolve().parents[2] / "robots" / "denso_vs6556g.toml"


def denso_truth(joint):
    """Paper Table 2 LuGre parameters of Denso joint ``joint`` (0-based) and its speed limit."""
    robot = load_robot(DENSO)
    return LuGreParameters.from_drive(robot.drives[joint]), float(robot.qd_max[joint])


def sine_series(parameters, qd_max, rate=1000.0, frequency_scale=1.0, pause=0.2):
    """Pre-sliding, Stribeck and sliding ``A (1 - cos)`` segments (as benchmarks/identification_friction.py)."""
    xb = parameters.fc / parameters.sigma0
    segments = [(k * xb, 10.0 * frequency_scale, 4) for k in (0.3, 0.7, 1.5, 3.0)]
    segments += [(v * parameters.vs / (2 * np.pi * frequency_scale), frequency_scale, 2) for v in (0.5, 1, 2, 4)]
    f_slide = 0.5 * frequency_scale
    segments += [(v * qd_max / (2 * np.pi * f_slide), f_slide, 1) for v in (0.1, 0.3, 0.6, 0.9)]
    starts, total = [], 0.0
    for _, frequency, periods in segments:
        starts.append(total)
        total += periods / frequency + pause
    t = np.arange(0.0, total, 1.0 / rate)
    qd = np.zeros_like(t)
    for start, (amplitude, frequency, periods) in zip(starts, segments):
        omega = 2 * np.pi * frequency
        m = (t >= start) & (t <= start + periods / frequency)
        qd[m] = amplitude * omega * np.sin(omega * (t[m] - start))
    return t, qd


def synthetic_record(joint, rng=None, noise=0.0, frequency_scale=2.0, substeps=32):
    """``(truth, t, qd, tau)`` with tau from a fine-step LuGre simulation plus ``noise * fc`` white noise."""
    truth, qd_max = denso_truth(joint)
    t, qd = sine_series(truth, qd_max, frequency_scale=frequency_scale)
    tau, _ = simulate_lugre(truth, t, qd, substeps=substeps)
    if noise:
        tau = tau + noise * truth.fc * rng.standard_normal(t.size)
    return truth, t, qd, tau
