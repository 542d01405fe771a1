"""Each joint's torque scale from recordings with and without a known payload: a datasheet torque constant that is off.

A recording of motor currents is read as torque through ``current x kt`` (``[transmission] motor_kt`` times the gear
ratio, or a ``[[drive]]`` table's ``kt``). A joint whose datasheet ``kt`` is 15 % off records 15 % too much torque,
and a rigid-body fit on unloaded recordings cannot see it: the joint's torque scale trades with the link and drive
parameters (an arm 15 % heavier reads the same). The fit absorbs it, and what the links cannot take was blamed on a
counterbalance or spring (a virtual 7-joint cobot with joint 2's ``motor_kt`` 15 % high).

A known payload fixes the absolute scale: its torque is stated, not fitted. With recordings that carry it and
recordings that do not (or carry another known load), the model

    tau_recorded_j = s_j * (Y_j theta + D_j f + P_j)

(``Y``: the base-parameter regressor, ``D``: Coulomb, viscous and the separate drive-inertia columns, ``P``: the
known payload's torque, zero without it) determines each joint's scale ``s_j`` where the payload's torque on that
joint is not itself a multiple of the arm's (:func:`torque_scales`). It is bilinear: alternating least squares (each
step exact for one factor given the other), then the Gauss-Newton covariance of ``(theta, f, s)`` with each joint's
residual variance grown by its correlation time. A joint the payload does not excite (a base joint about the
vertical, gravity only) keeps a wide or unbounded uncertainty and is reported as not determined, never as a finding.

A joint whose scale is off by more than :data:`MARGIN` and by more than :data:`SIGMAS` standard deviations is a
finding (:class:`TorqueScales`): it names the robot file's field and the value the payload's torque gives.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.payload import payload_torque
from identification.calibration.residual_correlation import residual_correlation_time
from identification.calibration.separate_inertia import separate_inertia_joints
from identification.calibration.trajectory_data import NormalEquations, drive_columns, prepare_recordings

__all__ = ["MARGIN", "SIGMAS", "TorqueScales", "compared_recordings", "corrected_robot_text", "torque_scales"]

#: A joint's torque scale off by less than this (relative) is not a finding, however sure: the friction and rigid
#: body models' own error moves a fitted scale by a few per cent.
MARGIN = 0.05
#: ... and it must be off by this many standard deviations.
SIGMAS = 3.0
#: Friction columns of the scale fit (its own: the identify route's column choice comes after it).
_TERMS = ("fc", "fv")
_COULOMB_VELOCITY = 0.05  # [rad/s]
_ITERATIONS = 200


@dataclass(frozen=True)
class TorqueScales:
    """Per joint, the recorded torque over the model's (``scale``, 1 when the constants are right) and its standard
    deviation (``std``, inf where the payloads do not determine it).

    ``kt`` are the joint-side torque constants the currents were read with (None for recorded torques), ``motor_kt``
    the robot file's ``[transmission] motor_kt`` when those came from it; ``loaded`` / ``unloaded`` name the
    recordings that carried a known payload and those that did not."""

    scale: np.ndarray
    std: np.ndarray
    joint_names: tuple
    kt: np.ndarray | None = None
    motor_kt: np.ndarray | None = None
    loaded: tuple = ()
    unloaded: tuple = ()
    margin: float = MARGIN

    @property
    def determined(self) -> np.ndarray:
        """Joints whose scale the payloads fix well enough to tell an error of ``margin``."""
        return np.isfinite(self.std) & (SIGMAS * self.std < self.margin)

    @property
    def off(self) -> np.ndarray:
        """Joints whose torque scale is off beyond the margin and beyond its uncertainty: the findings."""
        error = np.abs(self.scale - 1.0)
        return self.determined & (error > self.margin) & (error > SIGMAS * self.std)

    def corrected_kt(self) -> np.ndarray | None:
        """The joint-side torque constants with each finding's scale taken out (``kt / s``, through the rounded
        ``motor_kt`` when the file states one, so the model file's copy gives the same); None for torques."""
        if self.kt is None:
            return None
        if self.motor_kt is not None:
            return self.kt * self.corrected_motor_kt() / self.motor_kt
        return np.where(self.off, self.kt / self.scale, self.kt)

    def corrected_motor_kt(self) -> np.ndarray | None:
        """The ``[transmission] motor_kt`` with each finding's scale taken out (to 6 significant digits, as the
        model file's copy of the robot file states it); None without one."""
        if self.motor_kt is None:
            return None
        corrected = [float(f"{v:.6g}") for v in self.motor_kt / self.scale]
        return np.where(self.off, corrected, self.motor_kt)

    def corrected_robot(self, robot):
        """``robot`` reading currents through the corrected constants (its drives' ``kt``, its ``motor_kt``)."""
        kt = self.corrected_kt()
        if kt is None or robot.drives is None or not self.off.any():
            return robot
        drives = tuple(replace(d, kt=float(k)) for d, k in zip(robot.drives, kt))
        transmission = robot.transmission
        if transmission is not None and self.motor_kt is not None:
            transmission = replace(transmission, motor_kt=self.corrected_motor_kt())
        return replace(robot, drives=drives, transmission=transmission)

    def findings(self) -> list:
        """One sentence per joint whose torque constant is off, naming the field to fix and the value."""
        out = []
        for j in np.flatnonzero(self.off):
            s, sd = float(self.scale[j]), float(self.std[j])
            way = "high" if s > 1.0 else "low"
            head = (f"joint {j + 1} ({self.joint_names[j]}): its recorded torque reads {abs(s - 1.0) * 100:.0f} % "
                    f"{way} (scale {s:.3f} +/- {sd:.3f} from the known payload's torque on "
                    f"{compared_recordings(self.loaded, self.unloaded)})")  # fmt: skip
            if self.motor_kt is not None:
                fix = (f"its torque constant is off: [transmission] motor_kt[{j + 1}] = {self.motor_kt[j]:.4g} N m/A "
                       f"in the robot file; the payload gives {self.motor_kt[j] / s:.4g}")  # fmt: skip
            elif self.kt is not None:
                fix = (f"its torque constant is off: [[drive]] kt of joint {j + 1} = {self.kt[j]:.4g} N m/A (joint "
                       f"side) in the robot file; the payload gives {self.kt[j] / s:.4g}")  # fmt: skip
            else:
                fix = "its torque sensor's gain (or the torque's unit) is off: scale that joint's torque by 1/s"
            out.append(f"{head}: {fix}, not a spring or a counterbalance")
        return out

    def to_dict(self) -> dict:
        """The model file's ``identification.torque_scale`` block."""
        return {
            "scale": [float(v) for v in self.scale],
            "std": [float(v) if np.isfinite(v) else None for v in self.std],
            "determined": [bool(v) for v in self.determined],
            "off": [bool(v) for v in self.off],
            "margin": self.margin,
            "sigmas": SIGMAS,
            "loaded": list(self.loaded),
            "unloaded": list(self.unloaded),
            "corrected_kt": None if self.corrected_kt() is None else [float(v) for v in self.corrected_kt()],
            "findings": self.findings(),
        }


