"""Preprocessing: central differences against analytic derivatives, zero-phase filtering, uneven grids."""

import warnings

import numpy as np
import pytest

from identification.data.preprocessing import (
    PreprocessOptions,
    central_difference,
    preprocess,
    resample_uniform,
    zero_phase_filter,
)
from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, RecordingError

W = 2 * np.pi * 0.7


def sine_recording(t):
    q = np.column_stack([np.sin(W * t), 0.5 * np.cos(2 * W * t)])
    return Recording(t=t, q=q, current=np.column_stack([np.cos(W * t), np.sin(W * t)]))


def analytic(t):
    qd = np.column_stack([W * np.cos(W * t), -W * np.sin(2 * W * t)])
    qdd = np.column_stack([-(W**2) * np.sin(W * t), -2 * W**2 * np.cos(2 * W * t)])
    return qd, qdd


def test_central_difference_uniform_matches_sine_and_paper_formula():
    t = np.arange(0, 3, 1e-3)
    rec = sine_recording(t)
    qd, qdd = central_difference(t, rec.q)
    qd_true, qdd_true = analytic(t)
    np.testing.assert_allclose(qd[1:-1], qd_true[1:-1], atol=1e-4)  # h^2 q'''/6
    np.testing.assert_allclose(qd[[0, -1]], qd_true[[0, -1]], atol=1e-4 * W)
    np.testing.assert_allclose(qdd[1:-1], qdd_true[1:-1], atol=5e-4)  # h^2 q""""/12
    # the paper's formula at interior points
    np.testing.assert_allclose(qd[1:-1], (rec.q[2:] - rec.q[:-2]) / 2e-3, rtol=1e-9, atol=1e-12)


def test_central_difference_uneven_second_order():
    rng = np.random.default_rng(0)
    errors = []
    for dt in (2e-3, 1e-3):
        t = np.cumsum(rng.uniform(0.5 * dt, 1.5 * dt, int(3 / dt)))
        qd, qdd = central_difference(t, sine_recording(t).q)
        qd_true, qdd_true = analytic(t)
        errors.append(np.abs(qd - qd_true).max())
        # three-point second differences are first order on uneven grids
        np.testing.assert_allclose(qdd[1:-1], qdd_true[1:-1], atol=0.01 * 2 * W**2 * dt / 1e-3)
    assert errors[1] < errors[0] / 3  # second order: halving the step quarters the error


def test_filtfilt_has_zero_phase():
    t = np.arange(0, 10, 1e-3)
    x = np.sin(2 * np.pi * 1.0 * t)
    y = zero_phase_filter(x, 1000.0, 4.0, order=8)
    # a 1 Hz sine far below the 4 Hz cutoff comes out unshifted and unscaled (away from the edges)
    inner = slice(2000, 8000)
    np.testing.assert_allclose(y[inner], x[inner], atol=1e-3)
    lag = np.argmax(np.correlate(y[inner], x[inner], mode="full")) - (x[inner].size - 1)
    assert lag == 0


def test_filter_removes_noise_above_cutoff():
    t = np.arange(0, 10, 1e-3)
    x = np.sin(2 * np.pi * 0.5 * t) + 0.2 * np.sin(2 * np.pi * 100 * t)
    y = zero_phase_filter(x, 1000.0, 4.0)
    assert np.abs(y - np.sin(2 * np.pi * 0.5 * t))[1000:-1000].max() < 1e-3


def test_preprocess_adds_derivatives_and_keeps_input():
    t = np.arange(0, 5, 1e-3)
    rec = sine_recording(t)
    out = preprocess(rec, PreprocessOptions(cutoff_hz=15.0))
    qd_true, qdd_true = analytic(t)
    inner = slice(1000, -1000)  # away from the filter's edge transients
    np.testing.assert_allclose(out.qd[inner], qd_true[inner], atol=1e-3)
    np.testing.assert_allclose(out.qdd[inner], qdd_true[inner], atol=2e-2)
    assert rec.qd is None and out.current is not None


def test_preprocess_uneven_grid_resamples_uniformly():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.8e-3, 1.2e-3, 5000))
    rec = sine_recording(t)
    out = preprocess(rec, PreprocessOptions(cutoff_hz=15.0))
    assert out.is_uniform() and out.t[0] == t[0] and out.t[-1] <= t[-1]
    qd_true, _ = analytic(out.t)
    np.testing.assert_allclose(out.qd[500:-500], qd_true[500:-500], atol=1e-3)
    assert resample_uniform(rec).n_samples == out.n_samples


