"""Payload configurations in the recordings-route fit: known loads subtracted, unknown ones identified.

The arm's parameters are shared by every recording (as mujoco.sysid shares a model across
configurations); the load at the flange differs:

- a known payload (``data.configuration.PayloadConfiguration.payload``) is subtracted from the
  recording's torque (``payload.payload_torque``, the RNEA of a robot whose only body is the load);
- each unknown payload adds the 10 inertial parameters of a body fixed to the flange. Its columns
  are the last link's standard-parameter columns (:class:`FlangeRegressor`) on the samples of its
  own recordings and zero on the others; the consistent step keeps its pseudo-inertia positive
  definite (``consistent_fit``).

:func:`identified_payloads` reports each unknown payload's mass and centre of mass with standard
deviations (from the least-squares covariance), or says which of them the recordings cannot
separate from the arm (every recording carries the payload: record without it too).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from identification.calibration.payload import payload_torque
from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT
from identification.data.configuration import NO_PAYLOAD
from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError
from psdm_casadi.oracle import build_pinocchio_model, link_to_joint_frame_maps
from psdm_casadi.robot import physical_to_dynamic

__all__ = ["FlangeBodies", "FlangeRegressor", "IdentifiedPayload", "Estimable", "configurations_block",
           "carried_configurations", "identified_payloads", "stated_payload",
           "payload_prior", "separable_in_place", "subtract_known_payloads", "subtract_loads"]  # fmt: skip

BODY = 10  # inertial parameters of a flange body: m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz (origin)


class FlangeRegressor:
    """The torque columns of a body fixed to the flange: Pinocchio's joint torque regressor of the last body.

    Taken from Pinocchio rather than the PSDM model, whose base parameters may leave the flange link out
    (a robot file's ``massless_links``); the last body's columns are mapped from its joint frame to the
    last link frame (``oracle.link_to_joint_frame_maps``), where payloads are stated.
    """

    def __init__(self, robot):
        self.model = build_pinocchio_model(robot, np.zeros((robot.n_dof, LINK_PARAMETER_COUNT + 1)))
        self.data = self.model.createData()
        self.to_joint = link_to_joint_frame_maps(robot)[-1]

    def __call__(self, q, qd, qdd) -> np.ndarray:
        """(n_samples, n_dof, 10) for the samples (n_samples, n_dof) each."""
        out = np.empty((q.shape[0], q.shape[1], BODY))
        for k in range(q.shape[0]):
            full = pin.computeJointTorqueRegressor(self.model, self.data, q[k], qd[k], qdd[k])
            out[k] = full[:, -BODY:] @ self.to_joint
        return out


class RecordingColumns:
    """The extra columns of one recording: ``extra``'s (findings), then every unknown payload's block."""

    def __init__(self, flange: FlangeRegressor, n_bodies: int, body: int | None, extra=None):
        self.flange, self.n_bodies, self.body, self.extra = flange, n_bodies, body, extra

    @property
    def names(self) -> list:
        return [] if self.extra is None else list(self.extra.names)

    @property
    def lower(self) -> np.ndarray:
        return np.zeros(0) if self.extra is None else self.extra.lower

    def columns(self, q, qd, qdd) -> np.ndarray:
        own = np.zeros((q.shape[0], q.shape[1], BODY * self.n_bodies))
        if self.body is not None:
            own[:, :, BODY * self.body : BODY * (self.body + 1)] = self.flange(q, qd, qdd)
        return own if self.extra is None else np.concatenate([self.extra.columns(q, qd, qdd), own], axis=2)


@dataclass(frozen=True)
class FlangeBodies:
    """The unknown payloads of a fit (one per label) and which recording carries which."""

    labels: tuple
    index: tuple  # per recording, the payload's position in labels, or None

    @classmethod
    def of(cls, configurations, n_recordings: int) -> FlangeBodies:
        configurations = list(configurations) if configurations is not None else [NO_PAYLOAD] * n_recordings
        labels = tuple(dict.fromkeys(c.name for c in configurations if c.unknown))
        return cls(labels, tuple(labels.index(c.name) if c.unknown else None for c in configurations))

    @property
    def n_columns(self) -> int:
        return BODY * len(self.labels)

    def separable(self, estimable, offset: int) -> tuple:
        """(columns of the normal equations to keep, mask of the payloads whose mass the recordings determine).

        A payload every recording carries (or one the motion cannot tell from the arm) is left out of the
        consistent step: the arm's parameters then take it up, as without configurations.
        """
        mask = np.array([estimable.unit(offset + BODY * k) for k in range(len(self.labels))], dtype=bool)
        dropped = [offset + BODY * k + c for k in np.flatnonzero(~mask) for c in range(BODY)]
        return [c for c in range(estimable.scale.size) if c not in dropped], mask

    def extras(self, robot, extra=None) -> list:
        """Per recording, the extra-columns object of its rows (``extra`` itself when no payload is unknown)."""
        if not self.labels:
            return [extra] * len(self.index)
        flange = FlangeRegressor(robot)
        return [RecordingColumns(flange, len(self.labels), k, extra) for k in self.index]


def separable_in_place(found, mask) -> np.ndarray:
    """The consistent bodies ``found`` of the separable payloads (``mask``) in their places, NaN for the others."""
    out = np.full((mask.size, found.shape[1] if found.size else 10), np.nan)
    out[mask] = found
    return out


def subtract_known_payloads(robot, prepared, configurations) -> list:
    """The prepared recordings with each known payload's torque taken off (the arm's own torque is left).

    ``configurations`` holds one entry per recording (or is None: no loads); a list of another length is refused, as
    pairing them would leave recordings out of the fit unseen."""
    if configurations is None:
        return list(prepared)
    prepared, configurations = list(prepared), list(configurations)
    if len(prepared) != len(configurations):
        raise ValueError(f"{len(configurations)} payload configurations for {len(prepared)} recordings: give one per "
                         "recording (NO_PAYLOAD for an unloaded one)")  # fmt: skip
    out = []
    for recording, configuration in zip(prepared, configurations):
        if configuration.kind != "known":
            out.append(recording)
            continue
        load = payload_torque(robot, configuration.payload, recording.q, recording.qd, recording.qdd)
        _check_scale(load, recording, configuration)
        out.append(Recording(t=recording.t, q=recording.q, tau=recording.tau - load, qd=recording.qd,
                             qdd=recording.qdd, name=recording.name))  # fmt: skip
    return out


#: A stated load whose torque is this many times the recorded torque (RMS, on some joint) is not the load recorded.
MAX_LOAD_RATIO = 5.0


def _check_scale(load, recording, configuration) -> None:
    """Refuse a known load whose torque dwarfs the recorded one: a sidecar in g and mm (``{"mass": 3000, "com": [0,
    10, 70]}`` on a cobot) was subtracted as it stood, every joint's fit then explained nothing, and identify's
    warnings blamed the torque signs."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.sqrt(np.nanmean(load**2, axis=0) / np.nanmean(recording.tau**2, axis=0))
    if not np.any(ratio > MAX_LOAD_RATIO):
        return
    j = int(np.nanargmax(np.where(np.isfinite(ratio), ratio, -np.inf)))
    payload = configuration.payload
    raise ParameterError(
        f"{recording.name or 'a recording'}: the known payload '{configuration.name}' (mass {payload.mass:g} kg, com "
        f"{[float(c) for c in payload.com]} m) gives joint {j + 1} {ratio[j]:.3g} times the torque recorded there "
        f"(RMS {np.sqrt(np.nanmean(load[:, j] ** 2)):.3g} against {np.sqrt(np.nanmean(recording.tau[:, j] ** 2)):.3g} "
        "N m): not the load this recording carries, or the recorded torque is not in N m. State the load's mass in kg "
        "and its centre of mass in m (flange frame); or fix the torque's scale (its unit in --columns, the torque "
        "constants, the gear ratios: motor turns per joint turn)."
    )