def torque_scales(robot, model, recordings, configurations, kt=None, cutoff_hz=None, names=None):
    """Each joint's torque scale (:class:`TorqueScales`), or None unless the recordings hold a known payload and a
    recording without it (or with another known one): with one load on every recording the scale is not
    determined. Recordings of unknown payloads are left out. ``kt``: the joint-side torque constants the currents
    are read with (None for torques); ``names``: the recordings' labels (default their ``name``)."""
    if configurations is None:
        return None
    names = [r.name or f"recording {k + 1}" for k, r in enumerate(recordings)] if names is None else list(names)
    chosen = [k for k, c in enumerate(configurations) if c.kind != "unknown"]
    loads = {configurations[k].name if configurations[k].kind == "known" else None for k in chosen}
    if len(loads) < 2 or all(load is None for load in loads):
        return None
    _, _, prepared = prepare_recordings(robot, [recordings[k] for k in chosen], kt, cutoff_hz)
    inertia_joints = separate_inertia_joints(model, robot)
    rows = [_rows(robot, model, ready, configurations[k], inertia_joints) for ready, k in zip(prepared, chosen)]
    equations = NormalEquations(robot.n_dof, rows[0][0].shape[2])
    for columns, tau in rows:
        equations.add(columns, tau)
    x, s, sigma = _alternate(equations)
    correlation = np.max([residual_correlation_time(_residual(columns, tau, x, s)) for columns, tau in rows], axis=0)
    std = _scale_std(equations, x, s, sigma**2 * correlation)
    motor_kt = None  # the file's motor_kt, when the currents are read through it (not a [[drive]] kt of its own)
    joint_kt = None if robot.transmission is None else robot.transmission.joint_kt
    if kt is not None and joint_kt is not None and np.allclose(kt, joint_kt, rtol=1e-9):
        motor_kt = np.asarray(robot.transmission.motor_kt, dtype=float)
    loaded = tuple(names[k] for k in chosen if configurations[k].kind == "known")
    return TorqueScales(scale=s, std=std, joint_names=tuple(robot.joint_names),
                        kt=None if kt is None else np.asarray(kt, dtype=float), motor_kt=motor_kt, loaded=loaded,
                        unloaded=tuple(names[k] for k in chosen if configurations[k].kind != "known"))  # fmt: skip


def _rows(robot, model, ready, configuration, inertia_joints) -> tuple:
    """(columns (n_samples, n_dof, n_base + drive + 1) with the known payload's torque last, recorded torque)."""
    q, qd, qdd = ready.q, ready.qd, ready.qdd
    load = np.zeros_like(q)
    if configuration.kind == "known":
        load = payload_torque(robot, configuration.payload, q, qd, qdd)
    drive = drive_columns(qd, qdd, _TERMS, inertia_joints, _COULOMB_VELOCITY)
    return np.concatenate([model.regressor(q, qd, qdd), drive, load[:, :, None]], axis=2), ready.tau


