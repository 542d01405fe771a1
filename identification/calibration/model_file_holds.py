"""What identify fixed in a calibrated model file, which every later fit of that file keeps: read in one place.

calibrated-model document -> ``ModelFileHolds`` -> ``diagnose MODEL``'s nominal model (``diagnosis.carried_terms``) and
``diagnose --apply``'s refit (``recalibrate``).

Identify writes two things that a refit must not undo, because the data that decided them are not in the refit:

- the links it held at the robot file's (``worse_joint_hold``: joints the robot-file check named worse on the held-out
  recordings, ``identification.worse_joints.held_links``): a refit that frees them fits them to what the other
  joints ask of them again;
- the counterbalance it took (``counterbalance_column``: a spring on a joint its report named, ``findings[]`` with
  ``source`` ``"identify"``): the links' first moments absorb a counterbalance whose torque has the shape of the
  joint's gravity, so a refit of the rigid body without the spring's column takes it into the links again, and the
  diagnosis no longer sees it (issue 25: the heavy arm's balancer, found by ``diagnose ROBOT`` and lost by
  ``diagnose MODEL``). The spring stays a column of the model: its coefficients are fitted again, its shape is the
  file's. So does a spring an earlier ``diagnose --apply`` wrote (``findings[]`` of effect ``spring`` or
  ``gas_spring`` whatever their ``source``): diagnosing the applied model neither finds it again nor lets the rigid
  body absorb it; and so does every other torque finding the file holds (``torque_findings``: a ripple, a coupling, a
  Coulomb asymmetry ... an earlier ``diagnose --apply`` wrote), each a column of the diagnosis's nominal model: a
  diagnosis of the applied model does not find again what the file already has;
- the rotors it took apart from their same actuator's (``rotors_apart``: confirmed on held-out data the refit does not
  see; ``standard.envelope.drive_inertia_reference`` entries whose ``same_actuator`` was taken): a refit takes them
  apart too (``TrajectoryOptions.rotors_apart``) rather than holding them to their siblings again.
"""

from __future__ import annotations

from dataclasses import dataclass

from identification.calibration.counterbalance_column import COUNTERBALANCE_SOURCE
from identification.calibration.findings import FindingTerm

__all__ = ["COUNTERBALANCE_KEYS", "ModelFileHolds", "model_file_holds"]

#: The ``term.effect`` of a model file's findings that are a counterbalance (a spring, a gas spring, a counterbalance
#: written as one finding: ``counterbalance_finding``).
COUNTERBALANCE_KEYS = ("spring", "gas_spring", "counterbalance")


@dataclass(frozen=True)
class ModelFileHolds:
    """What a model file holds for its refits (module docstring).

    Attributes
    ----------
    held_links : tuple of int
        Links (0-based) identify held at the robot file's inertia (``TrajectoryOptions.held_links``).
    counterbalances : tuple of dict
        The ``findings`` entries of the file's counterbalances: the torque findings of a spring
        (``COUNTERBALANCE_KEYS``) identify took (``source`` ``"identify"``) or an earlier ``diagnose --apply`` wrote.
    torque_findings : tuple of dict
        The ``findings`` entries of every torque finding the file holds (its counterbalances among them).
    rotors_apart : tuple of int
        Joints (0-based) whose drive inertia identify took apart from the same actuator's
        (``TrajectoryOptions.rotors_apart``).
    """

    held_links: tuple = ()
    counterbalances: tuple = ()
    rotors_apart: tuple = ()
    torque_findings: tuple = ()

    @property
    def counterbalance_terms(self) -> tuple:
        """The ``FindingTerm`` of each counterbalance (its columns: the file's shape)."""
        return tuple(FindingTerm.from_dict(entry["term"]) for entry in self.counterbalances)

    @property
    def torque_terms(self) -> tuple:
        """The ``FindingTerm`` of each torque finding (``torque_findings``)."""
        return tuple(FindingTerm.from_dict(entry["term"]) for entry in self.torque_findings)

    @property
    def counterbalance_labels(self) -> tuple:
        return tuple(str(entry.get("label", "")) for entry in self.counterbalances)

    @property
    def taken_by(self) -> str:
        """Who took the torque findings: ``"identify"`` (its counterbalance), or the model file's fits when an earlier
        ``diagnose --apply`` added one."""
        applied = any(entry.get("source") != COUNTERBALANCE_SOURCE for entry in self.torque_findings)
        return "identify or an earlier 'diagnose --apply'" if applied else "identify"

    def describe(self) -> str:
        """What is held, in words (empty: nothing)."""
        parts = []
        if self.counterbalances:
            parts.append(f"the counterbalance {self.taken_by} took ({', '.join(self.counterbalance_labels)})")
        if self.held_links:
            parts.append(f"link(s) {', '.join(str(i + 1) for i in self.held_links)} held at the robot file's inertia")
        return " and ".join(parts)


def model_file_holds(document: dict) -> ModelFileHolds:
    """The ``ModelFileHolds`` of a calibrated-model ``document`` (files without them: none)."""
    identification = document.get("identification") or {}
    links = (identification.get("worse_joints") or {}).get("held_links") or []
    torque = tuple(
        entry
        for entry in document.get("findings") or ()
        if entry.get("kind") == "torque" and isinstance(entry.get("term"), dict)
    )
    counterbalances = tuple(entry for entry in torque if entry["term"].get("effect") in COUNTERBALANCE_KEYS)
    references = ((document.get("standard") or {}).get("envelope") or {}).get("drive_inertia_reference") or ()
    apart = tuple(sorted(int(entry["joint"]) - 1 for entry in references if _taken_apart(entry)))
    return ModelFileHolds(held_links=tuple(sorted(int(i) - 1 for i in links)), counterbalances=counterbalances,
                          rotors_apart=apart, torque_findings=torque)  # fmt: skip


def _taken_apart(entry) -> bool:
    """Whether a ``drive_inertia_reference`` entry is a rotor taken apart from its same actuator's (files of 4603d6c
    wrote no ``taken``: those it names were)."""
    same = entry.get("same_actuator") if isinstance(entry, dict) else None
    return bool(same) and bool(same.get("taken", True))