def subtract_loads(robot, prepared, configurations, payloads) -> list:
    """The prepared recordings with every load taken off their torque: the known ones as stated, the unknown ones as
    identified (``payloads``, the :class:`IdentifiedPayload` of a fit with these configurations; one whose recordings
    do not separate it from the arm stays in, as the arm's parameters took it up). What is left is the arm's own
    torque: the friction fits that follow the linear one (``lugre_identify``) see the arm's friction only."""
    prepared = subtract_known_payloads(robot, prepared, configurations)
    bodies = FlangeBodies.of(configurations, len(prepared))
    identified = {p.name: np.asarray(p.parameters, dtype=float) for p in payloads}
    if not bodies.labels:
        return prepared
    flange, out = FlangeRegressor(robot), []
    for recording, k in zip(prepared, bodies.index):
        body = None if k is None else identified.get(bodies.labels[k])
        if body is None or not np.all(np.isfinite(body)):
            out.append(recording)
            continue
        load = flange(recording.q, recording.qd, recording.qdd) @ body
        out.append(Recording(t=recording.t, q=recording.q, tau=recording.tau - load, qd=recording.qd,
                             qdd=recording.qdd, name=recording.name))  # fmt: skip
    return out


class Estimable:
    """Whether a linear functional ``c @ x`` is determined by normal equations ``gram`` (in the range of the
    unit-diagonal scaled gram); the pseudo-inverse is computed once."""

    def __init__(self, gram, tolerance: float = 1e-6):
        self.scale = np.sqrt(np.clip(np.diag(gram), 1e-300, None))
        scaled = gram / np.outer(self.scale, self.scale)
        self.projector = scaled @ np.linalg.pinv(scaled, rcond=1e-10, hermitian=True)
        self.tolerance = tolerance

    def __call__(self, functional) -> bool:
        c = np.asarray(functional, dtype=float) / self.scale
        if not np.any(c):
            return False
        return bool(np.linalg.norm(self.projector @ c - c) <= self.tolerance * np.linalg.norm(c))

    def unit(self, column: int) -> bool:
        """Whether the parameter of ``column`` alone is determined."""
        c = np.zeros(self.scale.size)
        c[column] = 1.0
        return self(c)


