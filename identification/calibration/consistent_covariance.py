"""The covariance of a consistent fit's base and drive parameters: the least squares' with the pull's precision added.

The least-squares estimate ``x_ls = (theta, drive)`` has the sandwich covariance ``C`` (``residual_correlation``: the
residual's correlation time counted, so ``C^-1`` is the information the data hold). The consistent fit
(``consistent_fit``) minimises, in those units, ``chi^2 / c + pull / u^2`` (``prior_pull``): the data's term and the
pull towards the robot file, a Gaussian prior on the links' standard parameters ``p ~ N(p_file, S)`` with
``S = diag(PriorPull.standard_deviations)^2``. The base parameters are ``theta = P p`` (the model's map, rotors
included), so the prior states ``theta ~ N(P p_file, P S P^T)`` (the directions of ``p`` that no base parameter
holds integrate out exactly), and nothing about the drive parameters. The Laplace (Gauss-Newton; the data term is
quadratic, so exact) covariance of the fit at its solution is then

    C_fit = (C^-1 + [ (P S P^T)^-1  0 ; 0  0 ])^-1 = C - C H^T (H C H^T + P S P^T)^-1 H C,

with ``H = [I 0]`` taking ``theta`` out of ``x``: the Kalman form, which needs no inverse of ``C`` (a held column's
rows are zero) nor of ``P S P^T``. It is never larger than ``C`` and much smaller where the data hardly fix a
direction that the pull holds (a 4 s recording: :func:`consistent_covariance`).

What it leaves out, and why:

- **The envelope's inequalities.** Where the solution presses a bound (a link on its ellipsoid, a mass at 0.5 or 2 x
  the file's, a friction at 0), the constraint holds the estimate on one side of it; it does not fix it. The
  estimate's spread there is truncated, not removed: projecting the covariance onto the active constraints' tangent
  space would state zero spread across the bound, and a truth inside it would then lie infinitely many standard
  deviations away. Barrier terms are left out for the same reason (at the path's end their curvature is the
  barrier's weight over the squared slack). So ``C_fit`` is the unconstrained Laplace covariance: wider than the
  truncated spread across an active bound, right elsewhere.
- **The flange bodies' pull** (unknown payloads): their block is not in the stored parameters; the payloads' own
  covariance stays the least-squares one.

Is the pull an honest prior? It is a regulariser read as one: the robot file is no measurement, and ``u`` = 2 (twice
each parameter's size; the masses to 35 %, as the mass bounds state them) is a wide statement, chosen for what it
holds, not calibrated on how far files are off. Where the file is off by much less than that (CAD inertia 10-20 %),
the prior is conservative and so is ``C_fit``; where the fit is pulled towards a file that is off by more, the
estimate carries a bias that no covariance states. Measured both ways on the flange payload check's +- (virtual Denso,
0.8 kg unknown load, calibrated on an empty and a known-load 4 s recording, 10 x 6 cases,
``test_payload_check_coverage``): with the arm equal to its robot file RMS z 0.91 and the truth within 2 sd in 59 of 60
(0.75 and 60 of 60 from the least squares' covariance: too wide); with its links' masses 50 % off the file's (and
their centres of mass and inertias up to 50 %) 0.89 and 59 of 60. Trained on one 4 s recording alone (12 x 6): 1.16
and 66 of 72 (least squares 0.82, 70 of 72): there the friction the fit cannot follow (the virtual arm's LuGre) is an
error of the model that neither covariance states, and the least squares' wider one happened to cover it. On 8 s
recordings (5 x 6) 1.03 and 30 of 30 (0.94).
"""

from __future__ import annotations

import numpy as np

from identification.calibration.consistent_fit import held_rotors, link_is_free, prior_standard
from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT

__all__ = ["consistent_covariance"]


def consistent_covariance(covariance, model, robot, pull, held_links=()) -> np.ndarray:
    """The consistent fit's covariance of the base then drive parameters (module docstring).

    Parameters
    ----------
    covariance : array (n_base + n_drive, n_base + n_drive)
        The least-squares (sandwich) covariance of the base then drive parameters, ``C``.
    model : PSDMModel
        The model whose map the consistent fit used (``merged_rotors``: with identify's merged rotors).
    robot : RobotDescription
        The robot file the fit was pulled towards (``consistent_fit.prior_standard``).
    pull : PriorPull
        The pull the fit used (``FitBounds.prior``).
    held_links : tuple of int
        Links (0-based) the fit held at the robot file's (``TrajectoryOptions.held_links``): known, no variables, nor
        the drive inertias held with them (``consistent_fit.held_rotors``).

    Returns
    -------
    array (n_base + n_drive, n_base + n_drive)
        ``C_fit``, symmetric.
    """
    c = np.asarray(covariance, dtype=float)
    n, n_base, size = robot.n_dof, model.n_base, LINK_PARAMETER_COUNT + 1
    sd = pull.standard_deviations(prior_standard(robot)).reshape(-1)
    free = [i * size + k for i in range(n) if link_is_free(model, i) and i not in held_links
            for k in range(LINK_PARAMETER_COUNT)]  # fmt: skip
    held = held_rotors(robot, held_links)  # known with their links
    varied = free + [i * size + LINK_PARAMETER_COUNT for i in range(n) if i not in held]  # free links, free rotors
    mapped = np.asarray(model.parameter_map, dtype=float)[:, varied] * sd[varied]
    innovation = c[:n_base, :n_base] + mapped @ mapped.T
    out = c - c[:, :n_base] @ np.linalg.solve(innovation, c[:n_base, :])
    return 0.5 * (out + out.T)
