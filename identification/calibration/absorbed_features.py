"""Which finding features a recalibration fits: those the fit's other columns do not already span.

A finding's column can lie in the span of the columns the recordings-route fit has anyway: a spring's constant beside
a joint's chosen torque offset (one column), a rotor inertia the base parameters identify. Fitted beside them, its
coefficient and theirs are not determined apart. ``recalibrate`` leaves such a feature out of the joint fit and
reports it as absorbed (``findings.FindingColumns.keep``); :func:`absorbed_mask` decides which, on the training data.
"""

from __future__ import annotations

import numpy as np

from identification.calibration.findings import FindingColumns
from identification.calibration.trajectory_data import NormalEquations, drive_column_names, prepare_recording
from identification.calibration.trajectory_fit import drive_inertia_joints

__all__ = ["ABSORBED", "absorbed_mask"]

#: A feature whose column keeps less than this fraction of its norm after projection on the others is absorbed.
ABSORBED = 1e-8


def absorbed_mask(robot, model, recordings, options, columns: FindingColumns, stribeck=None, kt=None) -> tuple:
    """Which finding features the fit's other columns (and earlier features) do not span, on the training data
    (a Stribeck friction shape with the velocities ``stribeck`` of the model the diagnosis started from; ``kt`` the
    torque constants of recordings of currents); the offsets the fit holds at 0 (outside ``options.offset_joints``)
    are not among those columns."""
    inertia = drive_inertia_joints(model, robot, options)
    names = drive_column_names(robot.n_dof, options.friction, inertia)
    n_extra = len(columns.all_names)
    equations = NormalEquations(robot.n_dof, model.n_base + len(names) + n_extra)
    for recording in recordings:
        ready, _, _ = prepare_recording(recording, kt, options.cutoff_hz, options.edge_periods)
        equations.add_recording(model, ready, options.friction, inertia, options.coulomb_velocity,
                                FindingColumns(columns.terms, columns.reference), stribeck=stribeck,
                                viscous=options.viscous_exponent)  # fmt: skip
    rms_tau = np.sqrt(equations.energy / np.maximum(equations.count, 1))
    gram, _, _ = equations.weighted(1.0 / np.maximum(rms_tau, 1e-12) ** 2)
    scale = np.sqrt(np.clip(np.diag(gram), 1e-300, None))
    gram = gram / np.outer(scale, scale)
    chosen = options.offset_joints  # an offset held at 0 (not chosen) absorbs nothing: a spring's constant stays
    kept = [model.n_base + k for k, n in enumerate(names) if chosen is None or not n.startswith("offset")
            or int(n[6:]) - 1 in chosen]  # fmt: skip
    kept = list(range(model.n_base)) + kept
    keep = []
    for k in range(gram.shape[0] - n_extra, gram.shape[0]):
        block = gram[np.ix_(kept, kept)]
        projected = gram[k, kept] @ np.linalg.pinv(block, rcond=1e-12, hermitian=True) @ gram[kept, k]
        independent = bool(gram[k, k] - projected > ABSORBED * gram[k, k])
        keep.append(independent)
        if independent:
            kept.append(k)
    return tuple(keep)