@dataclass(frozen=True)
class IdentifiedPayload:
    """An unknown payload as identified: mass [kg] and centre of mass [m] in the flange frame, with sigma.

    ``parameters`` are its 10 consistent inertial parameters about the flange origin; ``identifiable``
    says whether the recordings separate its mass from the arm's (NaN values where they do not).
    """

    name: str
    recordings: tuple
    mass: float
    mass_std: float
    com: tuple
    com_std: tuple
    parameters: tuple
    identifiable: bool

    def to_dict(self) -> dict:
        def number(v):
            return None if not np.isfinite(v) else float(v)

        return {"name": self.name, "recordings": list(self.recordings), "mass": number(self.mass),
                "mass_std": number(self.mass_std), "com": [number(v) for v in self.com],
                "com_std": [number(v) for v in self.com_std], "parameters": [number(v) for v in self.parameters],
                "identifiable": self.identifiable}  # fmt: skip


def identified_payloads(bodies: FlangeBodies, names, offset: int, estimable, covariance, consistent) -> tuple:
    """The :class:`IdentifiedPayload` of every unknown payload.

    ``offset`` is the column of the first payload parameter in the normal equations (``estimable``, an
    :class:`Estimable` of their weighted gram) and in ``covariance`` (the weighted least-squares one);
    ``consistent`` (k, 10) are the consistent step's bodies (the reported values).
    """
    out = []
    for k, label in enumerate(bodies.labels):
        first = offset + BODY * k
        body = np.asarray(consistent[k], dtype=float)
        mass, com = float(body[0]), body[1:4] / body[0] if body[0] > 0 else np.full(3, np.nan)
        identifiable = estimable.unit(first)
        block = covariance[first : first + 4, first : first + 4]
        mass_std = float(np.sqrt(max(block[0, 0], 0.0))) if identifiable else np.nan
        com_std = []
        for axis in range(3):  # delta method: d(h/m) = dh/m - h dm/m^2
            gradient = np.zeros(4)
            gradient[0], gradient[1 + axis] = -body[1 + axis] / mass**2, 1.0 / mass
            ok = identifiable and estimable.unit(first + 1 + axis)
            com_std.append(float(np.sqrt(max(gradient @ block @ gradient, 0.0))) if ok else np.nan)
        recordings = tuple(n for n, i in zip(names, bodies.index) if i == k)
        if not identifiable:
            mass, com = np.nan, np.full(3, np.nan)
        out.append(IdentifiedPayload(label, recordings, mass, mass_std, tuple(float(v) for v in com),
                                     tuple(com_std), tuple(float(v) for v in body), identifiable))  # fmt: skip
    return tuple(out)


