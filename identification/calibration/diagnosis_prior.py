"""Which rigid body a diagnosis of a calibrated model starts from: the model file's, or its robot file's.

``psdm diagnose MODEL`` normally takes the model file's identified rigid body as its nominal model. When identify
pushed a link against its physical envelope (``envelope_report``: a counterbalance, a spring or a payload the rigid
body was absorbing), that rigid body holds part of the effect, and whatever of it looks like gravity (the first
harmonic of a shoulder's counterbalance has the shape of that joint's gravity) is no longer in the residual: the
diagnosis cannot find it. A full recalibration of the rigid body, which the diagnosis tries when the prior's findings
look like wrong inertia, absorbs even more. The robot file's rigid body (the model file keeps the robot file) does
not hold the effect: against it the diagnosis finds the counterbalance and the payload as ``psdm diagnose ROBOT``
does, and its envelope check (``diagnosis.envelope_check``) keeps them where a physical rigid body still needs them.

:func:`diagnosis_prior` decides it from the model file: the robot file's rigid body when identify reported a link
(not only a drive inertia) pushed against its bounds for an absorbed counterbalance or payload and the robot file
states link inertias; the model file's otherwise. The friction and the preparation stay the model file's either way.
The choice is checked on the validation recording (``diagnosis.model_file``): when the diagnosis from the robot file's
rigid body (the model's friction refitted, its findings added) still predicts some joint worse than the model file as
it is beyond the never-worse margin (``paired_margin``), its findings only repair a nominal worse than the model the
user has, and the diagnosis starts from the model file's rigid body instead (``DiagnosisPrior.declining``), saying why.
:func:`carried_findings` names the findings of a diagnosis that the model file already holds (the same torque on the
same joint: its nominal model carries the file's findings, ``diagnosis.carried_terms``, but a torque of the angle may
be found beside a carried spring under another name).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from identification.calibration.envelope_report import pressed_findings

__all__ = ["ABSORBING_EFFECTS", "DiagnosisPrior", "carried_as", "carried_findings", "diagnosis_prior"]

#: What a pushed link absorbs that the robot file's rigid body lets the diagnosis find (not a drive inertia).
ABSORBING_EFFECTS = ("counterbalance", "payload")
LINK_BOUNDS = ("envelope", "mass upper", "mass lower")


@dataclass(frozen=True)
class DiagnosisPrior:
    """The rigid body a model-file diagnosis starts from.

    Attributes
    ----------
    robot_file : bool
        True: the robot file's link inertias (identify pushed ``links`` against their envelope for ``effects``);
        False: the model file's identified ones.
    links : tuple of int
        0-based links identify pushed against their bounds.
    effects : tuple of str
        What identify said they most likely absorb (``ABSORBING_EFFECTS``).
    declined : str
        Non-empty when the robot file's rigid body was asked for but declined: the joints on which the diagnosis's
        model from it (friction refitted, findings added) predicts the validation recording worse than the model
        file as it is, beyond the never-worse margin (``diagnosis.model_file.robot_file_worse``); ``robot_file`` is then
        False.
    """

    robot_file: bool = False
    links: tuple = ()
    effects: tuple = ()
    declined: str = ""

    def note(self) -> str:
        """The report's sentence on the choice (empty for the model file's own rigid body, unless the robot file's
        was declined)."""
        if not (self.robot_file or self.declined):
            return ""
        links = ", ".join(str(i + 1) for i in self.links)
        pushed = (f"the model file's identify pushed link{'s' if len(self.links) > 1 else ''} {links} against the "
                  f"physical envelope, absorbing a {' or a '.join(self.effects)}")  # fmt: skip
        if self.declined:
            return (
                f"{pushed}, but the diagnosis from the robot file's rigid body (the model's friction refitted on the "
                f"training recording, its findings added) predicts the validation recording worse than the model file "
                f"as it is beyond the never-worse margin ({self.declined}): its findings would only repair a nominal "
                "worse than the model file, so the diagnosis starts from the model file's rigid body (the absorbed "
                "effect may stay hidden in it)"
            )
        return (
            f"{pushed}: its rigid body holds part of that effect, so the diagnosis starts from the robot file's rigid "
            "body (kept in the model file) with the model's friction and preparation, as 'psdm diagnose ROBOT' would"
        )

    def first_pass(self) -> str:
        """The progress line that opens the diagnosis from the robot file's rigid body (there may be a second
        pass, from the model file's: ``second_pass``)."""
        links = f"link{'s' if len(self.links) > 1 else ''} {', '.join(str(i + 1) for i in self.links)}"
        absorbed = " or a ".join(self.effects)
        return (f"first pass, from the robot file's rigid body (identify pushed {links} against its bounds, absorbing "
                f"a {absorbed}); if its model predicts a joint worse than the model file as it is, a second pass "
                "starts from the model file's rigid body")  # fmt: skip

    def second_pass(self) -> str:
        """The progress line that opens the diagnosis from the model file's rigid body after the first pass
        (``first_pass``) was declined."""
        return (
            f"second pass, from the model file's rigid body: the first pass's model predicts worse than the "
            f"model file as it is ({self.declined})"
        )

    def declining(self, why: str) -> DiagnosisPrior:
        """This choice turned to the model file's rigid body because the robot file's predicts worse (``why``: the
        joints and their numbers)."""
        return dataclasses.replace(self, robot_file=False, declined=why)

    def sentence(self) -> str:
        """How the report's nominal-model line names the rigid body."""
        if self.declined:
            return "as identified in it, not the robot file's (see the rigid-body notes)"
        return "from the robot file the model file keeps (see the rigid-body notes)" if self.robot_file else ""


