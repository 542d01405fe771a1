"""The calibration experiments made ready for the steps: filtered, folded, decimated, split for training and validation.

Used by :class:`identification.calibration.pipeline.IdentificationPipeline`; every function takes
its :class:`~identification.calibration.pipeline.PipelineOptions` (cutoffs, rates, split). Each
experiment is filtered as in the paper (zero-phase 8th-order Butterworth, central differences;
``preprocessing.preprocess``), out-and-back experiments are folded (forward/backward averaged,
:func:`identification.calibration.out_and_back.fold_out_and_back`), and everything is split into training
and validation parts (``Recording.split``; a joint's second friction experiment, when recorded,
validates its friction instead).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.extra_terms import extra_torque
from identification.calibration.friction_step import FrictionExperiment, friction_torque
from identification.calibration.out_and_back import MotorExperiment, fold_out_and_back
from identification.calibration.payload import payload_torque
from identification.calibration.refinement import RefinementBlock
from identification.data.filter_choice import EDGE_PERIODS
from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.data.recording import Recording

__all__ = [
    "EDGE_PERIODS",
    "trim_filter_edges",
    "Split",
    "prepare",
    "decimation_step",
    "decimate",
    "without_torque",
    "motor_split",
    "gravity_split",
    "friction_split",
    "excitation_split",
    "refinement_blocks",
]


@dataclass(frozen=True, eq=False)
class Split:
    """Training and validation parts of one step's experiments (recordings or step experiments).

    Parameters
    ----------
    train, valid : tuple
    """

    train: tuple
    valid: tuple

    def __post_init__(self):
        object.__setattr__(self, "train", tuple(self.train))
        object.__setattr__(self, "valid", tuple(self.valid))


def prepare(rec: Recording, cutoff_hz, options) -> Recording:
    """``rec`` filtered at ``cutoff_hz`` [Hz] (None: unfiltered) with its central differences qd and qdd."""
    return preprocess(rec, PreprocessOptions(cutoff_hz=cutoff_hz, split_fraction=options.split_fraction))


def decimation_step(rec: Recording, rate_hz: float) -> int:
    """Keep every this-many samples of ``rec`` to reach about ``rate_hz`` [Hz] (>= 1)."""
    return max(1, int(round(1.0 / (rec.dt * rate_hz))))


def decimate(rec: Recording, rate_hz: float) -> Recording:
    """``rec`` decimated to about ``rate_hz`` [Hz] (every ``decimation_step``-th sample)."""
    step = decimation_step(rec, rate_hz)
    if step == 1:
        return rec
    every = slice(None, None, step)

    def pick(a):
        return None if a is None else a[every]

    return rec.with_signals(t=rec.t[every], q=rec.q[every], tau=pick(rec.tau), current=pick(rec.current),
                            qd=pick(rec.qd), qdd=pick(rec.qdd), temperature=pick(rec.temperature))  # fmt: skip


def without_torque(rec: Recording, torque, kt) -> Recording:
    """``rec`` with ``torque`` [N m], shape (n_samples, n_dof), removed from its torques or currents."""
    if rec.tau is not None:
        return rec.with_signals(tau=rec.tau - torque)
    return rec.with_signals(current=rec.current - torque / np.asarray(kt, dtype=float))


def motor_split(data, options) -> Split:
    """Step 1: per swept joint, the folded sweeps without and with the mass, as MotorExperiment parts."""
    train, valid = [], []
    for joint, nominal, loaded in data.motor:
        a = fold_out_and_back(prepare(nominal, options.motor_cutoff_hz, options))
        b = fold_out_and_back(prepare(loaded, options.motor_cutoff_hz, options))
        (a_t, a_v), (b_t, b_v) = (
            a.split(options.split_fraction, options.n_blocks),
            b.split(options.split_fraction, options.n_blocks),
        )
        train.append(MotorExperiment(joint, a_t, b_t))
        valid.append(MotorExperiment(joint, a_v, b_v))
    return Split(train, valid)


def gravity_split(data, options, lugre=None, kt=None) -> Split:
    """Step 2: the folded, decimated jogs; with ``lugre`` (and ``kt``) its friction is removed before folding.

    The friction is simulated along the unfiltered velocity and removed before the filter.
    """
    train, valid = [], []
    for rec in data.gravity:
        if lugre is not None:
            raw = prepare(rec, None, options)
            rec = without_torque(raw, friction_torque(tuple(lugre), raw.t, raw.qd), kt)
        folded = decimate(fold_out_and_back(prepare(rec, options.gravity_cutoff_hz, options)), options.gravity_rate_hz)
        tr, va = folded.split(options.split_fraction, options.n_blocks)
        train.append(tr)
        valid.append(va)
    return Split(train, valid)


def friction_split(data, options) -> Split:
    """Step 3: per joint its friction experiment, validated by its second one when recorded."""
    train, valid = [], []
    second = dict(data.friction_validation)
    for joint, rec in data.friction:
        clean = prepare(rec, options.friction_cutoff_hz, options)
        if joint in second:
            tr, va = clean, prepare(second[joint], options.friction_cutoff_hz, options)
        else:
            tr, va = clean.split(options.split_fraction)
        train.append(FrictionExperiment(joint, tr))
        valid.append(FrictionExperiment(joint, va))
    return Split(train, valid)


def trim_filter_edges(rec: Recording, cutoff_hz) -> Recording:
    """``rec`` without its first and last ``EDGE_PERIODS / cutoff_hz`` seconds (unchanged when unfiltered), the trim
    of ``psdm identify`` (``filter_choice.EDGE_PERIODS``, one definition).

    An exciting trajectory is recorded in motion from its first sample to its last; the zero-phase
    filter's start-up transient at both ends then corrupts the differentiated qdd there (and the
    torque), which no model predicts: left in, it dominates the validation part, the recording's end.
    """
    if cutoff_hz is None:
        return rec
    edge = EDGE_PERIODS / float(cutoff_hz)
    return rec.time_slice(rec.t[0] + edge, rec.t[-1] - edge + 0.5 * rec.dt)


def excitation_split(data, options) -> Split:
    """Step 4: the exciting trajectories filtered at the inertial cutoff, the filter's edges trimmed."""
    train, valid = [], []
    for rec in data.excitation:
        clean = trim_filter_edges(prepare(rec, options.inertial_cutoff_hz, options), options.inertial_cutoff_hz)
        tr, va = clean.split(options.split_fraction)
        train.append(tr)
        valid.append(va)
    return Split(train, valid)


