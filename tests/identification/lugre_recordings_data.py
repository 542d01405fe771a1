"""Virtual recordings with LuGre friction of known truth for the recordings route (``--friction lugre``).

The Denso's rigid body and rotor inertias with LuGre friction per joint whose pre-sliding is slow enough to
be seen in a 500 Hz recording filtered at 50 Hz: break-away displacements ``fc / sigma0`` of 2 mrad (the
Denso's own sigma0 of about 3e5 N m/rad puts them at 3e-5 rad, which no filtered exciting trajectory sees).
The virtual robot integrates the LuGre state exactly (``identification.virtual.lugre_exact``) at two
sub-steps per sample, independently of the identification's exponential integrator.
"""

import dataclasses

import numpy as np

from identification.data.io import save_recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from trajopt.experiments import sine_experiment

RATE, CUTOFF, NOISE = 500.0, 50.0, 0.05
FC = np.array([2.0, 2.5, 1.5, 0.6, 0.5, 0.3])
FS = 1.8 * FC
VS = np.array([0.1, 0.15, 0.08, 0.2, 0.12, 0.1])
FV = np.array([1.0, 1.5, 0.8, 0.3, 0.2, 0.1])
SIGMA0 = FC / 2e-3
SIGMA1 = np.array([20.0, 25.0, 15.0, 6.0, 5.0, 3.0])
TRUTH = {"fc": FC, "fs": FS, "vs": VS, "fv": FV, "sigma0": SIGMA0, "sigma1": SIGMA1}


def lugre_robot(robot):
    """``robot`` with the LuGre truth of this module in its drives (dv = 1: linear viscous friction)."""
    drives = tuple(
        dataclasses.replace(d, fc=FC[j], fs=FS[j], vs=VS[j], fv=FV[j], dv=1.0, sigma0=SIGMA0[j], sigma1=SIGMA1[j])
        for j, d in enumerate(robot.drives)
    )
    return dataclasses.replace(robot, drives=drives)


def lugre_recording(robot, seed: int, duration: float):
    """A recording of joint torques (noise ``NOISE``) of the LuGre robot along a seeded sine excitation."""
    rng = np.random.default_rng(seed)
    reference = sine_experiment(robot, duration=duration, rng=rng).reference()
    options = SimulationOptions(rate=RATE, record_tau=True, record_current=False, tau_noise_std=NOISE)
    recording, _ = simulate_recording(lugre_robot(robot), reference, options, rng)
    return dataclasses.replace(recording, name=f"lugre{seed}")


def write_lugre_recordings(robot, folder, train_s: float = 12.0, valid_s: float = 8.0):
    """(training CSV, validation CSV) in ``folder``."""
    paths = []
    for seed, duration, name in ((1, train_s, "train.csv"), (2, valid_s, "valid.csv")):
        paths.append(save_recording(lugre_recording(robot, seed, duration), folder / name))
    return tuple(paths)
