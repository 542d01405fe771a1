"""Limits of an excitation trajectory: joint position, velocity, acceleration, torque and a keep-out plane.

``JointLimits`` holds the limits; ``limit_margins`` measures how far a sampled trajectory is from
them (relative, >= 0 when every limit holds); ``verify_limits`` checks a trajectory on a grid ten
times finer than the optimisation grid; ``scale_into_limits`` shrinks a trajectory's oscillation
joint by joint until the kinematic limits hold (used for random feasible starts and as a repair).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError, ShapeError

LIMIT_KINDS = ("q", "qd", "qdd", "tau", "keep_out")


def _vector(owner: str, field: str, value, n_dof: int, fix: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n_dof, float(arr))
    arr = arr.reshape(-1)
    if arr.shape != (n_dof,):
        raise ShapeError(f"{owner}.{field} must have {n_dof} entries (one per joint); got {arr.shape[0]}. {fix}")
    if np.any(np.isnan(arr)):
        raise ParameterError(f"{owner}.{field} must not contain NaN; got {arr.tolist()}. {fix}")
    return arr


@dataclass(frozen=True)
class JointLimits:
    """Symmetric velocity/acceleration/torque limits and a position range per joint.

    Parameters
    ----------
    q_min, q_max : array, shape (n_dof,)
        Position range [rad or m]; ``q_min < q_max``.
    qd_max, qdd_max : array, shape (n_dof,)
        Velocity [rad/s] and acceleration [rad/s^2] limits, positive: ``|qd| <= qd_max``.
    tau_max : array, shape (n_dof,), optional
        Torque limit [N m], positive; None (default) does not constrain torque.

    Examples
    --------
    >>> limits = JointLimits(q_min=[-1, -1], q_max=[1, 1], qd_max=[2, 2], qdd_max=[5, 5])
    >>> limits.n_dof
    2
    """

    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    qdd_max: np.ndarray
    tau_max: np.ndarray | None = None

    def __post_init__(self):
        n = np.asarray(self.q_min, dtype=float).reshape(-1).shape[0]
        fix = "Give one value per joint."
        q_min = _vector("JointLimits", "q_min", self.q_min, n, fix)
        q_max = _vector("JointLimits", "q_max", self.q_max, n, fix)
        bad = np.flatnonzero(~(q_min < q_max))
        if bad.size:
            i = int(bad[0])
            raise ParameterError(
                f"JointLimits.q_min must be below q_max for every joint; got q_min={q_min[i]} >= q_max={q_max[i]} "
                f"on joint {i + 1}. Swap them or widen the range."
            )
        object.__setattr__(self, "q_min", q_min)
        object.__setattr__(self, "q_max", q_max)
        for key in ("qd_max", "qdd_max", "tau_max"):
            value = getattr(self, key)
            if value is None:
                continue
            arr = _vector("JointLimits", key, value, n, fix)
            bad = np.flatnonzero(~(arr > 0))
            if bad.size:
                i = int(bad[0])
                raise ParameterError(
                    f"JointLimits.{key} must be positive on every joint (no motion is possible otherwise); "
                    f"got {arr[i]} on joint {i + 1}. Give the magnitude of the limit, e.g. the datasheet value, "
                    "or lock the joint out of the model."
                )
            object.__setattr__(self, key, arr)

    @property
    def n_dof(self) -> int:
        return self.q_min.shape[0]

    @property
    def center(self) -> np.ndarray:
        return 0.5 * (self.q_min + self.q_max)

    @property
    def half_range(self) -> np.ndarray:
        return 0.5 * (self.q_max - self.q_min)

    @classmethod
    def from_robot(cls, robot, *, torque: bool = False, scale: float = 1.0) -> JointLimits:
        """Limits of a RobotDescription, optionally with the torque limits and a common scale.

        Parameters
        ----------
        robot : RobotDescription
        torque : bool
            Include ``robot.tau_max`` (joints with an infinite limit are left free).
        scale : float
            Factor in (0, 1] on the velocity, acceleration and torque limits and on the half range
            about the centre of the position range.
        """
        if not (isinstance(scale, (int, float)) and 0 < scale <= 1):
            raise ParameterError(f"JointLimits.from_robot scale must be in (0, 1]; got {scale!r}. Use e.g. 0.9.")
        center, half = 0.5 * (robot.q_min + robot.q_max), 0.5 * (robot.q_max - robot.q_min)
        tau = robot.tau_max * scale if torque else None
        return cls(
            q_min=center - scale * half,
            q_max=center + scale * half,
            qd_max=robot.qd_max * scale,
            qdd_max=robot.qdd_max * scale,
            tau_max=tau,
        )

    def shrunk(self, backoff: float) -> JointLimits:
        """Limits tightened by the fraction ``backoff`` (positions about the centre of their range)."""
        factor = 1.0 - backoff
        tau = None if self.tau_max is None else self.tau_max * factor
        return JointLimits(
            q_min=self.center - factor * self.half_range,
            q_max=self.center + factor * self.half_range,
            qd_max=self.qd_max * factor,
            qdd_max=self.qdd_max * factor,
            tau_max=tau,
        )


@dataclass(frozen=True)
class KeepOut:
    """Keep a point of the robot on one side of a plane: ``normal . p(q) >= offset`` on every sample.

    Parameters
    ----------
    point : casadi.Function
        ``q (n_dof) -> p (3)``: position of the point in the base frame [m], e.g. from
        ``build_dh_point_function``.
    normal : array, shape (3,)
        Plane normal pointing into the allowed side (normalised on construction).
    offset : float
        Plane offset [m]: for a floor at height ``h`` below a z-up base, ``normal=(0,0,1)``, ``offset=-h``.
    margin : float
        Extra clearance [m] demanded on the optimisation grid so that the plane also holds between
        samples (the verification on the fine grid uses the plane itself).
    """

    point: ca.Function
    normal: np.ndarray
    offset: float = 0.0
    margin: float = 0.01

    def __post_init__(self):
        if not isinstance(self.point, ca.Function) or self.point.n_in() != 1 or self.point.numel_out(0) != 3:
            raise ParameterError(
                "KeepOut.point must be a casadi.Function q -> p with one input and a 3-vector output; "
                f"got {self.point!r}. Build it with build_dh_point_function(robot, tool_point)."
            )
        normal = np.asarray(self.normal, dtype=float).reshape(-1)
        if normal.shape != (3,) or not np.all(np.isfinite(normal)) or np.linalg.norm(normal) == 0:
            raise ParameterError(
                f"KeepOut.normal must be a non-zero 3-vector; got {self.normal!r}. Use e.g. (0, 0, 1)."
            )
        object.__setattr__(self, "normal", normal / np.linalg.norm(normal))
        object.__setattr__(self, "offset", float(self.offset))
        if not (isinstance(self.margin, (int, float)) and self.margin >= 0):
            raise ParameterError(f"KeepOut.margin must be a non-negative distance [m]; got {self.margin!r}. Use 0.01.")

    def distance(self, q: np.ndarray) -> np.ndarray:
        """Signed distance [m] of the point from the plane for each row of q, shape (n_samples,)."""
        q = np.atleast_2d(q)
        p = np.asarray(self.point.map(q.shape[0])(q.T)).reshape(3, -1)
        return self.normal @ p - self.offset


def build_dh_point_function(robot, tool_point=(0.0, 0.0, 0.0)) -> ca.Function:
    """Forward kinematics of a point fixed in the last DH frame, as a CasADi Function ``q -> p``.

    Parameters
    ----------
    robot : RobotDescription
        A DH robot (``convention`` "standard" or "modified"); URDF robots are not supported here.
    tool_point : array, shape (3,)
        The point in the last link frame [m].

    Returns
    -------
    casadi.Function
        Named ``tool_point`` with input ``q`` (n_dof) and output ``p`` (3) in the base frame [m].
    """
    if getattr(robot, "urdf_path", None):
        raise ParameterError(
            f"build_dh_point_function robot must be a DH robot; got the URDF robot {robot.name!r}. "
            "Write the point's forward kinematics as a casadi.Function q -> p yourself."
        )
    q = ca.SX.sym("q", robot.n_dof)
    transform = ca.SX.eye(4)

    def rot(axis, angle):
        c, s = ca.cos(angle), ca.sin(angle)
        m = ca.SX.eye(4)
        i, j = {"x": (1, 2), "z": (0, 1)}[axis]
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
        return m

    def trans(axis, length):
        m = ca.SX.eye(4)
        m[{"x": 0, "z": 2}[axis], 3] = length
        return m

    for i, joint in enumerate(robot.joints):
        theta = joint.theta + (q[i] if joint.is_revolute else 0)
        d = joint.d + (q[i] if not joint.is_revolute else 0)
        if robot.convention == "standard":
            step = rot("z", theta) @ trans("z", d) @ trans("x", joint.a) @ rot("x", joint.alpha)
        else:
            step = rot("x", joint.alpha) @ trans("x", joint.a) @ rot("z", theta) @ trans("z", d)
        transform = transform @ step
    point = ca.vertcat(*[float(v) for v in np.asarray(tool_point, dtype=float).reshape(3)], 1)
    p = (transform @ point)[:3]
    return ca.Function("tool_point", [q], [p], ["q"], ["p"])


def limit_margins(limits: JointLimits, q, qd, qdd, tau=None, keep_out=None) -> dict:
    """Smallest relative margin to each kind of limit over the samples (>= 0 when the limit holds).

    Margins are relative: ``(qd_max - |qd|) / qd_max`` for velocity, acceleration and torque,
    the distance to the nearer end of the range over the half range for position, and the
    distance to the plane in metres for the keep-out.

    Returns
    -------
    dict
        ``{"q": float, "qd": float, "qdd": float[, "tau": float][, "keep_out": float]}``, each the
        minimum over samples and joints; also ``"joint"`` entries naming where the minimum is.
    """
    q, qd, qdd = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    if q.shape[1] != limits.n_dof:
        raise ShapeError(f"q must have {limits.n_dof} columns to match JointLimits.n_dof; got {q.shape[1]}.")
    per_joint = {
        "q": (np.minimum(q - limits.q_min, limits.q_max - q) / limits.half_range).min(axis=0),
        "qd": (1.0 - np.abs(qd) / limits.qd_max).min(axis=0),
        "qdd": (1.0 - np.abs(qdd) / limits.qdd_max).min(axis=0),
    }
    if tau is not None and limits.tau_max is not None:
        finite = np.isfinite(limits.tau_max)
        margin = np.ones(limits.n_dof)
        margin[finite] = (1.0 - np.abs(np.atleast_2d(tau)[:, finite]) / limits.tau_max[finite]).min(axis=0)
        per_joint["tau"] = margin
    out = {kind: float(values.min()) for kind, values in per_joint.items()}
    out["joint"] = {kind: int(np.argmin(values)) + 1 for kind, values in per_joint.items()}
    if keep_out is not None:
        out["keep_out"] = float(keep_out.distance(q).min())
    return out


def worst_margin(margins: dict) -> float:
    """The smallest of the margins returned by ``limit_margins``."""
    return min(v for k, v in margins.items() if k in LIMIT_KINDS)


def fine_grid(parametrization, n_samples: int, factor: int = 10) -> np.ndarray:
    """A verification grid ``factor`` times finer than ``n_samples`` points over the trajectory."""
    return parametrization.default_grid(max(int(n_samples), 2) * factor)


def verify_limits(
    parametrization, x, limits: JointLimits, n_samples: int, *, torque_function=None, keep_out=None, factor: int = 10
) -> dict:
    """Margins of trajectory ``x`` on a grid ``factor`` times finer than the ``n_samples`` constraint grid.

    Parameters
    ----------
    parametrization : FourierTrajectory or SumOfSinesTrajectory
    x : array, shape (n_parameters,)
    limits : JointLimits
    n_samples : int
        Number of samples of the constraint grid the trajectory was optimised on.
    torque_function : casadi.Function, optional
        ``q, qd, qdd -> tau`` with nominal parameters; needed when ``limits.tau_max`` is set.
    keep_out : KeepOut, optional
    factor : int
        Refinement of the verification grid (10 by default).

    Returns
    -------
    dict
        As ``limit_margins``, plus ``"worst"`` (the smallest margin) and ``"n_samples"``.
    """
    t = fine_grid(parametrization, n_samples, factor)
    q, qd, qdd = parametrization.evaluate(t, x)
    tau = None
    if limits.tau_max is not None and torque_function is not None:
        tau = evaluate_mapped(torque_function, q, qd, qdd)
    margins = limit_margins(limits, q, qd, qdd, tau=tau, keep_out=keep_out)
    margins["worst"] = worst_margin(margins)
    margins["n_samples"] = t.shape[0]
    return margins


def evaluate_mapped(function: ca.Function, *columns) -> np.ndarray:
    """Evaluate a per-sample Function ``(n_dof,) x k -> (n_out,)`` on rows of arrays, shape (n_samples, n_out)."""
    n_samples = columns[0].shape[0]
    out = function.map(n_samples)(*[np.asarray(c, dtype=float).T for c in columns])
    return np.asarray(out).T.reshape(n_samples, -1)


def scale_into_limits(parametrization, x, limits: JointLimits, t, *, fill: float = 1.0) -> np.ndarray:
    """Shrink each joint's oscillation (never grow it) so that q, qd and qdd use at most ``fill`` of the limits.

    An offset outside the position range is first moved to the centre of the range. Only kinematic limits are
    handled; torque and keep-out limits are checked separately.

    Raises
    ------
    ParameterError
        When a joint's offset cannot lie inside its range (a sum of sines without offset whose range
        excludes 0).
    """
    offsets = parametrization.offsets(x)
    offsets = np.where((offsets > limits.q_min) & (offsets < limits.q_max), offsets, limits.center)
    x = parametrization.with_offsets(x, offsets)
    offsets = parametrization.offsets(x)
    inside = (offsets > limits.q_min) & (offsets < limits.q_max)
    if not np.all(inside):
        i = int(np.flatnonzero(~inside)[0])
        raise ParameterError(
            f"JointLimits.q_min/q_max of joint {i + 1} ([{limits.q_min[i]}, {limits.q_max[i]}]) must contain the "
            f"trajectory offset {offsets[i]}; a sum of sines without offset oscillates about 0. "
            "Use SumOfSinesTrajectory(offset=True)."
        )
    q, qd, qdd = parametrization.evaluate(t, x)
    dq = q - offsets[None, :]
    room = np.minimum(limits.q_max - offsets, offsets - limits.q_min)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.vstack(
            [
                np.abs(dq).max(axis=0) / room,
                np.abs(qd).max(axis=0) / limits.qd_max,
                np.abs(qdd).max(axis=0) / limits.qdd_max,
            ]
        )
    usage = np.nanmax(np.where(np.isfinite(ratios), ratios, np.inf), axis=0)
    scales = np.where(usage > fill, fill / np.maximum(usage, 1e-300), 1.0)
    return parametrization.scale_joints(x, scales)


def describe_violation(margins: dict) -> str:
    """A short text naming the limit kind and joint with the worst margin."""
    kind = min((k for k in margins if k in LIMIT_KINDS), key=lambda k: margins[k])
    joint = margins.get("joint", {}).get(kind)
    where = f" on joint {joint}" if joint is not None else ""
    return f"{kind}{where} (margin {margins[kind]:.3g})"


def check_same_dof(limits: JointLimits, n_dof: int) -> None:
    if limits.n_dof != n_dof:
        raise ShapeError(
            f"JointLimits must have one entry per joint ({n_dof}); got {limits.n_dof}. "
            "Build them with JointLimits.from_robot(robot)."
        )


__all__ = [
    "JointLimits",
    "KeepOut",
    "build_dh_point_function",
    "limit_margins",
    "worst_margin",
    "verify_limits",
    "scale_into_limits",
    "fine_grid",
    "evaluate_mapped",
    "describe_violation",
]
