"""What estimating the rigid body costs on a held-out motion, per joint: the robot-file check's estimation allowance.

The model identify hands over estimates the rigid body's base parameters that the model it replaces (the robot file's
rigid body with its friction fitted, ``robot_file_check``) takes from the file; both fit the drive parameters (friction,
offsets, drive inertias). Were the file exact, the identified model would still be worse on a held-out recording by
its rigid body's estimation error. With the base parameters' covariance given the drive parameters,
``Sigma = S_tt - S_td S_dd^+ S_dt`` of the fit's covariance ``S`` (``TrajectoryFit.covariance`` of its base then
drive parameters as written: sandwich, with the pull's precision where the fit is pulled towards the file), the
expected mean square of that error on joint ``j`` over the held-out samples is

    ``v_j = mean_t phi_j(t) Sigma phi_j(t)^T``     (``phi_j(t)``: joint ``j``'s row of the regressor at sample ``t``)

so the identified model's RMSE may exceed the baseline's ``b_j`` by ``sqrt(b_j^2 + v_j) - b_j`` before the joint is
called worse (``joint_allowance``). It is the motion's own and the joint's own: a joint the well-determined parameters
carry gets little, one carried by parameters the training motion hardly fixes gets more.

Why these choices (the virtual robots whose robot file is the truth, ``tests/identification/test_robot_file_check``):

- given the drive parameters, not with them: along a joint that moves one way only, its Coulomb friction and the
  gravity parameters trade freely, and the whole covariance predicts a large error on a held-out motion on which it
  reverses -- the very error the robot-file check exists to find and ``one_way_friction`` mends by holding that
  friction. The baseline fits the same friction; what the identified model adds is the rigid body.
- on the held-out motion, not on the training samples: there the leverages sum to the parameters' count as in
  ``sigma^2 (1 + p / N)``, but a held-out motion is another motion, and the identified model of an exact file was
  then over the allowance on the virtual Denso.

It replaces the uniform ``sqrt(1 + p / N) - 1`` of the baseline's RMSE (``uniform_allowance``), which counts every
one of the ``p`` base parameters as estimated from the ``N`` independent samples of each joint: summed over the
joints a least-squares fit's leverages are ``p``, not ``p`` per joint, so it was about ``n_dof`` times too wide and
the same on every joint. It stays the allowance of a fit without a covariance (routes that state none).
"""

from __future__ import annotations

import numpy as np

__all__ = ["joint_allowance", "prediction_variance", "rigid_body_covariance", "uniform_allowance"]


def rigid_body_covariance(model, fit) -> np.ndarray | None:
    """The covariance of ``fit``'s base parameters given its drive parameters (module docstring), or None when the
    fit states no covariance of its parameters (or one of another size)."""
    covariance = getattr(fit, "covariance", None)
    size, n = model.n_base + len(fit.drive_names), model.n_base
    if covariance is None or np.shape(covariance) != (size, size):
        return None
    covariance = np.nan_to_num(np.asarray(covariance, dtype=float))
    rigid, cross, drive = covariance[:n, :n], covariance[:n, n:], covariance[n:, n:]
    given = rigid - cross @ np.linalg.pinv(drive, rcond=1e-10, hermitian=True) @ cross.T if drive.size else rigid
    return (given + given.T) / 2.0


def prediction_variance(model, covariance, ready) -> np.ndarray:
    """Per joint, ``v_j`` [N^2 m^2] (module docstring): the mean over the samples of the prepared recording ``ready``
    of the rigid-body torque's variance under the base parameters' ``covariance`` (``rigid_body_covariance``)."""
    n, n_dof = np.shape(ready.q)
    regressor = np.asarray(model.regressor(ready.q, ready.qd, ready.qdd), dtype=float).reshape(n, n_dof, -1)
    return np.maximum(np.einsum("tjp,pq,tjq->j", regressor, covariance, regressor) / max(n, 1), 0.0)


def joint_allowance(before, variance) -> np.ndarray:
    """Per joint, how far [N m] the identified model's RMSE may exceed the baseline's ``before`` for estimating the
    parameters with prediction ``variance`` (``prediction_variance``): ``sqrt(before^2 + v) - before``."""
    before = np.asarray(before, dtype=float)
    return np.sqrt(before**2 + np.asarray(variance, dtype=float)) - before


def uniform_allowance(parameters: int, samples_per_joint: float) -> float:
    """``sqrt(1 + p / N) - 1``: the relative allowance of a fit without a covariance (module docstring)."""
    return float(np.sqrt(1.0 + parameters / max(samples_per_joint, 1.0)) - 1.0)
