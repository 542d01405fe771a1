"""Extra physics for the virtual robot: small objects that add effects the PSDM model does not contain.

Each term subclasses ``ExtraPhysics`` and overrides one or more hooks:

- ``modify_model(robot, parameters)``: change the rigid-body truth before simulation (payload,
  gravity tilt, extra rotor inertia);
- ``torque(t, q, qd, tau_motor)``: a load torque the motors must supply, added to the joint torque
  balance ``M qdd + h + tau_friction + sum(torque) = tau_motor`` (spring, ripple, coupling, ...);
- ``measure(t, q, tau)``: a signal-level effect on the recorded joint positions and torques
  (offset, delay), applied after the simulation and before noise and quantisation.

``describe()`` returns the plain description stored beside a recording as truth. Terms hold
no mutable state; joints are numbered from 0.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from identification.data.payload import Payload as KnownPayload
from psdm_casadi.errors import ParameterError


class ExtraPhysics:
    """Base class of the extra-physics terms of the virtual robot; every hook defaults to no effect."""

    #: whether ``torque`` is overridden (the simulator skips the call per step otherwise)
    has_torque = False

    def validate(self, n_dof: int) -> None:
        """Raise ``ParameterError`` when the term does not fit a robot with ``n_dof`` joints."""

    def modify_model(self, robot, parameters):
        """Return ``(robot, parameters)`` with the term's change to the rigid-body truth.

        Parameters
        ----------
        robot : RobotDescription
        parameters : array, shape (n_dof, 11)
            Standard parameters (link-frame dynamic parameters and Im per joint).
        """
        return robot, parameters

    def torque(self, t: float, q: np.ndarray, qd: np.ndarray, tau_motor: np.ndarray) -> np.ndarray:
        """Load torque (n_dof,) [N m] the motors must supply at time ``t`` [s] in state ``(q, qd)``."""
        return np.zeros_like(q)

    def measure(self, t: np.ndarray, q: np.ndarray, tau: np.ndarray):
        """Return the recorded ``(q, tau)`` (n_samples, n_dof) given the true ones."""
        return q, tau

    def describe(self) -> dict:
        """Plain-data description (JSON-serialisable) for the truth file."""
        out = {"term": type(self).__name__}
        for key, value in asdict(self).items():
            out[key] = np.asarray(value).tolist() if isinstance(value, np.ndarray) else value
        return out


def _check_joint(owner: str, joint, n_dof: int) -> None:
    if not (isinstance(joint, (int, np.integer)) and 0 <= joint < n_dof):
        raise ParameterError(f"{owner}.joint must be a joint index 0..{n_dof - 1}; got {joint!r}.")


def _check_vector(owner: str, key: str, value, n_dof: int) -> None:
    arr = np.asarray(value, dtype=float)
    if arr.shape not in ((), (n_dof,)):
        raise ParameterError(f"{owner}.{key} must be a number or have shape ({n_dof},); got shape {arr.shape}.")


@dataclass(frozen=True)
class Spring(ExtraPhysics):
    """A spring on one joint (e.g. a gravity compensator or cable): load torque ``k (q - q0)``.

    Parameters
    ----------
    joint : int
    stiffness : float
        [N m/rad]
    q0 : float
        Rest position [rad].
    """

    joint: int
    stiffness: float
    q0: float = 0.0
    has_torque = True

    def validate(self, n_dof):
        _check_joint("Spring", self.joint, n_dof)

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        out[self.joint] = self.stiffness * (q[self.joint] - self.q0)
        return out


@dataclass(frozen=True)
class TorqueRipple(ExtraPhysics):
    """Torque ripple periodic in the joint angle (cogging): ``amplitude sin(harmonic q + phase)``."""

    joint: int
    amplitude: float
    harmonic: float = 6.0
    phase: float = 0.0
    has_torque = True

    def validate(self, n_dof):
        _check_joint("TorqueRipple", self.joint, n_dof)

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        out[self.joint] = self.amplitude * np.sin(self.harmonic * q[self.joint] + self.phase)
        return out


@dataclass(frozen=True)
class CoulombAsymmetry(ExtraPhysics):
    """Extra Coulomb friction in the positive direction only: ``delta (1 + tanh(qd / v)) / 2``."""

    joint: int
    delta: float
    smoothing_velocity: float = 1e-3
    has_torque = True

    def validate(self, n_dof):
        _check_joint("CoulombAsymmetry", self.joint, n_dof)

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        out[self.joint] = 0.5 * self.delta * (1.0 + np.tanh(qd[self.joint] / self.smoothing_velocity))
        return out


@dataclass(frozen=True)
class FrictionDrift(ExtraPhysics):
    """Coulomb friction growing linearly with time (warm-up, wear): ``rate t tanh(qd / v)``."""

    joint: int
    rate: float
    smoothing_velocity: float = 1e-3
    has_torque = True

    def validate(self, n_dof):
        _check_joint("FrictionDrift", self.joint, n_dof)

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        out[self.joint] = self.rate * t * np.tanh(qd[self.joint] / self.smoothing_velocity)
        return out


@dataclass(frozen=True)
class LoadDependentFriction(ExtraPhysics):
    """Friction proportional to the transmitted torque: ``coefficient |tau_motor| tanh(qd / v)``."""

    joint: int
    coefficient: float
    smoothing_velocity: float = 1e-3
    has_torque = True

    def validate(self, n_dof):
        _check_joint("LoadDependentFriction", self.joint, n_dof)

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        out[self.joint] = (
            self.coefficient * abs(tau_motor[self.joint]) * np.tanh(qd[self.joint] / self.smoothing_velocity)
        )
        return out


@dataclass(frozen=True)
class JointCoupling(ExtraPhysics):
    """Viscous coupling between joints (e.g. a wrist differential): load torque ``C qd``, C (n_dof, n_dof)."""

    matrix: np.ndarray
    has_torque = True

    def validate(self, n_dof):
        if np.asarray(self.matrix).shape != (n_dof, n_dof):
            raise ParameterError(
                f"JointCoupling.matrix must have shape ({n_dof}, {n_dof}); got {np.asarray(self.matrix).shape}."
            )

    def torque(self, t, q, qd, tau_motor):
        return np.asarray(self.matrix, dtype=float) @ qd


@dataclass(frozen=True)
class Payload(KnownPayload, ExtraPhysics):
    """A known body fixed to the flange (:class:`identification.data.payload.Payload`) as a virtual-robot effect.

    Same fields and validation as the data value; the effect adds its dynamic parameters to the
    last link of the rigid-body truth.
    """

    def modify_model(self, robot, parameters):
        parameters = np.array(parameters, dtype=float)
        parameters[-1, :10] += self.dynamic_parameters()
        return robot, parameters


@dataclass(frozen=True)
class GravityTilt(ExtraPhysics):
    """A base mounted off level: gravity rotated by ``angle`` [rad] about the base ``axis``."""

    angle: float
    axis: tuple = (1.0, 0.0, 0.0)

    def validate(self, n_dof):
        axis = np.asarray(self.axis, dtype=float)
        if axis.shape != (3,) or not np.linalg.norm(axis) > 0:
            raise ParameterError(f"GravityTilt.axis must be a non-zero 3-vector; got {self.axis!r}.")

    def modify_model(self, robot, parameters):
        axis = np.asarray(self.axis, dtype=float)
        axis = axis / np.linalg.norm(axis)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        rotation = np.eye(3) + np.sin(self.angle) * k + (1 - np.cos(self.angle)) * k @ k
        return replace(robot, gravity=rotation @ robot.gravity), parameters


@dataclass(frozen=True)
class ExtraRotorInertia(ExtraPhysics):
    """Rotor (drive) inertia [kg m^2] added to joints, shape () or (n_dof,): the nominal model lacks it."""

    inertia: object = 0.0

    def validate(self, n_dof):
        _check_vector("ExtraRotorInertia", "inertia", self.inertia, n_dof)

    def modify_model(self, robot, parameters):
        parameters = np.array(parameters, dtype=float)
        parameters[:, 10] += np.asarray(self.inertia, dtype=float)
        return robot, parameters


@dataclass(frozen=True)
class TorqueOffset(ExtraPhysics):
    """A constant offset [N m] on the recorded joint torque (current-sensor offset), shape () or (n_dof,)."""

    offset: object = 0.0

    def validate(self, n_dof):
        _check_vector("TorqueOffset", "offset", self.offset, n_dof)

    def measure(self, t, q, tau):
        return q, tau + np.asarray(self.offset, dtype=float)


@dataclass(frozen=True)
class SignalDelay(ExtraPhysics):
    """The recorded torque lags the recorded position by ``samples`` sample periods (a bus delay)."""

    samples: int = 1

    def validate(self, n_dof):
        if not (isinstance(self.samples, (int, np.integer)) and self.samples >= 0):
            raise ParameterError(f"SignalDelay.samples must be an integer >= 0; got {self.samples!r}.")

    def measure(self, t, q, tau):
        if self.samples == 0:
            return q, tau
        delayed = np.empty_like(tau)
        delayed[self.samples :] = tau[: -self.samples]
        delayed[: self.samples] = tau[0]
        return q, delayed


@dataclass(frozen=True)
class PositionDependentFriction(ExtraPhysics):
    """Coulomb friction that varies along the joint's travel (a tight spot of a gear or bearing):
    ``amplitude sin(harmonic q + phase) tanh(qd / v)``. Outside the diagnosis library (issue 16)."""

    joint: int
    amplitude: float
    harmonic: float = 1.0
    phase: float = 0.0
    smoothing_velocity: float = 1e-3
    has_torque = True

    def validate(self, n_dof):
        _check_joint("PositionDependentFriction", self.joint, n_dof)

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        j = self.joint
        out[j] = self.amplitude * np.sin(self.harmonic * q[j] + self.phase) * np.tanh(qd[j] / self.smoothing_velocity)
        return out


@dataclass(frozen=True)
class StribeckHump(ExtraPhysics):
    """A low-speed friction hump wider than the drive's Stribeck curve (a grease or seal effect):
    ``height exp(-(qd / velocity)^2) tanh(qd / v)``. Outside the diagnosis library (issue 16)."""

    joint: int
    height: float
    velocity: float = 0.2
    smoothing_velocity: float = 1e-3
    has_torque = True

    def validate(self, n_dof):
        _check_joint("StribeckHump", self.joint, n_dof)
        if not (np.isfinite(self.velocity) and self.velocity > 0):
            raise ParameterError(f"StribeckHump.velocity must be positive [rad/s]; got {self.velocity!r}.")

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        j = self.joint
        out[j] = self.height * np.exp(-((qd[j] / self.velocity) ** 2)) * np.tanh(qd[j] / self.smoothing_velocity)
        return out


@dataclass(frozen=True)
class CamCounterbalance(ExtraPhysics):
    """A counterbalance acting through a cam: ``amplitude sin(q - q0) (1 + lobe cos(2 (q - q0)))``, a torque
    that is neither linear in the angle (a spring) nor a single sine (gravity). It equals
    ``amplitude ((1 - lobe / 2) sin x + (lobe / 2) sin 3x)``, ``x = q - q0``: two harmonics of the diagnosis' torque
    ripple, and over a short travel a low-order spring series, so it is inside the library (``LobedCam`` is not)."""

    joint: int
    amplitude: float
    q0: float = 0.0
    lobe: float = 0.5
    has_torque = True

    def validate(self, n_dof):
        _check_joint("CamCounterbalance", self.joint, n_dof)

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        x = q[self.joint] - self.q0
        out[self.joint] = self.amplitude * np.sin(x) * (1.0 + self.lobe * np.cos(2.0 * x))
        return out


@dataclass(frozen=True)
class GasSpringCounterbalance(ExtraPhysics):
    """A gas-spring counterbalance: a strut of length ``l`` between a point at ``a`` [m] from the joint axis on the
    previous link and one at ``b`` [m] on the moving link, the two levers aligned at ``q = q0``.

    With ``x = q - q0`` the strut is ``l = sqrt(a^2 + b^2 - 2 a b cos x)`` long and pushes with ``F(l) = F0 + k (l0
    - l)`` [N] (a preload ``F0`` at length ``l0``, stiffness ``k`` [N/m] as the gas is compressed), giving the joint
    the torque ``F(l) a b sin(x) / l`` that opens the angle between the levers; the motors supply its opposite.
    """

    joint: int
    a: float
    b: float
    q0: float
    preload: float
    length0: float
    stiffness: float = 0.0
    has_torque = True

    def validate(self, n_dof):
        _check_joint("GasSpringCounterbalance", self.joint, n_dof)
        for key in ("a", "b", "length0"):
            if not getattr(self, key) > 0:
                raise ParameterError(f"GasSpringCounterbalance.{key} must be > 0 [m]; got {getattr(self, key)!r}.")
        if abs(self.a - self.b) < 1e-6:
            raise ParameterError("GasSpringCounterbalance.a and .b must differ (the strut would reach length 0).")
        if self.preload < 0:
            raise ParameterError(f"GasSpringCounterbalance.preload must be >= 0 [N]; got {self.preload!r}.")

    def strut_torque(self, q_joint):
        """The torque [N m] the strut gives the joint at angles ``q_joint`` (array, rad)."""
        x = np.asarray(q_joint, dtype=float) - self.q0
        length = np.sqrt(self.a**2 + self.b**2 - 2.0 * self.a * self.b * np.cos(x))
        force = self.preload + self.stiffness * (self.length0 - length)
        return force * self.a * self.b * np.sin(x) / length

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        out[self.joint] = -self.strut_torque(q[self.joint])
        return out


@dataclass(frozen=True)
class LobedCam(ExtraPhysics):
    """A spring-loaded follower on a cam with a single lobe (a counterbalance or detent that acts over part of the
    travel only): load torque ``amplitude u exp((1 - u^2) / 2)``, ``u = (q - q0) / width``.

    The follower's preloaded spring stores ``E(q) ~ exp(-u^2 / 2)`` as it rides over the lobe, so the torque is
    ``-dE/dq`` up to scale: restoring about ``q0``, largest (``amplitude`` [N m]) at ``q0 +- width`` [rad] and fading
    beyond. Over a travel of several ``width`` it is neither a low-order polynomial (a spring) nor a single
    harmonic of the angle (ripple, gravity): outside the diagnosis library (issue 16)."""

    joint: int
    amplitude: float
    q0: float = 0.0
    width: float = 0.3
    has_torque = True

    def validate(self, n_dof):
        _check_joint("LobedCam", self.joint, n_dof)
        if not (np.isfinite(self.width) and self.width > 0):
            raise ParameterError(f"LobedCam.width must be positive [rad]; got {self.width!r}.")

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        u = (q[self.joint] - self.q0) / self.width
        out[self.joint] = self.amplitude * u * np.exp(0.5 * (1.0 - u * u))
        return out


EXTRA_PHYSICS_TERMS = {
    cls.__name__: cls
    for cls in (
        Spring,
        TorqueRipple,
        CoulombAsymmetry,
        FrictionDrift,
        LoadDependentFriction,
        JointCoupling,
        Payload,
        GravityTilt,
        ExtraRotorInertia,
        TorqueOffset,
        SignalDelay,
        PositionDependentFriction,
        StribeckHump,
        CamCounterbalance,
        GasSpringCounterbalance,
        LobedCam,
    )
}
