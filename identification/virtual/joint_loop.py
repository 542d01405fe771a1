"""Gains of the virtual robot's joint controller, chosen so that the sampled loop is stable on any arm."""

from __future__ import annotations

import numpy as np

from psdm_casadi.oracle import mass_matrix

__all__ = ["LOOP_DAMPING_LIMIT", "TRACKING_LIMIT", "joint_loop_gains", "tracks"]

# spectral radius of dt M^-1 Kd above which the sampled PD loop is retuned: a held derivative term is unstable
# beyond 2, and well damped only far below it
LOOP_DAMPING_LIMIT = 0.5
# a run farther than this from its reference [rad or m] has diverged: the simulator retunes the loop and runs again
TRACKING_LIMIT = 0.5


def _loop_damping(model, data, poses, kd, dt: float) -> float:
    """Largest spectral radius of ``dt M(q)^-1 diag(kd)`` over ``poses``: how hard the sampled derivative term
    kicks the arm in one control period (symmetric positive-definite pencil, so real eigenvalues)."""
    worst = 0.0
    for q in poses:
        mass = mass_matrix(model, data, q)
        worst = max(worst, float(np.max(np.abs(np.linalg.eigvals(np.linalg.solve(mass, np.diag(kd)))))) * dt)
    return worst


def joint_loop_gains(
    model,
    data,
    q_ref,
    rate: float,
    bandwidth_hz: float,
    damping_ratio: float,
    integral_gain: float,
    retuned: bool = False,
) -> tuple:
    """``(kp, kd, ki)`` per joint of the virtual robot's PD + integral loop sampled at ``rate``: from the bandwidth
    and each joint's inertia at the first pose of ``q_ref`` (n_samples, n_dof).

    The inertia is the mass-matrix diagonal ``M_ii``. Where axes are nearly aligned and rotors light (a tree of
    arms) the inverse mass matrix couples the joints strongly, and gains from ``M_ii`` can make the sampled loop
    unstable although each joint alone would be fine: the recording diverges. ``retuned=True`` (the simulator's
    second attempt after such a run, :data:`TRACKING_LIMIT`) takes each joint's inertia with the other joints free,
    ``1 / (M^-1)_ii``, and lowers the bandwidth if ``dt M^-1 Kd`` still exceeds ``LOOP_DAMPING_LIMIT`` on the
    reference's poses. The retune is a fallback, not the default: on arms whose loop tracks (the Panda with a hidden
    spring) the lower gains of the coupled inertia interact with the integral term and can diverge themselves.
    """
    omega = 2.0 * np.pi * bandwidth_hz
    mass = mass_matrix(model, data, q_ref[0])
    inertia = mass.diagonal().copy()
    if retuned:
        dt = 1.0 / rate
        poses = q_ref[np.linspace(0, q_ref.shape[0] - 1, min(16, q_ref.shape[0])).astype(int)]
        inertia = 1.0 / np.linalg.inv(mass).diagonal()
        worst = _loop_damping(model, data, poses, 2.0 * damping_ratio * inertia * omega, dt)
        if worst > LOOP_DAMPING_LIMIT:
            omega *= LOOP_DAMPING_LIMIT / worst
    kp, kd = inertia * omega**2, 2.0 * damping_ratio * inertia * omega
    ki = integral_gain * inertia * omega**3
    return kp, kd, ki


def tracks(q, q_ref) -> bool:
    """Whether a simulated run followed its reference: finite and never farther than :data:`TRACKING_LIMIT`."""
    return bool(np.all(np.isfinite(q)) and np.abs(q - q_ref).max() <= TRACKING_LIMIT)
