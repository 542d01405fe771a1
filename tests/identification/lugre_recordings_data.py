"""Virtual recordings with LuGre friction of known truth for the recordings route (``--friction lugre``).

The Denso's rigid body and rotor inertias with LuGre friction per joint whose pre-sliding is slow enough to
be seen in a 500 Hz recording filtered at 50 Hz: break-away displacements ``fc / sigma0`` of 2 mrad (the
Denso's own sigma0 of about 3e5 N m/rad puts them at 3e-5 rad, which no filtered exciting trajectory sees).
The virtual robot integrates the LuGre state exactly (``identification.virtual.lugre_exact``) at two
sub-steps per sample, independently of the identification's exponential integrator.

``exported_c_rmse`` evaluates a LuGre model's exported C along a recording as a user's controller would.
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


def lugre_recording(robot, seed: int, duration: float, extras=()):
    """A recording of joint torques (noise ``NOISE``) of the LuGre robot along a seeded sine excitation, with the
    hidden physics ``extras`` (``identification.virtual.effects``)."""
    rng = np.random.default_rng(seed)
    reference = sine_experiment(robot, duration=duration, rng=rng).reference()
    options = SimulationOptions(rate=RATE, record_tau=True, record_current=False, tau_noise_std=NOISE)
    recording, _ = simulate_recording(lugre_robot(robot), reference, options, rng, extras=extras)
    return dataclasses.replace(recording, name=f"lugre{seed}")


def write_lugre_recordings(robot, folder, train_s: float = 12.0, valid_s: float = 8.0, extras=()):
    """(training CSV, validation CSV) in ``folder``."""
    paths = []
    for seed, duration, name in ((1, train_s, "train.csv"), (2, valid_s, "valid.csv")):
        paths.append(save_recording(lugre_recording(robot, seed, duration, extras), folder / name))
    return tuple(paths)


def exported_c_rmse(model_path, recording_path, out) -> tuple:
    """(per-joint RMSE [N m], LuGre header text) of ``psdm codegen MODEL --compile``'s C along a raw recording.

    C only: ``psdm_lugre_step`` carried from a relaxed bristle at the raw start along the velocity of the positions
    filtered as the identification filters them, plus ``psdm_inverse_dynamics`` (rigid body, drive terms and the
    torque findings), at the samples ``psdm validate`` keeps.
    """
    import casadi as ca

    from identification.calibration.calibrated_model import load_calibrated_model
    from identification.calibration.trajectory_data import choose_filter, prepare_recording
    from identification.data.io import load_recording
    from identification.data.preprocessing import central_difference, zero_phase_filter
    from psdm_casadi.cli import main

    if main(["codegen", str(model_path), "--out", str(out), "--compile"]) != 0:
        raise RuntimeError(f"psdm codegen {model_path} failed")
    library = str(out / "libpsdm_dynamics.so")
    inverse, step = (ca.external(name, library) for name in ("psdm_inverse_dynamics", "psdm_lugre_step"))
    calibrated = load_calibrated_model(model_path)
    recording = load_recording(recording_path, calibrated.n_dof)
    cutoff = calibrated.document["identification"]["cutoff_hz"][0]
    prepared, _, _ = prepare_recording(recording, None, cutoff)
    rate = 1.0 / recording.dt
    qd, _ = central_difference(recording.t, zero_phase_filter(recording.q, rate, choose_filter(rate, cutoff)[0]))
    s, friction = np.zeros(calibrated.n_dof), [np.zeros(calibrated.n_dof)]
    for k in range(1, recording.n_samples):
        s_next, tau = step(s, qd[k - 1], qd[k], recording.t[k] - recording.t[k - 1])
        s, _ = np.array(s_next).ravel(), friction.append(np.array(tau).ravel())
    keep = np.searchsorted(recording.t, prepared.t)
    np.testing.assert_array_equal(recording.t[keep], prepared.t)
    rigid = np.array(inverse.map(prepared.n_samples)(prepared.q.T, prepared.qd.T, prepared.qdd.T)).T
    tau_c = rigid + np.array(friction)[keep]
    return np.sqrt(np.mean((prepared.tau - tau_c) ** 2, axis=0)), (out / "psdm_dynamics_lugre.h").read_text()
