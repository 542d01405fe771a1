"""The counterbalance a model carries as its torque offset, written with the shape found beside it as one finding.

Identify keeps a torque offset no sensor has as the counterbalance's stand-in (``counterbalance_record``), and
``diagnose MODEL`` may find the balancer's bend beside it, a low harmonic of the joint's angle (the unseen heavy arm's
cam: ``diagnosis.counterbalance_naming.counterbalance_shapes``). Over the swing that shape is mostly a constant, so
refitted beside the offset the two trade it: the offset moves far beyond its standard deviation and neither number is
the counterbalance's (``offset_split``: one torque written as two). Dropping the shape keeps the offset's number but
loses the bend, which the joint's held-out torque may show. So where the offset and the shape together predict the
joint better than the offset alone, the model writes them as one finding, ``counterbalance[jJ]``
(``diagnosis.candidates.counterbalance.CounterbalanceTerm``: a constant and the shape's harmonic of the angle), in the
offset's place: its constant is the offset's column (named as a spring's constant, so the offset the data chose on
that joint is left out of the fit, ``findings.offsets_left_to_findings``), its three coefficients are fitted together
with the rest of the model and their standard deviations come from that joint fit. One label, one constant: no
second torque beside the offset, and the bend kept.

The rule (``bends``): the offset with the shape lowers the joint's validation RMSE against the offset alone on every
held-out recording (each one, not only their mean). Where it does not, the shape is dropped as ``offset_split`` says.
The one finding then faces the gates every finding of ``diagnose --apply`` faces: taking it out (``unhelpful_findings``)
also takes its constant, so its bend's gain is this rule's, and ``recalibrate`` judges the written model, each joint
within its paired margin on the held-out recordings (``never_worse``), the finding's gain over the model without it
(the offset again: ``no_gain``). The finding's entry says what it joins (``combines``: the offset's and the shape's
labels, the offset alone and beside the shape, their correlation and the joint's RMSE with each alone and both).

A model file with such a finding is written as version ``COUNTERBALANCE_VERSION``: older readers do not know its term
and refuse the file rather than predict it without its counterbalance.
"""

from __future__ import annotations

import copy

import numpy as np

from identification.calibration.findings import FindingTerm
from identification.diagnosis.candidates.counterbalance import CounterbalanceTerm

__all__ = ["COUNTERBALANCE_VERSION", "EFFECT", "bends", "combined_findings", "combined_verdict", "counterbalance_term",
           "versioned"]  # fmt: skip

#: The ``findings[].term.effect`` of a counterbalance written as one finding.
EFFECT = CounterbalanceTerm.key
#: The model-file version of a file holding such a finding (older readers refuse it: they do not know its term).
COUNTERBALANCE_VERSION = 5
#: The new findings' term effects a counterbalance offset is written with: a shape of the joint's angle of one harmonic.
SHAPES = ("torque_ripple",)


def counterbalance_term(shape: FindingTerm) -> FindingTerm:
    """The one finding of the offset on ``shape``'s joint and ``shape`` (a ripple: its harmonic)."""
    spec = CounterbalanceTerm(joint=shape.joint, harmonic=int(shape.harmonic)).spec()
    return FindingTerm(effect=EFFECT, joint=shape.joint, velocity=shape.velocity, spec=spec)


def bends(offset_alone, both) -> bool:
    """Whether the offset with the shape (``both``) lowers the joint's validation RMSE against the offset alone
    (``offset_alone``) on every held-out recording: per recording, the joint's RMSE [N m] with each model."""
    offset_alone, both = np.asarray(offset_alone, dtype=float), np.asarray(both, dtype=float)
    return bool(offset_alone.size) and bool(np.all(both < offset_alone))


def combined_verdict(verdict: dict, term: FindingTerm, offset_alone, both) -> dict | None:
    """``offset_split``'s ``verdict`` dropping the shape whose term is ``term`` turned into the counterbalance that
    joins the shape and the offset (``combined``: its label), where the shape is one of ``SHAPES`` and the two together
    bend (``bends``: the joint's RMSE per held-out recording, ``offset_alone`` and ``both``); None otherwise."""
    split = verdict.get("split") or {}
    if verdict["label"] != split.get("new") or term.effect not in SHAPES or not bends(offset_alone, both):
        return None
    joined = counterbalance_term(term)
    rmse = split["validation_rmse"]
    gain = 1.0 - rmse["both"] / rmse["carried_alone"]
    reason = (f"written with {split['carried']} as one finding, {joined.label} (its constant and its bend fitted "
              f"together in the offset's place): the two split one torque (correlation {split['correlation']:+.4f}, "
              f"{split['carried']} moved by {split['sigmas']:.1f} of its standard deviations beside it), and together "
              f"they lower joint {term.joint + 1}'s validation RMSE on every held-out recording "
              f"({rmse['carried_alone']:.4g} N m with {split['carried']} alone, {rmse['both']:.4g} with both, "
              f"{gain:.0%} lower; {rmse['new_alone']:.4g} with {split['new']} alone)")  # fmt: skip
    return {**verdict, "combined": joined.label, "reason": reason}


def combined_findings(findings, verdicts) -> tuple:
    """((torque terms, corrections, entries), dropped) of ``applied_model``'s ``findings`` with each shape a
    ``combined_verdict`` joins to its joint's offset replaced by the one counterbalance finding (its term, label and
    entry: the shape's diagnosis and the ``combines`` record). A torque-offset finding on that joint (the diagnosis's
    part of the offset, a column beside the file's) is the counterbalance's constant, one column: it is left out and
    listed in ``dropped`` with the reason."""
    terms, corrections, entries = findings
    joined = {v["label"]: v for v in verdicts if v.get("combined")}
    joints = {t.joint: joined[t.label]["combined"] for t in terms if t.label in joined}
    offsets = {t.label: t.joint for t in terms if t.effect == "torque_offset" and t.joint in joints}
    dropped = [{"label": e["label"], "effect": e["effect"], "joints": list(e["joints"]),
                "reason": f"{joints[offsets[e['label']]]}, written in the place of joint {offsets[e['label']] + 1}'s "
                          "torque offset, holds its torque (its constant): one column, not two findings sharing it",
                "split": {"carried": e["label"], "new": joints[offsets[e["label"]]]}}
               for e in entries if e["label"] in offsets]  # fmt: skip
    terms = [counterbalance_term(t) if t.label in joined else t for t in terms if t.label not in offsets]
    out = []
    for entry in entries:
        verdict = joined.get(entry["label"])
        if verdict is None:
            out.extend([] if entry["label"] in offsets else [entry])
            continue
        term = counterbalance_term(FindingTerm.from_dict(entry["term"]))
        split = verdict["split"]
        combines = {"offset": split["carried"], "shape": split["new"], "correlation": split["correlation"],
                    "sigmas": split["sigmas"], "offset_alone": split["carried_alone"],
                    "offset_beside": split["carried_beside"], "validation_rmse": split["validation_rmse"],
                    "reason": verdict["reason"]}  # fmt: skip
        out.append({**copy.deepcopy(entry), "effect": EFFECT, "label": term.label, "term": term.to_dict(),
                    "combines": combines})  # fmt: skip
    return (terms, corrections, out), dropped


def versioned(document: dict) -> dict:
    """``document`` (a model file's) at ``COUNTERBALANCE_VERSION`` where a finding is a counterbalance written as one
    (module docstring); as it is otherwise."""
    held = any((entry.get("term") or {}).get("effect") == EFFECT for entry in document.get("findings") or ())
    if held:
        document["version"] = max(int(document["version"]), COUNTERBALANCE_VERSION)
    return document
