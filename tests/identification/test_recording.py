"""Recording: validation messages, views, split and slicing."""

import numpy as np
import pytest

from identification.data.recording import Recording
from psdm_casadi.errors import RecordingError, ShapeError


def make(n=100, n_dof=2, **kw):
    t = np.linspace(0.0, 1.0, n)
    q = np.column_stack([np.sin((j + 1) * t) for j in range(n_dof)])
    args = dict(t=t, q=q, tau=np.cos(q))
    args.update(kw)
    return Recording(**args)


def test_arrays_are_read_only_copies():
    q = np.zeros((10, 2))
    rec = Recording(t=np.arange(10.0), q=q, current=q)
    q[0, 0] = 5.0
    assert rec.q[0, 0] == 0.0
    with pytest.raises(ValueError):
        rec.q[0, 0] = 1.0


def test_transposed_q_names_fix():
    t = np.linspace(0, 1, 50)
    with pytest.raises(ShapeError, match=r"Recording.q .*Pass q.T"):
        Recording(t=t, q=np.zeros((6, 50)), tau=np.zeros((50, 6)))


def test_transposed_tau_names_fix():
    t = np.linspace(0, 1, 50)
    with pytest.raises(ShapeError, match=r"Recording.tau .*Pass tau.T"):
        Recording(t=t, q=np.zeros((50, 6)), tau=np.zeros((6, 50)))


def test_check_robot_message():
    rec = make(n=6, n_dof=4)
    with pytest.raises(
        ShapeError, match=r"Recording.q must have shape \(n_samples, 6\) to match RobotDescription.n_dof=6"
    ):
        rec.check_robot(6)
    assert rec.check_robot(4) is rec


@pytest.mark.parametrize("field", ["q", "tau", "t"])
def test_nan_is_refused_naming_field(field):
    rec = make()
    bad = np.array(getattr(rec, field))
    bad[5] = np.nan
    with pytest.raises(RecordingError, match=f"Recording.{field} must be finite"):
        rec.with_signals(**{field: bad})


def test_non_increasing_time():
    t = np.linspace(0, 1, 10)
    t[4] = t[3]
    with pytest.raises(RecordingError, match=r"Recording.t must be strictly increasing.*t\[4\]"):
        Recording(t=t, q=np.zeros((10, 1)), tau=np.zeros((10, 1)))


def test_too_few_samples():
    with pytest.raises(RecordingError, match="Recording.t must hold at least 3"):
        Recording(t=[0.0, 1.0], q=np.zeros((2, 1)), tau=np.zeros((2, 1)))


def test_needs_tau_or_current():
    with pytest.raises(RecordingError, match="tau= or current="):
        Recording(t=np.arange(5.0), q=np.zeros((5, 1)))


def test_t_must_be_1d():
    with pytest.raises(ShapeError, match="Recording.t"):
        Recording(t=np.zeros((5, 2)), q=np.zeros((5, 1)), tau=np.zeros((5, 1)))


def test_split_sizes_and_contiguity():
    rec = make(n=1000)
    train, val = rec.split(0.85)
    assert (train.n_samples, val.n_samples) == (850, 150)
    assert train.t[-1] < val.t[0]
    np.testing.assert_array_equal(np.concatenate([train.q, val.q]), rec.q)


def test_split_blocks():
    rec = make(n=1000)
    train, val = rec.split(0.8, n_blocks=4)
    assert (train.n_samples, val.n_samples) == (800, 200)
    # the validation part holds the last 50 samples of every 250-sample block
    expected = np.concatenate([np.arange(200, 250) + 250 * b for b in range(4)])
    np.testing.assert_array_equal(val.t, rec.t[expected])


@pytest.mark.parametrize("fraction", [0.0, 1.0, 1.5])
def test_split_bad_fraction(fraction):
    with pytest.raises(RecordingError, match="fraction"):
        make().split(fraction)


def test_split_too_small():
    with pytest.raises(RecordingError, match="at least 3"):
        make(n=10).split(0.9)


def test_slice_and_time_slice():
    rec = make(n=101)
    part = rec.slice(10, 20)
    assert part.n_samples == 10 and part.t[0] == rec.t[10]
    part = rec.time_slice(0.5, 0.6)
    assert np.all((part.t >= 0.5) & (part.t < 0.6))


def test_joint_torque_from_current():
    t = np.arange(5.0)
    current = np.ones((5, 2))
    rec = Recording(t=t, q=np.zeros((5, 2)), current=current)
    np.testing.assert_allclose(rec.joint_torque([2.0, 3.0]), np.tile([2.0, 3.0], (5, 1)))
    with pytest.raises(RecordingError, match="kt"):
        rec.joint_torque()
    with pytest.raises(ShapeError, match="kt"):
        rec.joint_torque([1.0])


def test_with_tau_and_uniformity():
    rec = make()
    assert rec.is_uniform()
    new = rec.with_tau(np.zeros_like(rec.q))
    assert np.all(new.tau == 0) and not np.all(rec.tau == 0)
    uneven = rec.with_signals(t=rec.t**2 + rec.t)
    assert not uneven.is_uniform()


def test_read_only_arrays_that_own_their_data_are_kept_not_copied():
    q = np.zeros((10, 2))
    q.setflags(write=False)
    rec = Recording(t=np.arange(10.0), q=q, current=np.ones((10, 2)))
    assert rec.q is q  # nobody can write it: sharing it is safe and saves a copy
    again = rec.with_signals(name="again")
    assert again.q is rec.q and again.current is rec.current
    view = rec.q[:, :1]  # a view is copied: its base could be made writable elsewhere
    assert Recording(t=rec.t, q=view, tau=view).q is not view