def test_preprocess_without_filter_keeps_grid():
    t = np.cumsum(np.linspace(1e-3, 2e-3, 400))
    out = preprocess(sine_recording(t), PreprocessOptions(cutoff_hz=None))
    np.testing.assert_array_equal(out.t, t)
    np.testing.assert_array_equal(out.q, sine_recording(t).q)


def test_split_after_preprocess():
    out = preprocess(sine_recording(np.arange(0, 2, 1e-3)), PreprocessOptions(cutoff_hz=10.0))
    opts = PreprocessOptions()
    train, val = out.split(opts.split_fraction)
    assert train.n_samples == 1700 and val.n_samples == 300 and train.qd is not None


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(cutoff_hz=-1.0), "cutoff_hz"),
        (dict(order=0), "order"),
        (dict(differentiation="spline"), "differentiation"),
        (dict(split_fraction=1.0), "split_fraction"),
        (dict(uniform_rtol=-1.0), "uniform_rtol"),
    ],
)
def test_bad_options(kwargs, field):
    with pytest.raises(ParameterError, match=f"PreprocessOptions.{field}"):
        PreprocessOptions(**kwargs)


def test_cutoff_above_nyquist():
    with pytest.raises(ParameterError, match="cutoff_hz must be below the Nyquist"):
        preprocess(sine_recording(np.arange(0, 1, 0.01)), PreprocessOptions(cutoff_hz=60.0))


def test_too_short_for_filter():
    with pytest.raises(RecordingError, match="samples"):
        preprocess(sine_recording(np.arange(0, 0.02, 1e-3)), PreprocessOptions(cutoff_hz=4.0))


def test_options_type_checked():
    with pytest.raises(ParameterError, match="PreprocessOptions"):
        preprocess(sine_recording(np.arange(0, 1, 1e-3)), {"cutoff_hz": 4.0})


@pytest.mark.parametrize(
    "t, scale",
    [
        (
            np.arange(50) * 1e-3,
            1e307,
        ),  # values so large that their differences overflow
        (np.arange(50) * 1e-300, 1.0),  # steps so small that dividing by them overflows
    ],
)
def test_overflow_in_differentiation_is_refused_without_warnings(t, scale):
    rec = Recording(t=t, q=scale * np.sin(np.arange(50.0))[:, None], tau=np.zeros((50, 1)), name="huge.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning: overflow ... before the message
        with pytest.raises(RecordingError, match=r"preprocess of huge.csv: Recording.qd must be finite.*units"):
            preprocess(rec, PreprocessOptions(cutoff_hz=None))


def test_filter_refusals_name_the_recording():
    short = sine_recording(np.arange(0, 0.02, 1e-3)).with_signals(name="friction_j1.csv")
    with pytest.raises(RecordingError, match=r"^friction_j1.csv: Recording.t holds 20 samples"):
        preprocess(short, PreprocessOptions(cutoff_hz=4.0))
    slow = sine_recording(np.arange(0, 1, 0.01)).with_signals(name="slow.csv")
    with pytest.raises(ParameterError, match=r"^slow.csv: PreprocessOptions.cutoff_hz must be below the Nyquist"):
        preprocess(slow, PreprocessOptions(cutoff_hz=60.0))


def test_a_logger_gap_is_bridged_without_the_spline_s_swing(denso):
    """A log with 60 ms of dropped messages (a ROS bag's gap) is prepared like the log without the gap: near each gap
    the filtered torque stays within 1 % of the joint's torque range of the complete recording's (the virtual Denso,
    torque noise 0.3 N m). A cubic spline through the noisy torques at the gap's ends swung by up to 14 N m on a
    100 N m joint (3 % RMS over the second around it; 7 % on joint 4)."""
    from identification.virtual.simulation import SimulationOptions, simulate_recording
    from trajopt.experiments import sine_experiment

    rng = np.random.default_rng(3)
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.3)
    rec, _ = simulate_recording(denso, sine_experiment(denso, duration=4.0, rng=rng).reference(), options, rng)
    full = preprocess(rec, PreprocessOptions(cutoff_hz=10.0))
    span = rec.tau.max(axis=0) - rec.tau.min(axis=0)
    for start in (1.0, 2.0, 3.0):
        keep = (rec.t < start) | (rec.t >= start + 0.06)
        gapped = preprocess(rec.with_signals(t=rec.t[keep], q=rec.q[keep], tau=rec.tau[keep]), PreprocessOptions(10.0))
        np.testing.assert_allclose(gapped.t, full.t, rtol=0, atol=1e-9)  # the same grid
        near = np.abs(full.t - start) < 0.5
        error = np.sqrt(np.mean((gapped.tau - full.tau)[near] ** 2, axis=0))
        assert np.all(error < 0.01 * span), (start, error / span)