def refinement_blocks(robot, data, options, extra_terms=None) -> list:
    """The training parts of every experiment, decimated, with their known tool torques (the mass of step 1 too).

    Fitted ``extra_terms`` (:class:`~identification.calibration.extra_terms.ExtraTerms`) count as known
    torques too: the refinement holds them.
    """
    blocks = []

    def add(rec, cutoff, payload=None, trim=False):
        clean = prepare(rec, cutoff, options)
        clean = trim_filter_edges(clean, cutoff) if trim else clean
        clean = decimate(clean.split(options.split_fraction)[0], options.refinement_rate_hz)
        tool = extra_torque(extra_terms, clean)
        for load in (payload, data.tool):
            if load is not None:
                tool = tool + payload_torque(robot, load, clean.q, clean.qd, clean.qdd)
        blocks.append(RefinementBlock(clean, tool))

    for _, nominal, loaded in data.motor:
        add(nominal, options.motor_cutoff_hz)
        add(loaded, options.motor_cutoff_hz, data.payload)
    for rec in data.gravity:
        add(rec, options.gravity_cutoff_hz)
    for _, rec in data.friction:
        add(rec, options.friction_cutoff_hz)
    for rec in data.excitation:
        add(rec, options.inertial_cutoff_hz, trim=True)
    return blocks
