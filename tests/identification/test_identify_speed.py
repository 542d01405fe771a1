"""identify's fast paths give the straightforward computation's choices and parameters.

The straightforward computations are written here, as the references: the Stribeck-velocity search summing
every candidate's normal equations from the rows as ``NormalEquations.add`` takes them (``plain_accumulate``), and
the column choice summing and weighting its blocks anew for every candidate (``plain_evaluate``).
The library keeps only its fast path; the test swaps the reference in and compares the whole default
identification (column choice, fit, validation) on a virtual Denso of known friction shapes and offsets.
"""

import numpy as np
import pytest

from identification.calibration import column_candidates, stribeck
from identification.calibration.column_choice import choose_columns
from identification.calibration.trajectory_data import CHUNK_SAMPLES, NormalEquations, drive_columns, prepare_recording
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories, predict_torque
from identification.metrics import rmse
from tests.identification.test_column_choice import OFFSET, synthetic


def plain_accumulate(regressors, prepared, terms, inertia_joints, coulomb_velocity, extras):
    """The normal equations of ``[Y, D(vs), extra]`` from the rows as ``NormalEquations.add`` takes them (the base
    regressor read from the first columns of ``stribeck.row_buffers``)."""
    vs, equations = extras[0].stribeck_velocity, None
    for chunks, r, extra in zip(regressors, prepared, extras):
        for k, per_joint in zip(range(0, r.n_samples, CHUNK_SAMPLES), chunks):
            q, qd, qdd = (x[k : k + CHUNK_SAMPLES] for x in (r.q, r.qd, r.qdd))
            drive = drive_columns(qd, qdd, terms, inertia_joints, coulomb_velocity, vs)
            more = extra.columns(q, qd, qdd)
            n_base = per_joint.shape[2] - drive.shape[2] - more.shape[2]
            rigid = per_joint.transpose(1, 0, 2)[:, :, :n_base]  # the base regressor, (n_samples, n_dof, n_base)
            columns = np.concatenate([rigid, drive, more], axis=2)
            equations = equations or NormalEquations(vs.size, columns.shape[2])
            equations.add(columns, r.tau[k : k + CHUNK_SAMPLES])
    return equations


def plain_evaluate(self, stribeck, dropped=()):
    """``column_candidates.Candidates.evaluate`` summing the blocks and weighting them anew for every candidate."""
    transform = self.transform(stribeck, dropped)
    total = column_candidates.sum_blocks(self.blocks)
    x, std = column_candidates.solve_columns(total.weighted(self.weights)[:2], transform)
    held = None if self.held is None else self.held.residual_sum(x)
    if held is None or np.any(self.held.count == 0):
        folds = [column_candidates.sum_blocks(self.blocks, skip=k) for k in range(len(self.blocks))]
        fits = [column_candidates.solve_columns(fold.weighted(self.weights)[:2], transform)[0] for fold in folds]
        cv = sum(block.residual_sum(fit) for block, fit in zip(self.blocks, fits))
        held = cv if held is None else np.where(self.held.count == 0, cv, held)
    return total.residual_sum(x), held, x, std


def identify(robot, model, train, validation):
    """The defaults of ``psdm identify``: (choice, fit, validation RMSE)."""
    choice = choose_columns(robot, model, [train])
    fit = identify_trajectories(robot, model, [train], choice.options(TrajectoryOptions()))
    ready = prepare_recording(validation, None, fit.cutoff_hz[0])[0]
    return choice, fit, rmse(ready.tau, predict_torque(model, fit, ready.q, ready.qd, ready.qdd))


def relative(a, b):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-12)))


@pytest.fixture(scope="module")
def denso_recordings(denso):
    static = np.array([6.0, 2.0, 6.0, 2.0, 6.0, 2.0])  # Stribeck on joints 1, 3 and 5
    return synthetic(denso, 11, offset=OFFSET, stribeck=static), synthetic(denso, 12, offset=OFFSET, stribeck=static)


def test_the_stribeck_rows_built_per_joint_give_the_same_sums(denso, denso_model, denso_recordings):
    ready = prepare_recording(denso_recordings[0])[0]
    terms = ("fc", "fs", "fv", "offset")
    n_columns = denso_model.n_base + 4 * 6 + 1 + 6
    regressors = stribeck.row_buffers(stribeck.base_regressors(denso_model, [ready]), n_columns)
    for vs in ([0.1, 0.0, 0.2, 0.05, 1.0, 0.0], [0.02] * 6):
        at = [stribeck.StribeckColumns(0.01, np.array(vs))]
        fast = stribeck.stribeck_equations(regressors, [ready], terms, [3], 0.01, at)
        plain = plain_accumulate(regressors, [ready], terms, [3], 0.01, at)
        for name in ("gram", "moment", "energy", "count", "total"):
            assert np.array_equal(getattr(fast, name), getattr(plain, name)), name


def test_defaults_choose_and_fit_as_the_straightforward_computation(denso, denso_model, denso_recordings, monkeypatch):
    train, validation = denso_recordings
    choice, fit, error = identify(denso, denso_model, train, validation)
    monkeypatch.setattr(stribeck, "stribeck_equations", plain_accumulate)
    monkeypatch.setattr(column_candidates.Candidates, "evaluate", plain_evaluate)
    choice_ref, fit_ref, error_ref = identify(denso, denso_model, train, validation)
    assert choice.stribeck_joints == choice_ref.stribeck_joints == (0, 2, 4)  # the truth's shapes
    assert choice.offset_joints == choice_ref.offset_joints and choice.inertia_joints == choice_ref.inertia_joints
    kept = [[(e.term, e.joint, e.kept) for e in c.evidence] for c in (choice, choice_ref)]
    assert kept[0] == kept[1]
    # a difference of log-likelihoods (n log(RSS ratio)): its rounding is absolute, not relative to it
    assert np.allclose([e.delta_bic for e in choice.evidence], [e.delta_bic for e in choice_ref.evidence], atol=1e-6)
    assert relative([e.held_out_ratio for e in choice.evidence], [e.held_out_ratio for e in choice_ref.evidence]) < 1e-9
    assert relative(fit.stribeck_velocity, fit_ref.stribeck_velocity) < 1e-9
    for name in ("theta", "drive", "theta_ols", "drive_ols", "theta_std"):
        assert relative(getattr(fit, name), getattr(fit_ref, name)) < 1e-9, name
    assert relative(fit.standard, fit_ref.standard) < 1e-9
    assert relative(error, error_ref) < 1e-9
