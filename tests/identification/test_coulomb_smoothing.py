"""The Coulomb column's smoothing velocity, chosen from the recordings' reversals (``coulomb_smoothing``).

The reference is the measured torque itself: a Coulomb friction ``fc sign(qd)`` recorded and prepared as the fit
prepares it (filtered at the cutoff, differentiated, trimmed, decimated). The chosen ``tanh(qd / v)`` must follow
that filtered step; 0.05 rad/s stays for motions that reverse fast enough.
"""

import numpy as np
import pytest

from identification.calibration.coulomb_smoothing import (
    MIN_VELOCITY,
    SmoothingChoice,
    smoothing_velocity,
    with_smoothing,
)
from identification.calibration.trajectory_data import prepare_recording
from identification.calibration.trajectory_fit import TrajectoryOptions
from identification.data.recording import Recording


def coulomb_recording(amplitude: float, frequency: float, duration: float = 20.0) -> Recording:
    """Two joints moving ``amplitude sin(2 pi f t)`` (the second a third faster), recording only their Coulomb
    friction of 1 N m at 1 kHz."""
    t = np.arange(0.0, duration, 1e-3)
    w = 2.0 * np.pi * frequency * np.array([1.0, 1.3])
    q = amplitude * np.sin(np.outer(t, w))
    qd = amplitude * w * np.cos(np.outer(t, w))
    return Recording(t=t, q=q, tau=np.sign(qd))


@pytest.mark.parametrize("amplitude, frequency, slow", [(0.2, 0.1, True), (1.0, 0.4, False)])
def test_the_smooth_sign_follows_the_filtered_friction_step(amplitude, frequency, slow):
    ready, cutoff, _ = prepare_recording(coulomb_recording(amplitude, frequency), None, None)
    choice = smoothing_velocity([ready], cutoff, 0.05)
    peak = amplitude * (2.0 * np.pi * frequency) ** 2 * np.array([1.0, 1.3**2])  # |qdd| at a reversal
    wanted = 0.2 * float(np.median(peak)) / cutoff
    expected = 0.05 if wanted >= 0.025 else max(wanted, MIN_VELOCITY)
    assert choice.changed is slow
    np.testing.assert_allclose(choice.velocity, expected, rtol=0.05)
    error = {v: np.sqrt(np.mean((ready.tau - np.tanh(ready.qd / v)) ** 2)) for v in (choice.velocity, 0.05)}
    if slow:  # 0.05 rad/s is far from the sign on this motion; the chosen value follows the filtered step
        assert error[choice.velocity] < 0.3 * error[0.05] and error[choice.velocity] < 0.05
        assert "chosen from the data" in choice.sentence() and f"{choice.velocity:.3g}" in choice.sentence()
    else:
        assert "0.05 rad/s" in choice.sentence()


def test_a_still_recording_keeps_the_default_and_the_floor_holds():
    t = np.arange(0.0, 5.0, 1e-3)
    still = Recording(t=t, q=np.ones((t.size, 2)), tau=np.zeros((t.size, 2)))
    ready, cutoff, _ = prepare_recording(still, None, None)
    kept = smoothing_velocity([ready], cutoff, 0.05)  # no reversal: nothing to go by
    assert isinstance(kept, SmoothingChoice) and kept.velocity == 0.05 and not kept.changed
    creeping, cutoff, _ = prepare_recording(coulomb_recording(1e-3, 0.1), None, None)
    assert smoothing_velocity([creeping], cutoff, 0.05).velocity == MIN_VELOCITY


def test_with_smoothing_prepares_as_the_fit_and_keeps_the_other_options(denso):
    """On the virtual Denso's exciting trajectory the joints reverse fast: 0.05 rad/s and every option kept;
    a recording of another robot is refused as the fit refuses it."""
    from identification.virtual.simulation import SimulationOptions, simulate_recording
    from psdm_casadi.errors import ShapeError
    from trajopt.experiments import sine_experiment

    rng = np.random.default_rng(5)
    reference = sine_experiment(denso, duration=4.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
    recording, _ = simulate_recording(denso, reference, options, rng)
    given = TrajectoryOptions(cutoff_hz=8.0, mass_ratio=(0.8, 1.25))
    chosen, choice = with_smoothing(denso, [recording], given)
    assert chosen == given and not choice.changed and choice.cutoff_hz == 8.0
    slow, _ = simulate_recording(denso, (10.0 * reference[0], reference[1]), SimulationOptions(rate=250.0), rng)
    chosen, choice = with_smoothing(denso, [slow], given)
    assert choice.changed and chosen.coulomb_velocity == choice.velocity < 0.01 and chosen.mass_ratio == (0.8, 1.25)
    with pytest.raises(ShapeError):
        with_smoothing(denso, [Recording(t=recording.t, q=recording.q[:, :3], tau=recording.tau[:, :3])], given)


@pytest.mark.slow
def test_a_slow_recording_fits_as_well_as_the_truth_with_the_chosen_smoothing(denso, denso_model):
    """The virtual Denso moved ten times slower than its exciting trajectory (250 Hz, torque noise 0.1 N m): with
    tanh(qd / 0.05) the fit bends for the friction it misses (up to 5x the truth model's validation RMSE); with the
    smoothing chosen from the reversals it is within 2x of the truth (the robot file's rigid body and its LuGre
    drives' steady-state friction) on every joint."""
    import pinocchio as pin

    from identification.calibration.trajectory_fit import identify_trajectories, predict_torque
    from identification.metrics import rmse
    from identification.virtual.lugre_exact import LuGreArrays, steady_state_friction
    from identification.virtual.simulation import SimulationOptions, simulate_recording
    from psdm_casadi.oracle import build_pinocchio_model
    from trajopt.experiments import sine_experiment

    recordings = []
    for seed in (0, 1):
        rng = np.random.default_rng(seed)
        t, q = sine_experiment(denso, duration=3.0, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=250.0)
        recordings.append(simulate_recording(denso, (10.0 * t, q), options, rng)[0])
    train, validation = recordings
    ready, _, _ = prepare_recording(validation, None, None)
    pinocchio = build_pinocchio_model(denso)
    data = pinocchio.createData()
    truth = np.array([pin.rnea(pinocchio, data, *x) for x in zip(ready.q, ready.qd, ready.qdd)])
    truth += np.asarray(denso.rotor_inertia) * ready.qdd
    truth += steady_state_friction(ready.qd, LuGreArrays.from_drives(denso.drives))
    floor = rmse(ready.tau, truth)
    default = TrajectoryOptions()
    chosen, choice = with_smoothing(denso, [train], default)
    assert choice.changed
    error = {}
    for options in (default, chosen):
        fit = identify_trajectories(denso, denso_model, [train], options)
        error[options.coulomb_velocity] = rmse(
            ready.tau, predict_torque(denso_model, fit, ready.q, ready.qd, ready.qdd)
        )
    assert np.all(error[chosen.coulomb_velocity] < 2.0 * floor), error[chosen.coulomb_velocity] / floor
    assert np.max(error[0.05] / floor) > 3.0