def diagnosis_prior(document: dict, robot) -> DiagnosisPrior:
    """The ``DiagnosisPrior`` of a calibrated-model file's ``document`` and its robot file ``robot`` (module
    docstring): the robot file's rigid body when identify reported links pushed for an absorbed counterbalance or
    payload and ``robot`` has link inertias."""
    findings = pressed_findings((document.get("standard") or {}).get("envelope_findings") or [])
    pushed = [
        f for f in findings if f.get("absorbs") in ABSORBING_EFFECTS and set(f.get("bounds") or ()) & set(LINK_BOUNDS)
    ]
    if not pushed or robot is None or robot.links is None:
        return DiagnosisPrior()
    links = tuple(sorted({int(f["link"]) for f in pushed}))
    effects = tuple(e for e in ABSORBING_EFFECTS if any(f["absorbs"] == e for f in pushed))
    return DiagnosisPrior(True, links, effects)


def with_file_rigid_body(nominal, robot):
    """``nominal`` (``calibrated_model.calibrated_robot``: the model's links and friction) with the robot file
    ``robot``'s link inertias and rotor inertias instead of the identified ones; the friction stays the model's."""
    out = nominal.with_links(robot.links, rotor_inertia=robot.rotor_inertia)
    return dataclasses.replace(out, drives=nominal.drives)


def carried_findings(findings, document: dict) -> tuple:
    """The labels of ``findings`` (a diagnosis's ``Finding``s, 0-based ``joints``) that the calibrated-model
    ``document`` already holds as torque findings: the same effect on the same single joint, a position-dependent
    torque counting as one (a spring, a gas spring or a ripple found where the file carries a spring: one
    counterbalance, whose shape the diagnosis may name otherwise)."""
    return tuple(label for label, _ in carried_as(findings, document))


def carried_as(findings, document: dict) -> tuple:
    """``((finding label, the file's label), ...)``: each of ``carried_findings`` with the file's finding it is."""
    held = {
        (_family(e["term"].get("effect")), int(e["term"].get("joint", 0)) - 1): e.get("label", e["term"].get("effect"))
        for e in document.get("findings") or ()
        if e.get("kind") == "torque" and isinstance(e.get("term"), dict)
    }
    labels = {e.get("label") for e in document.get("findings") or () if e.get("kind") == "torque"}
    keys = [(f.label, (_family(f.effect), int(f.joints[0])) if len(f.joints) == 1 else None) for f in findings]
    # a term of several joints (a coupling, a payload) is the file's when it has the file's label
    return tuple((label, label if label in labels else held[key]) for label, key in keys
                 if label in labels or key in held)  # fmt: skip


#: Torques of the joint angle alone: one counterbalance may be found as any of them.
POSITION_TORQUES = ("spring", "gas_spring", "torque_ripple", "counterbalance")


def _family(effect) -> str:
    return "position" if effect in POSITION_TORQUES else str(effect)
