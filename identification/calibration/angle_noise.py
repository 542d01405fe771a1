"""A joint's noise that the effect judged cannot inflate: the denominator of ``clear_ask``'s rule.

``clear_ask`` names a counterbalance or spring, or a payload on a proximal link, only where the torque the bounds
refuse is large against the joint's noise. The data's own least squares hold no such effect, so their residual holds
the part of it their columns cannot give: a large effect raised the noise it was judged against, and a cam
counterbalance far above the sensor noise, whose harmonics the links cannot give, was named as none.

The noise the rule needs is that of the alternative: the same least squares with the named effects' columns. A
payload is the links' own columns already. A counterbalance or spring is a torque of its joint's own angle; on each
joint's rows a Fourier series of that joint's angle (``HARMONICS`` harmonics, sine and cosine) holds any such law the
recorded travel shows: the library's cam is two harmonics, a gas spring's lever law and a spring series over a
travel shorter than a turn a few more. What they leave is the noise and what no torque of the angle explains (the
residual sigma of that fit, as the least squares' own: ``weighted_least_squares``). A robot file off beyond its
bounds, or a rotor inertia it does not state, is held by the least squares' own columns, so the noise it is judged
against stays the plain least squares' (the false alarms the rule was made for stay below it). A model error that is
no torque of the angle stays in it: the bursts a model without friction dynamics leaves at each velocity reversal.
Their median absolute deviation would drop those too, but it drops as much of a plain arm's residual and names a
spring a link held at its reach does not have (``tests/identification/test_clear_ask.py``).

A constant is no torque of the angle, but a Fourier series over a travel shorter than a turn gives one, and a torque
offset the model lacks (its column off, forced or refused) then passed for a counterbalance: the series took the
offset, the links it had bent fitted the other joints again, and a torque the bounds refused because of the offset
was judged against a noise the offset no longer raised (a true offset on the Denso's joint 2 named "a counterbalance
on joint 1"). So only what the series explains beyond a torque offset per joint is credited: the noise is the least
squares' residual less what the series adds to an offset (in variance: the fit with an offset per joint, against the
fit with the offset and the series). A counterbalance's torque of one sign over the travel, the part an offset gives
as well, stays in the noise: over a short travel the data cannot tell it from an offset. The fits with an offset alone
are kept (``JointNoise``): where a joint's own offset takes its noise well down, the data hold an offset the model
lacks there, which ``clear_ask`` names where it names no counterbalance. A joint whose model columns already hold its
offset (a drive column the data chose or forced, ``held_offsets``) gets no second one: it would be a column identical
to the model's, and on that joint the fits with and without the added offset are the same fit.

That noise keeps a counterbalance's part an offset gives as well, so ``clear_ask`` also asks how much of the torque
the bounds refuse is a torque of the joint's own angle beyond an offset (``AngleShare``, from the same pass's normal
equations), against the noise of the fit with the series and an offset (``JointNoise.own``). The pass also reads
which joints gravity can give a torque at the recorded poses (``JointNoise.carries``,
``gravity_load.joints_carrying_gravity``): a joint gravity gives none carries no counterbalance.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import numpy as np

from identification.calibration.configuration_check import accumulate
from identification.calibration.gravity_load import joints_carrying_gravity, recorded_poses
from identification.calibration.weighted_solve import weighted_least_squares

__all__ = [
    "COLLINEAR",
    "HARMONICS",
    "AngleColumns",
    "AngleShare",
    "JointNoise",
    "effect_free_noise",
    "held_offsets",
    "joint_noise",
]

#: Harmonics of each joint's angle in the alternative's columns: a counterbalance's law over the recorded travel.
HARMONICS = 4
#: A model column whose cosine with a joint's constant column is within this of 1 is that joint's torque offset.
COLLINEAR = 1e-9


class AngleShare:
    """Per joint, the part of a torque of the model's columns (a direction ``delta`` of its parameters: what the
    bounds refuse) that a torque of the joint's own angle gives beyond a torque offset: on the joint's rows, its
    projection on the Fourier series of the angle and a constant, less its projection on the constant alone, in RMS
    [N m]. From the normal equations of ``AngleColumns`` with ``offset`` (``equations``, the model's ``n_columns``
    first): each joint's series and constant are on its own rows alone, so its gram holds the products needed."""

    def __init__(self, equations, n_columns: int, harmonics: int = HARMONICS):
        n_dof, width = equations.n_dof, 2 * harmonics
        self.n_columns, self.count = n_columns, np.maximum(equations.count, 1)
        series = [range(n_columns + j * width, n_columns + (j + 1) * width) for j in range(n_dof)]
        own = [[*k, n_columns + width * n_dof + j] for j, k in enumerate(series)]  # the series, then the constant
        self.cross = [equations.gram[j][np.ix_(k, range(n_columns))] for j, k in enumerate(own)]
        self.inverse = [np.linalg.pinv(equations.gram[j][np.ix_(k, k)], rcond=1e-12, hermitian=True)
                        for j, k in enumerate(own)]  # fmt: skip
        self.constant = np.array([equations.gram[j][k[-1], k[-1]] for j, k in enumerate(own)])
        self.model = equations.gram[:, :n_columns, :n_columns]

    def rms(self, delta) -> np.ndarray:
        """Per joint [N m RMS]: the part of the torque of ``delta`` (the model's first columns; zero beyond them)
        that a torque of the joint's own angle gives beyond an offset."""
        return np.sqrt(self._energies(delta)[0] / self.count)

    def share(self, delta) -> np.ndarray:
        """Per joint, the share of the torque of ``delta`` beyond its offset (its energy less its projection on a
        constant) that a torque of the joint's own angle gives: near 1 for a torque of that angle alone."""
        angle, varying = self._energies(delta)
        return angle / np.maximum(varying, 1e-300)

    def _energies(self, delta) -> tuple:
        """Per joint, the energies of the torque of ``delta``: its projection on the angle's series and a constant
        less that on the constant, and the whole less that on the constant."""
        delta = np.zeros(self.n_columns) if delta is None else np.asarray(delta, dtype=float)
        d = np.zeros(self.n_columns)
        d[: min(delta.size, self.n_columns)] = delta[: self.n_columns]
        angle, varying = np.zeros(len(self.cross)), np.zeros(len(self.cross))
        for j, (cross, inverse) in enumerate(zip(self.cross, self.inverse)):
            b = cross @ d
            constant = b[-1] ** 2 / max(float(self.constant[j]), 1e-300)
            angle[j], varying[j] = float(b @ inverse @ b) - constant, float(d @ self.model[j] @ d) - constant
        return np.maximum(angle, 0.0), np.maximum(varying, 0.0)


