"""How well a recording weighs a payload at the flange: its noise and the robot file's links it cannot separate.

Identify's payload route (``payload_route.estimate_payload``) fits the payload's mass and first moment on the torque
the robot file's rigid body leaves. Every error of the file's links is in that torque too, and part of it looks like
the payload: a mass error of a link whose centre of mass sits near the wrist centre (the wrist, the forearm's end)
acts on the shoulder and elbow exactly as payload mass there, and on the wrist joints not at all, which a payload's
mass with its centre of mass moved towards the wrist centre reproduces. No motion of a loaded arm separates the two:
the shoulder and elbow see the mass at the wrist centre (the payload's and the links' together), the wrist joints the
payload's first moment about it. The recording's noise then says little about how far the mass is off; the file's
links say the most.

:func:`weigh_payload` gives the estimate's standard deviation from both (:class:`PayloadWeight`):

- the noise: the weighted least squares' covariance with each joint's residual variance grown by its correlation
  time (``residual_correlation``; the recordings are filtered and oversampled), as the fit's own standard deviations;
- the links: the estimate's linear response to each standard parameter of the file's links (and drive inertias the
  fit does not estimate), times that parameter's standard deviation as identify's pull towards the file states it
  (``prior_pull.PriorPull``: the masses as the mass bounds state them, the rest to ``prior_uncertainty`` times their
  size), the parameters independent.

Where the links' part is the larger, the recording cannot separate the payload's mass from the links': the mass is
known to the file's accuracy, not the recording's, and a recording of the arm without the tool (the tool stated as an
unknown payload, ``data.configuration``) separates them, as the arm's parameters are then fitted on the recording
that does not carry it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from identification.calibration.prior_pull import PriorPull
from identification.calibration.residual_correlation import residual_correlation_time
from psdm_casadi.oracle import build_pinocchio_model, link_to_joint_frame_maps

__all__ = ["BODY", "LinkRegressor", "PayloadWeight", "link_cross", "point_mass_inertia", "weigh_payload"]

BODY = 10  # standard parameters of a body: m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz (link frame origin)


class LinkRegressor:
    """Every link's standard-parameter torque columns in its own link frame (Pinocchio's joint torque regressor, each
    body's columns mapped from its joint frame, ``oracle.link_to_joint_frame_maps``), then one drive-inertia column per
    joint: ``(n_samples, n_dof, 11 n_dof)``, the columns of ``robot.nominal_dynamic_parameters()`` row by row."""

    def __init__(self, robot):
        self.n_dof = robot.n_dof
        self.model = build_pinocchio_model(robot, np.zeros((robot.n_dof, BODY + 1)))
        self.data = self.model.createData()
        self.to_link = link_to_joint_frame_maps(robot)

    def __call__(self, q, qd, qdd) -> np.ndarray:
        n = self.n_dof
        out = np.zeros((q.shape[0], n, (BODY + 1) * n))
        for k in range(q.shape[0]):
            full = pin.computeJointTorqueRegressor(self.model, self.data, q[k], qd[k], qdd[k])
            for i in range(n):
                out[k, :, (BODY + 1) * i : (BODY + 1) * i + BODY] = full[:, BODY * i : BODY * (i + 1)] @ self.to_link[i]
        for i in range(n):
            out[:, i, (BODY + 1) * i + BODY] = qdd[:, i]
        return out


def point_mass_inertia(mass: float, first_moment) -> np.ndarray:
    """The six inertia parameters (Ixx, Ixy, Iyy, Ixz, Iyz, Izz) about the origin of a point mass ``mass`` [kg] with
    first moment ``first_moment`` (``mass`` times its position) [kg m]: ``(|h|^2 1 - h h^T) / m``; zero for no mass."""
    h = np.asarray(first_moment, dtype=float)
    if not mass > 0.0:
        return np.zeros(6)
    inertia = (h @ h * np.eye(3) - np.outer(h, h)) / mass
    return inertia[[0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]


def _size(value: float) -> str:
    """Three significant digits, without an exponent below 1e4."""
    return f"{value:.3g}" if abs(value) < 1000 or not np.isfinite(value) else f"{value:.0f}"


def link_cross(columns, links) -> np.ndarray:
    """``(n_dof, k, 11 n_dof)``: per joint, ``sum_s columns[s, j]^T links[s, j]`` over the samples (a recording's
    share of :func:`weigh_payload`'s ``cross``; its link columns need not be kept)."""
    return np.einsum("snc,snp->ncp", columns, links)


@dataclass(frozen=True)
class PayloadWeight:
    """A payload's mass [kg] and centre of mass [m] (flange frame) with their standard deviations (module docstring).

    ``mass_std`` is the total; ``noise_std`` the recording's part, ``links_std`` the robot file's links' part, and
    ``link_std`` that part per link (its drive inertia with it), 1-based link ``i`` at index ``i - 1``.
    """

    mass: float
    com: tuple
    mass_std: float
    noise_std: float
    links_std: float
    link_std: tuple
    com_std: tuple

    @property
    def separable(self) -> bool:
        """Whether the recording, not the robot file's links, limits how well the mass is known."""
        return not self.links_std > self.noise_std

    def sentence(self) -> str:
        """The report's words on the mass: its +- and, where the recording cannot separate it, why and what to do."""
        head = (f"mass {self.mass:.4g} +- {_size(self.mass_std)} kg (+- {_size(self.noise_std)} from the recording's "
                f"noise, +- {_size(self.links_std)} from the robot file's links)")  # fmt: skip
        if self.separable:
            return head
        order = np.argsort(self.link_std)[::-1]
        most = [f"link {i + 1}" for i in order[:2] if self.link_std[i] > 0.25 * self.links_std]
        return (f"{head}: the recording cannot separate the payload's mass from the errors of the robot file's links "
                f"({', '.join(most)} most), whose torque on the joints that carry the payload is partly a payload's (a "
                "link's mass at the wrist centre is one, its centre of mass moved); record the arm without the tool "
                "too and state the tool as an unknown payload ({\"unknown\": \"tool\"} beside the loaded "
                "recordings): the links are then weighed on the recording without it")  # fmt: skip

    def to_dict(self) -> dict:
        return {"mass_std": self.mass_std, "mass_std_noise": self.noise_std, "mass_std_links": self.links_std,
                "mass_std_per_link": list(self.link_std), "com_std": list(self.com_std),
                "separable": self.separable}  # fmt: skip


def weigh_payload(columns, residual, weights, cross, prior, options, fixed=()) -> PayloadWeight:
    """The :class:`PayloadWeight` of the weighted least squares whose first four ``columns`` are the payload's mass
    and first moment (module docstring).

    ``columns`` (n_samples, n_dof, k) and ``residual`` (n_samples, n_dof) are the fit's, ``weights`` (n_dof,) its
    per-joint weights (inverse residual variances); ``cross`` (n_dof, k, 11 n_dof) per joint the products of the
    fit's columns with the :class:`LinkRegressor` columns of the same samples, summed over them (:func:`link_cross`);
    ``prior`` (n_dof, 11) the robot file's standard parameters, ``options`` the fit's (its pull towards the file);
    ``fixed`` the joints whose drive inertia the fit estimates (their column is not the file's to err).
    """
    gram = np.einsum("n,snc,snd->cd", weights, columns, columns)
    inverse = np.linalg.pinv(gram, hermitian=True)
    x = inverse @ np.einsum("n,snc,sn->c", weights, columns, residual)
    left = residual - columns @ x
    correlation = residual_correlation_time(left)
    noise = inverse @ np.einsum("n,snc,snd->cd", weights * correlation, columns, columns) @ inverse
    pull = PriorPull.of(options, np.full(residual.shape[1], float(residual.shape[0])), correlation)
    spread = pull.standard_deviations(np.asarray(prior, dtype=float)).copy()
    spread[list(fixed), BODY] = 0.0
    response = (inverse @ np.einsum("n,ncp->cp", weights, cross))[:4] * spread.reshape(-1)
    links_cov = response @ response.T
    mass = float(x[0])
    per_link = np.sqrt(np.sum(response[0].reshape(-1, BODY + 1) ** 2, axis=1))
    com, com_std = x[1:4] / (mass if mass > 0.0 else np.nan), []
    for axis in range(3):  # delta method: d(h/m) = dh/m - h dm/m^2
        gradient = np.zeros(4)
        gradient[0], gradient[1 + axis] = -com[axis] / mass, 1.0 / mass
        variance = gradient @ (noise[:4, :4] + links_cov) @ gradient
        com_std.append(float(np.sqrt(max(variance, 0.0))))
    noise_std, links_std = float(np.sqrt(max(noise[0, 0], 0.0))), float(np.sqrt(links_cov[0, 0]))
    return PayloadWeight(mass, tuple(float(v) for v in com), float(np.hypot(noise_std, links_std)), noise_std,
                         links_std, tuple(float(v) for v in per_link), tuple(com_std))  # fmt: skip
