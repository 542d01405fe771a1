"""The LuGre route's alternation (``lugre_identify``): the friction its rigid-body refit takes out, and when it stops.

The reference is the friction package's own simulation (``simulate_lugre``) from a known bristle state: a recording
that starts with its joint holding its static friction (as the virtual Denso's joint 2 does, 4.5 N m) must have that
friction taken out from its first sample, not a relaxed bristle's. The slow recovery of the virtual robot's LuGre
parameters, sigma0 within 6 % on every joint, is in ``test_lugre_recordings``.

The route's warnings are checked on a virtual Denso whose wrist (joint 6) is mostly friction, as the unseen belt
cobot's (``benchmarks/unseen_belt_cobot.py``): its refit without friction explains under half of what is left, the
fit of the whole torque explains it, and no swapped column is claimed; with two columns really swapped it is (the
LuGre route itself in a slow test, its two linear fits in a fast one).
"""

import dataclasses

import numpy as np
import pytest

from identification.calibration.lugre_identify import (
    ROUND_TOLERANCE,
    identify_lugre_trajectories,
    raw_start_force,
    round_change,
    whole_torque_warnings,
    without_lugre_friction,
)
from identification.calibration.lugre_recordings import LuGreFit
from identification.calibration.trajectory_checks import MIN_TRAINING_R2, fit_quality_warnings
from identification.calibration.trajectory_data import choose_filter, prepare_recording
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.preprocessing import central_difference, zero_phase_filter
from identification.data.recording import Recording
from identification.friction.models import LuGreParameters
from identification.friction.simulation import simulate_lugre
from identification.virtual.effects import TorqueRipple
from identification.virtual.simulation import SimulationOptions, simulate_recording
from tests.identification.lugre_recordings_data import NOISE, lugre_robot
from trajopt.experiments import sine_experiment

RATE, CUTOFF = 500.0, 50.0
TRUTH = LuGreParameters(fc=2.5, fs=4.5, vs=0.15, fv=1.5, dv=1.0, sigma0=1250.0, sigma1=25.0)


def _held_then_moving(duration=3.0):
    """Times and positions of a joint at rest for 0.4 s, creeping 0.5 mrad (pre-sliding), then swinging."""
    t = np.arange(int(RATE * duration)) / RATE
    ramp = np.clip((t - 0.4) / 0.3, 0.0, 1.0)
    creep = 5e-4 * ramp**2 * (3 - 2 * ramp)
    swing = np.where(t > 0.8, 0.3 * (1 - np.cos(2 * np.pi * 0.8 * (t - 0.8))), 0.0)
    return t, (creep + swing)[:, None]


def _lugre_fit(parameters, start_force) -> LuGreFit:
    return LuGreFit(parameters=(parameters,), std=np.zeros((1, 7)), identifiable=(True,), rmse=np.zeros(1),
                    rmse_stribeck=np.zeros(1), status=("Solve_Succeeded",),
                    start_force=np.array([[start_force]]))  # fmt: skip


def test_the_raw_start_force_carries_a_state_back_over_pre_sliding_and_is_bounded_after_sliding():
    t, q = _held_then_moving()
    qd = np.gradient(q[:, 0], t)
    s_raw = 0.9 * TRUTH.fs
    force = TRUTH.sigma0 * simulate_lugre(TRUTH, t, qd, z0=s_raw / TRUTH.sigma0)[1]
    creeping = int(0.6 * RATE)  # in pre-sliding: the start is remembered
    assert raw_start_force(TRUTH, t, qd, creeping, force[creeping]) == pytest.approx(s_raw, rel=1e-9)
    slid = int(2.0 * RATE)  # after the swing: the start is forgotten, any start within +-fs gives the force there
    start = raw_start_force(TRUTH, t, qd, slid, force[slid])
    assert abs(start) <= TRUTH.fs
    again = TRUTH.sigma0 * simulate_lugre(TRUTH, t[: slid + 1], qd[: slid + 1], z0=start / TRUTH.sigma0)[1][-1]
    assert again == pytest.approx(force[slid], abs=1e-9)


def test_the_refit_takes_out_the_friction_of_the_fitted_start_not_of_a_relaxed_bristle():
    """A joint holding its static friction at the start: with the fit's state at the first prepared sample the
    friction taken out is the truth from the first raw sample on; a relaxed bristle leaves about fs there."""
    t, q = _held_then_moving()
    qd, _ = central_difference(t, zero_phase_filter(q, RATE, choose_filter(RATE, CUTOFF)[0]))
    held = TRUTH.fs  # the arm stopped holding its static friction before the recording began
    truth = TRUTH.sigma0 * simulate_lugre(TRUTH, t, qd[:, 0], z0=held / TRUTH.sigma0)[1]
    friction = simulate_lugre(TRUTH, t, qd[:, 0], z0=held / TRUTH.sigma0)[0]
    recording = Recording(t=t, q=q, tau=friction[:, None], name="held")
    prepared, _, _ = prepare_recording(recording, None, CUTOFF, 1.0)
    first = int(np.searchsorted(t, prepared.t[0] - 1e-9 / RATE))
    assert first > 0 and abs(truth[first] - held) < 0.05 * held  # still held at the first prepared sample
    for start_force, error in ((truth[first], 1e-9), (0.0, None)):
        (left,) = without_lugre_friction([recording], _lugre_fit(TRUTH, start_force), [prepared], None, CUTOFF)
        worst = np.abs(left.tau[:, 0]).max()
        if error is None:  # the bristle relaxed at the fitted one's first prepared sample: fs of error at the start
            assert worst > 0.9 * held
        else:
            assert worst < error