class JointNoise(NamedTuple):
    """Per joint [N m]: ``noise``, the one the effect cannot inflate (module docstring); ``offset``, the least
    squares' residual sigma with a torque offset on every joint, and ``others``, theirs with one on every other joint
    (well above ``offset``: the joint's data hold an offset the model lacks; an offset elsewhere bends the links
    every joint's rows share, and the offsets on the other joints take that). ``own``: theirs with the offset and
    the series of the angle on every joint, the noise neither a torque of the angle nor an offset inflates;
    ``angle``: the ``AngleShare`` of a torque the model's columns give; ``carries``: per joint, whether gravity can
    give it a torque at the recorded poses (``gravity_load.joints_carrying_gravity``: a joint it gives none carries no
    counterbalance; None: not known)."""

    noise: np.ndarray
    offset: np.ndarray
    others: np.ndarray
    own: np.ndarray | None = None
    angle: AngleShare | None = None
    carries: np.ndarray | None = None


class AngleColumns:
    """A recording's extra columns (``extra``: an object with ``columns(q, qd, qdd)``, or None) followed by, on each
    joint's rows, ``cos(k q_j)`` and ``sin(k q_j)`` for ``k = 1..harmonics`` (``2 harmonics`` columns per joint,
    joint after joint; zero on the other joints' rows), then with ``offset`` a constant 1 on each joint's rows (one
    column per joint)."""

    def __init__(self, extra, n_dof: int, harmonics: int = HARMONICS, offset: bool = False):
        self.extra, self.n_dof, self.harmonics, self.offset = extra, n_dof, harmonics, offset

    @property
    def series(self) -> int:
        """The number of angle columns."""
        return 2 * self.harmonics * self.n_dof

    @property
    def width(self) -> int:
        """The number of columns after the extra's: the angle's, then (``offset``) one constant per joint."""
        return self.series + (self.n_dof if self.offset else 0)

    def columns(self, q, qd, qdd) -> np.ndarray:
        """(n_samples, n_dof, extra's columns + ``width``)."""
        q = np.asarray(q, dtype=float)
        angle = q[:, :, None] * np.arange(1, self.harmonics + 1)  # (n, n_dof, harmonics)
        series = np.concatenate([np.cos(angle), np.sin(angle)], axis=2)
        block = np.zeros((q.shape[0], self.n_dof, self.width))
        width = 2 * self.harmonics
        for j in range(self.n_dof):
            block[:, j, j * width : (j + 1) * width] = series[:, j]
            if self.offset:
                block[:, j, self.series + j] = 1.0
        return block if self.extra is None else np.concatenate([self.extra.columns(q, qd, qdd), block], axis=2)