def _alternate(equations) -> tuple:
    """(x, s, sigma): alternating least squares of ``tau_j = s_j (A_j x + P_j)`` from the per-joint sums (the last
    column is ``P``), each joint weighted by its residual variance."""
    gram, moment, n = equations.gram, equations.moment, equations.n_columns - 1
    s, variance = np.ones(equations.n_dof), equations.energy / np.maximum(equations.count, 1)
    x = np.zeros(n)
    for _ in range(_ITERATIONS):
        w = 1.0 / np.maximum(variance, 1e-300)
        lhs = np.einsum("j,jab->ab", w * s**2, gram[:, :n, :n])
        rhs = np.einsum("j,ja->a", w * s, moment[:, :n] - s[:, None] * gram[:, :n, n])
        x = _solve(lhs, rhs)
        z = np.append(x, 1.0)
        predicted = np.einsum("a,jab,b->j", z, gram, z)  # ||A_j x + P_j||^2
        new = np.einsum("ja,a->j", moment, z) / np.maximum(predicted, 1e-300)
        variance = _residual_variance(equations, z, new)
        if np.max(np.abs(new - s)) < 1e-10:
            s = new
            break
        s = new
    return x, s, np.sqrt(variance)


def _residual_variance(equations, z, s) -> np.ndarray:
    cross = np.einsum("ja,a->j", equations.moment, z)
    square = np.einsum("a,jab,b->j", z, equations.gram, z)
    return np.maximum(equations.energy - 2.0 * s * cross + s**2 * square, 1e-300) / np.maximum(equations.count, 1)


def _solve(lhs, rhs) -> np.ndarray:
    """Least squares from normal equations with unit-diagonal scaling (a column the data leave out stays at 0)."""
    scale = np.sqrt(np.clip(np.diag(lhs), 1e-300, None))
    solution = np.linalg.lstsq(lhs / np.outer(scale, scale), rhs / scale, rcond=1e-12)[0]
    return solution / scale


def _residual(columns, tau, x, s) -> np.ndarray:
    return tau - s * (columns @ np.append(x, 1.0))


def _scale_std(equations, x, s, variance) -> np.ndarray:
    """Standard deviations of ``s`` from the Gauss-Newton information of ``(x, s)``; inf for a joint whose scale
    lies along a direction the data leave free (one load on every recording, a joint the load does not turn)."""
    gram, n, n_dof = equations.gram, equations.n_columns - 1, equations.n_dof
    z = np.append(x, 1.0)
    info = np.zeros((n + n_dof, n + n_dof))
    for j in range(n_dof):
        w = 1.0 / variance[j]
        info[:n, :n] += w * s[j] ** 2 * gram[j, :n, :n]
        cross = w * s[j] * (gram[j, :n, :] @ z)
        info[:n, n + j] += cross
        info[n + j, :n] += cross
        info[n + j, n + j] += w * (z @ gram[j] @ z)
    scale = np.sqrt(np.clip(np.diag(info), 1e-300, None))
    values, vectors = np.linalg.eigh(info / np.outer(scale, scale))
    free = values < 1e-10 * values[-1]
    inverse = (vectors[:, ~free] / values[~free]) @ vectors[:, ~free].T / np.outer(scale, scale)
    std = np.sqrt(np.clip(np.diag(inverse)[n:], 0.0, None))
    along_free = np.linalg.norm(vectors[n:, free], axis=1) > 1e-6
    return np.where(along_free, np.inf, std)


def compared_recordings(loaded, unloaded) -> str:
    """The recordings whose known loads fixed the scale: the loaded ones against the unloaded ones, or, where every
    recording carries a known load, the loads against each other (their difference fixes it)."""
    if unloaded:
        return f"{', '.join(loaded)} against {', '.join(unloaded)}"
    return f"{', '.join(loaded)} (their different known loads against each other; no recording without a load)"


def corrected_robot_text(text: str, motor_kt) -> str | None:
    """A robot file's text with its one ``motor_kt = [...]`` replaced by ``motor_kt`` (the model file's copy of the
    robot file, so every later command reads the currents as identify did); None when it has no single such line, or
    states a ``[[drive]]`` ``kt`` too (which must agree with ``motor_kt``: one changed alone would be refused)."""
    pattern = re.compile(r"(?m)^(\s*motor_kt\s*=\s*)\[[^\]]*\]")
    if len(pattern.findall(text)) != 1 or re.search(r"(?m)^\s*kt\s*=", text):
        return None
    values = ", ".join(f"{float(v)!r}" for v in motor_kt)
    return pattern.sub(lambda m: f"{m.group(1)}[{values}]", text)