def test_the_rounds_stop_when_every_parameter_has_settled_in_value_or_in_standard_deviations():
    base = _lugre_fit(TRUTH, 0.0)
    moved = [LuGreParameters(**{**TRUTH.as_dict(), "sigma0": TRUTH.sigma0 * factor}) for factor in (1.005, 1.03)]
    small, large = (_lugre_fit(p, 0.0) for p in moved)
    assert round_change(base, small)[0] < 1.0 and round_change(base, small)[1] == pytest.approx(np.log(1.005))
    assert round_change(base, large)[0] == pytest.approx(np.log(1.03) / ROUND_TOLERANCE)
    std = np.zeros((1, 7))
    std[0, 5] = 20 * 0.03 * TRUTH.sigma0  # a sigma0 the data hardly see: 3 % is 0.05 of its sd
    uncertain = LuGreFit(**{**large.__dict__, "std": std})
    assert round_change(base, uncertain)[0] < 1.0
    std[0, 5] = 0.03 * TRUTH.sigma0 / 0.2  # 3 % is 0.2 of its sd: moving at the default step, settled at half an sd
    within = LuGreFit(**{**large.__dict__, "std": std})
    assert round_change(base, within)[0] == pytest.approx(2.0)
    assert round_change(base, within, tolerance_sd=0.5)[0] == pytest.approx(0.4)


def _belt_wrist(denso, duration=3.0):
    """``duration`` s of the virtual Denso with LuGre friction whose wrist (joint 6) carries 3 N m of Coulomb friction
    (5.4 N m static) beside its small inertia, and a 0.6 N m ripple 7 times per turn the model lacks (a belt pulley
    out of true, as the unseen belt cobot's)."""
    truth = lugre_robot(denso)
    wrist = dataclasses.replace(truth.drives[5], fc=3.0, fs=5.4, fv=1.0, sigma0=3.0 / 2e-3)
    truth = dataclasses.replace(truth, drives=(*truth.drives[:5], wrist))
    rng = np.random.default_rng(1)
    reference = sine_experiment(denso, duration=duration, rng=rng).reference()
    options = SimulationOptions(rate=RATE, record_tau=True, record_current=False, tau_noise_std=NOISE)
    ripple = TorqueRipple(joint=5, amplitude=0.6, harmonic=7.0, phase=0.8)
    recording, _ = simulate_recording(truth, reference, options, rng, extras=(ripple,))
    return dataclasses.replace(recording, name="belt_wrist")


@pytest.fixture(scope="module")
def belt_wrist(denso):
    return _belt_wrist(denso)


def _lugre_route(denso, denso_model, recording):
    options = TrajectoryOptions(friction=("fc", "fs", "fv"), cutoff_hz=CUTOFF)
    return identify_lugre_trajectories(denso, denso_model, [recording], options, rounds=2)


def test_a_wrist_whose_torque_is_mostly_friction_is_not_said_to_be_a_swapped_column(denso, denso_model, belt_wrist):
    found = _lugre_route(denso, denso_model, belt_wrist)
    # the premise: the refit explains under half of the torque left once the friction is taken out, the Stribeck fit
    # explains the whole torque
    assert found.fit.training_r2[5] < MIN_TRAINING_R2 <= found.stribeck.training_r2[5]
    assert not [w for w in found.fit.warnings if "tau6" in w or "does not look like the torque" in w]
    assert not fit_quality_warnings(denso, found.stribeck, found.stribeck.loaded)


def _swapped(recording):
    """``recording`` with the torques of joints 5 and 6 logged in each other's column."""
    tau = recording.tau.copy()
    tau[:, [4, 5]] = tau[:, [5, 4]]
    return dataclasses.replace(recording, tau=tau)


def _quality_warnings(fit) -> list:
    """The warnings of a joint whose torque the model does not explain (``trajectory_checks.fit_quality_warnings``)."""
    return [w for w in fit.warnings if "the identified model explains" in w]


def test_the_whole_torque_s_warning_of_a_swapped_column_replaces_the_refit_s(denso, denso_model, belt_wrist):
    """The fast guard of the slow test below: the two linear fits of the route (the Stribeck start and a refit without
    friction columns) on swapped columns, without the LuGre fits between them."""
    swapped = _swapped(belt_wrist)
    stribeck = identify_trajectories(denso, denso_model, [swapped], TrajectoryOptions(friction=("fc", "fs", "fv"),
                                                                                      cutoff_hz=CUTOFF))  # fmt: skip
    refit = identify_trajectories(denso, denso_model, [swapped], TrajectoryOptions(friction=(), cutoff_hz=CUTOFF))
    judged = whole_torque_warnings(denso, refit, stribeck)
    quality = _quality_warnings(judged)
    assert [w.split(":")[0] for w in quality] == ["joint 5 (J5)", "joint 6 (J6)"]
    assert "tau6 does not look like the torque of joint 6 (J6)" in quality[1]
    assert quality == _quality_warnings(stribeck)  # in the words of the fit of the whole torque
    others = [w for w in refit.warnings if w not in _quality_warnings(refit)]
    assert judged.warnings == (*quality, *others)  # the refit's other warnings kept
    assert whole_torque_warnings(denso, stribeck, stribeck) is stribeck


@pytest.mark.slow
def test_a_really_swapped_torque_column_is_still_warned_about_on_the_lugre_route(denso, denso_model, belt_wrist):
    found = _lugre_route(denso, denso_model, _swapped(belt_wrist))
    quality = _quality_warnings(found.fit)
    assert [w.split(":")[0] for w in quality] == ["joint 5 (J5)", "joint 6 (J6)"]
    assert "tau6 does not look like the torque of joint 6 (J6)" in quality[1]
    assert quality == fit_quality_warnings(denso, found.stribeck, found.stribeck.loaded)
