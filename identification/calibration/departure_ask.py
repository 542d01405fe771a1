"""A counterbalance the links take inside their envelopes: the data ask for it by its gravity departure, not a refusal.

``clear_ask`` names a counterbalance or spring only where the data clearly ask for it, and measures that by the torque
the bounds refuse on its joint. A balancer whose torque has the shape of a gravity torque is not refused where the
links' first moments can take it inside their envelopes: beside a tool at the flange they do (the heavy virtual arm:
link 2 takes joint 2's cam up to its envelope, the bounds refuse joint 2 less than its noise, a noise that holds the
bursts a static friction model leaves at each velocity reversal). What the data give that joint then is its gravity
departure: the fitted gravity torque leaving the robot file's on that joint alone, by a share of its gravity no
robot file's error gives (``gravity_departure``), which named the link (``envelope_report.named_by_departure``).

The departure asks for the balancer as the refused torque does for an effect outside the envelopes: where the data's
own least squares (unbounded: what the data ask, not what the bounds made of it) depart on that joint alone too, by
at least ``clear_ask.NAME_SIGMA`` noise levels of the joint in RMS torque (the noise the refused torque is judged
against). A departure the bounded fit shows and the least squares do not (the bounds pressed a link into it) asks
for nothing.
"""

from __future__ import annotations

import numpy as np

from identification.calibration.gravity_departure import theta_departures

__all__ = ["departed_noise"]


def departed_noise(robot, model, recordings, theta_ols, named, sigma) -> np.ndarray:
    """Per joint, the RMS torque [in noise levels ``sigma`` of the joint, or a callable giving them] by which the
    gravity torque of the data's own least squares (base parameters ``theta_ols``, on the prepared training
    ``recordings``) departs from the robot file's on that joint alone (``gravity_departure.theta_departures``), on the
    joints of ``named`` (the bounded fit's departures that named a pushed link: ``{0-based joint: ...}``); 0 on every
    other joint, and where the least squares do not depart on it alone (module docstring)."""
    out = np.zeros(robot.n_dof)
    theta_ols = np.asarray(theta_ols, dtype=float)[: model.n_base]
    if not named or not np.all(np.isfinite(theta_ols)):
        return out
    sigma = np.asarray(sigma() if callable(sigma) else sigma, dtype=float)
    own = theta_departures(robot, model, recordings, theta_ols)
    for j in named:
        if j in own:
            out[j] = own[j].departure / max(float(sigma[j]), 1e-12)
    return out