def payload_prior(bodies: FlangeBodies, x_ols, offset: int, estimable) -> np.ndarray:
    """(k, 10) consistent start bodies: the least-squares mass and centre of mass where determined, a small sphere."""
    out = np.zeros((len(bodies.labels), BODY))
    for k in range(len(bodies.labels)):
        first = offset + BODY * k
        mass = float(x_ols[first]) if estimable.unit(first) else 0.0
        mass = max(mass, 0.05)
        com = np.clip(x_ols[first + 1 : first + 4] / mass, -0.5, 0.5) if mass > 0.05 else np.zeros(3)
        out[k] = physical_to_dynamic(mass, com, mass * 0.05**2 * np.eye(3))
    return out


def configurations_block(configurations, names, payloads) -> list:
    """The ``configurations`` block of the calibrated-model file: per configuration its kind, recordings and load.

    A known load is stored as given; an unknown one as identified (:meth:`IdentifiedPayload.to_dict`).
    """
    identified = {p.name: p for p in payloads}
    out = {}
    for configuration, name in zip(configurations, names):
        entry = out.setdefault(configuration.name, {"name": configuration.name, "kind": configuration.kind,
                                                    "recordings": []})  # fmt: skip
        entry["recordings"].append(name)
        if configuration.kind == "known":
            load = configuration.payload
            inertia = None if load.inertia is None else np.asarray(load.inertia).tolist()
            entry["payload"] = {"mass": float(load.mass), "com": [float(v) for v in load.com], "inertia": inertia}
        elif configuration.kind == "unknown":
            entry["payload"] = identified[configuration.name].to_dict()
    return list(out.values())


def carried_configurations(stored, configurations, names) -> list:
    """The ``configurations`` block of a model identified again on new recordings (``recalibrate``): the file's own
    entries (``stored``), with each new recording (``names``) that states its load (``configurations``, loads already
    taken off its torque: ``payload_check.without_load``) listed under that load. A known load the file did not
    have gets an entry of its own; an unknown one the file has not identified is left out (nothing weighs it)."""
    out = [dict(entry, recordings=list(entry.get("recordings") or [])) for entry in stored]
    by_name = {entry.get("name"): entry for entry in out}
    for configuration, name in zip(configurations or (), names):
        entry = by_name.get(configuration.name)
        if not configuration.stated or (entry is None and configuration.kind == "unknown"):
            continue
        if entry is None:
            entry = by_name[configuration.name] = configurations_block([configuration], [name], ())[0]
            out.append(entry)
        elif name not in entry["recordings"]:
            entry["recordings"].append(name)
    return out


def stated_payload(configuration, stored, model_name: str) -> tuple:
    """(10 inertial parameters about the flange or None, note or None): the load a recording to be validated
    carries by its own statement (``configuration``): a known one as given, an unknown one as the model
    identified it under the same name (``stored``: the model file's ``configurations`` block); None for none, and
    None with a note for an unknown payload the model has not identified (then validated against the arm alone)."""
    if configuration.kind == "known":
        return configuration.payload.dynamic_parameters(), None
    if configuration.kind == "none":
        return None, None
    entries = {e.get("name"): e for e in stored if e.get("kind") == "unknown"}
    entry = entries.get(configuration.name)
    parameters = None if entry is None else (entry.get("payload") or {}).get("parameters")
    if entry is not None and (parameters is None or any(v is None for v in parameters)):
        return None, (
            f"payload {configuration.name!r} is in {model_name} but not separable from the arm (every recording it "
            "was identified from carried it, or their motion did not tell them apart): the last links hold it, and "
            "the recording is judged against the arm as identified, the load included. To weigh the load itself, "
            "identify with a recording of the arm without it too."
        )
    if parameters is None:
        return None, (
            f"payload {configuration.name!r} is unknown and {model_name} has not identified it (its identified "
            f"payloads: {sorted(entries) or 'none'}); the recording is validated against the arm alone. Identify "
            "with recordings that carry it, or state its mass."
        )
    return np.asarray(parameters, dtype=float), None
