"""Which joints' drive inertia is a column of its own beside the base parameters: a rank test on random states.

A drive inertia ``Ia_j qdd_j`` that the PSDM model's map does not hold (the robot file's ``[assumptions]
drive_inertia`` is off on that joint) is either in the span of the base regressor (the first joint's, about a vertical
axis, adds to its link's Izz; a joint parallel to its neighbours adds to a lumped ZZ: ``merged_rotors`` places it in the
map) or independent of it, and then the fit gives it a column of its own (``Ia<j>``, ``trajectory_fit``; which of them
the data keep is ``column_choice``'s). The test evaluates the base regressor on :func:`random_states` and keeps a joint
where its column's residual off the span of the regressor and the columns kept before it exceeds ``SPAN_TOLERANCE``
(the same test ``merged_rotors.merged_rotor_map`` makes, so that the two answers are complements).

The answer is a function of the model and the robot's joint limits only; identify asks it in its column choice, its
fit and its check of which torques hold the rotors (``merged_rotors.holds_rotors``), and the diagnosis in each of its
refits. It is computed once per model object (:func:`separate_inertia_joints` remembers it while the model lives).
"""

from __future__ import annotations

import threading
import weakref

import numpy as np

from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT

__all__ = ["SPAN_TOLERANCE", "drive_inertias", "random_states", "separate_inertia_joints"]

SPAN_TOLERANCE = 1e-8  # relative residual below which Ia_j qdd_j is taken as inside the base regressor's span

#: {(id(model), seed, joint limits): (weak reference to the model, joints)}; an entry leaves with its model.
_REMEMBERED = {}
_LOCK = threading.Lock()


def random_states(model, robot, seed: int = 0) -> tuple:
    """``(q, qd, qdd)``, each (4 (n_base + n_dof), n_dof): joint angles uniform within the robot's limits, speeds and
    accelerations standard normal, from ``seed``; four times as many states as unknowns of the rank test."""
    rng = np.random.default_rng(seed)
    n_states = 4 * (model.n_base + robot.n_dof)
    q = rng.uniform(robot.q_min, robot.q_max, size=(n_states, robot.n_dof))
    qd, qdd = rng.normal(size=(2, n_states, robot.n_dof))
    return q, qd, qdd


def separate_inertia_joints(model, robot, seed: int = 0) -> list:
    """The joints (0-based) whose drive inertia needs a column of its own: not in ``model``'s map, and independent of
    its base regressor and of the drive-inertia columns of the joints before it on :func:`random_states`.

    Remembered per model object (and ``seed`` and joint limits): the diagnosis asks it in every refit."""
    key = (id(model), seed, np.asarray(robot.q_min, dtype=float).tobytes(), np.asarray(robot.q_max).tobytes())
    with _LOCK:
        entry = _REMEMBERED.get(key)
    if entry is not None and entry[0]() is model:
        return list(entry[1])
    joints = _rank_test(model, robot, seed)
    with _LOCK:
        _REMEMBERED[key] = (weakref.ref(model), tuple(joints))
    weakref.finalize(model, _forget, key)
    return joints


def _forget(key) -> None:
    with _LOCK:
        _REMEMBERED.pop(key, None)


def _rank_test(model, robot, seed: int) -> list:
    """:func:`separate_inertia_joints` computed: each candidate's column projected off an orthonormal basis of the
    regressor's span, which a kept column joins."""
    mapped = model.parameter_map[:, LINK_PARAMETER_COUNT :: LINK_PARAMETER_COUNT + 1]
    candidates = [j for j in range(robot.n_dof) if not np.any(mapped[:, j])]
    if not candidates:
        return []
    q, qd, qdd = random_states(model, robot, seed)
    stacked = model.regressor(q, qd, qdd).reshape(-1, model.n_base)
    u, singular, _ = np.linalg.svd(stacked, full_matrices=False)
    basis = u[:, singular > singular[0] * max(stacked.shape) * np.finfo(float).eps]
    kept = []
    for j in candidates:
        column = np.zeros_like(qdd)
        column[:, j] = qdd[:, j]
        column = column.reshape(-1)
        residual = column - basis @ (basis.T @ column)
        residual -= basis @ (basis.T @ residual)  # twice: the basis grows by Gram-Schmidt
        size = np.linalg.norm(residual)
        if size > SPAN_TOLERANCE * np.linalg.norm(column):
            kept.append(j)
            basis = np.column_stack([basis, residual / size])
    return kept


def drive_inertias(model, standard, drive, names) -> np.ndarray:
    """The drive inertia of every joint of a fit: in the model's standard parameters (``standard``, (n_dof, 11)) where
    they hold it, from its own column ``Ia<j>`` of ``drive`` (labelled ``names``), else 0."""
    rotor = LINK_PARAMETER_COUNT  # the drive inertia's column in a joint's 11 standard parameters
    out = np.where(np.any(model.parameter_map[:, rotor :: rotor + 1], axis=0), standard[:, rotor], 0.0)
    out[[int(n[2:]) - 1 for n in names if n.startswith("Ia")]] = [v for n, v in zip(names, drive) if n.startswith("Ia")]
    return out