def effect_free_noise(robot, model, prepared, extras, setup, n_columns: int, free, payload=range(0)):
    """A callable giving, once asked, per joint the ``JointNoise`` of the data's own least squares
    (``weighted_least_squares`` over the ``free`` of ``n_columns`` columns, ``payload`` the unknown payloads'): their
    residual sigma less what, on each joint's rows, a Fourier series of its own angle (``AngleColumns``) explains
    beyond a torque offset per joint (module docstring). ``prepared``, ``extras`` and ``setup`` are the fit's
    (``configuration_check.accumulate``); asked, it makes one more pass over the recordings."""
    return partial(_noise, robot, model, prepared, extras, setup, n_columns, free, payload)


def _noise(robot, model, prepared, extras, setup, n_columns: int, free, payload) -> JointNoise:
    """``effect_free_noise``'s noise, computed."""
    wrapped = [AngleColumns(extra, robot.n_dof, offset=True) for extra in extras]
    width = wrapped[0].width if wrapped else 0
    equations, _ = accumulate(robot, model, prepared, wrapped, setup, n_columns + width)
    carries = joints_carrying_gravity(robot, recorded_poses(prepared)) if prepared else None
    return joint_noise(equations, n_columns, free, payload)._replace(carries=carries)


def joint_noise(equations, n_columns: int, free, payload=range(0), harmonics: int = HARMONICS) -> JointNoise:
    """The ``JointNoise`` of normal ``equations`` whose first ``n_columns`` columns are the model's (the ``free`` of
    them fitted, ``payload`` the unknown payloads') and the rest ``AngleColumns`` with ``offset`` (``harmonics``),
    without ``carries``. A joint whose model columns already hold a torque offset (a column collinear with that
    joint's constant, ``held_offsets``) gets no second one: two identical columns make the solve's normal matrix
    singular in a direction its rounding does not cut, and the figure was unreliable."""
    n_dof = equations.n_dof
    width = (2 * harmonics + 1) * n_dof if equations.n_columns > n_columns else 0
    series = width - n_dof if width else 0
    free = np.asarray(free, dtype=int).tolist()
    held = held_offsets(equations, n_columns, free, n_columns + series) if width else np.zeros(n_dof, dtype=bool)
    offsets = [n_columns + series + j if width and not held[j] else None for j in range(n_dof)]
    added = [k for k in offsets if k is not None]
    plain = weighted_least_squares(equations, free, payload)[0]
    constant = weighted_least_squares(equations, [*free, *added], payload)[0]
    both = weighted_least_squares(equations, [*free, *added, *range(n_columns, n_columns + series)], payload)[0]
    others = [weighted_least_squares(equations, [*free, *(k for k in added if k != offsets[j])], payload)[0][j]
              for j in range(n_dof)]  # fmt: skip
    noise = np.sqrt(np.clip(plain**2 - constant**2 + both**2, both**2, plain**2))
    others = np.asarray(others, dtype=float).reshape(constant.shape)
    angle = AngleShare(equations, n_columns, harmonics) if width else None
    return JointNoise(noise, constant, others, both, angle)


def held_offsets(equations, n_columns: int, free, first: int) -> np.ndarray:
    """Per joint, whether one of the ``free`` model columns (of the first ``n_columns`` of ``equations``) is a torque
    offset of that joint: collinear (to ``COLLINEAR``) with the constant on its rows, column ``first + j``."""
    model = [k for k in free if k < n_columns]
    energy = equations.gram[:, model, model].sum(axis=0)  # each column over all rows
    out = np.zeros(equations.n_dof, dtype=bool)
    for j in range(equations.n_dof):
        ones = equations.gram[j, first + j, first + j]
        cross = equations.gram[j, model, first + j]  # the constant is zero on the other joints' rows
        out[j] = bool(np.any(cross**2 >= (1.0 - COLLINEAR) * energy * ones)) if ones > 0 else False
    return out
