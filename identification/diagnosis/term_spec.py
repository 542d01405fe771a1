"""Candidate terms stored by their definition: ``term_from_spec(term.spec())`` rebuilds the term.

A model file (the calibrated model's findings, the four-step ``IdentifiedModel``'s extra terms) stores each
term as a small JSON spec (``CandidateTerm.spec``): the effect key, the joint, and the shape parameters (a
spring's order, centre and range, a ripple's harmonic, an unnamed effect's sparse features and their
centre). Rebuilding from the spec gives the very term the diagnosis fitted, so its columns and CasADi
expression are the same numbers in the fit, the prediction and the exported code.
"""

from __future__ import annotations

from dataclasses import fields

from identification.diagnosis.candidates import TERMS_BY_KEY
from identification.diagnosis.sparse_terms import SparseFeature, SparseTerm
from psdm_casadi.errors import ParameterError

__all__ = ["SPEC_CLASSES", "term_from_spec"]

SPEC_CLASSES = {**TERMS_BY_KEY, SparseTerm.key: SparseTerm}


def _field_value(cls, name: str, value):
    """A spec value back in the field's Python type (lists as tuples, sparse features as ``SparseFeature``)."""
    if cls is SparseTerm and name == "features":
        return tuple(
            SparseFeature(position=(str(f["position"][0]), int(f["position"][1])), velocity=str(f["velocity"]),
                          width=float(f.get("width", 0.0)), lobe_centre=float(f.get("lobe_centre", 0.0)),
                          lobe_width=float(f.get("lobe_width", 0.0)))
            for f in value
        )  # fmt: skip
    if isinstance(value, list):
        return tuple(value)
    return value


def term_from_spec(spec: dict):
    """The candidate term a ``CandidateTerm.spec()`` dictionary describes.

    Raises
    ------
    ParameterError
        An unknown effect key, an unknown field or a value the term refuses, naming the spec.
    """
    if not isinstance(spec, dict) or spec.get("key") not in SPEC_CLASSES:
        known = sorted(SPEC_CLASSES)
        raise ParameterError(f"term spec must be a dict with 'key' one of {known}; got {spec!r}.")
    cls = SPEC_CLASSES[spec["key"]]
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(spec) - names - {"key"})
    if unknown:
        raise ParameterError(f"term spec {spec!r}: unknown fields {unknown} for {spec['key']}; known: {sorted(names)}.")
    try:
        return cls(**{k: _field_value(cls, k, v) for k, v in spec.items() if k != "key"})
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise ParameterError(f"term spec {spec!r} cannot be rebuilt: {exc}.") from None
