"""The counterbalance a model carries as its torque offset, written with its shape as one finding
(``calibration.counterbalance_finding``, issue 25).

Reference: a hidden cam balancer on a joint, its torque ``A sin(x) (1 + lobe cos 2x)`` near its flattest over the
training swing, and held-out swings wider than it (the unseen heavy arm's case). Least squares with the offset's
column alone, and with the offset and a second harmonic of the angle, stand for the joint refits; the truth says which
model is the balancer's. Where the cam bends, the offset and its shape predict every held-out swing better than the
offset alone and are written as one finding, whose torque is the cam's closer than the offset's. Where the truth is a
constant (a balancer that does not bend over the travel), the shape fitted over a narrow swing is the noise's and
extrapolates worse: it is dropped, as ``offset_split`` says.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from identification.calibration.calibrated_model import READABLE_VERSIONS
from identification.calibration.counterbalance_finding import (
    COUNTERBALANCE_VERSION,
    EFFECT,
    bends,
    combined_findings,
    combined_verdict,
    counterbalance_term,
    versioned,
)
from identification.calibration.findings import FindingTerm, offsets_left_to_findings, term_values
from identification.calibration.offset_split import constant_correlation
from identification.calibration.split_torque import coefficient_shift, one_of_the_two, split_reason
from identification.calibration.trajectory_fit import TrajectoryOptions
from identification.diagnosis.term_spec import term_from_spec

RIPPLE = FindingTerm(effect="torque_ripple", joint=1, harmonic=2)
NOISE = 20.0  # [N m]


def _swing(centre, amplitude, n=1500, seed=0):
    """Joint 2's angle over a recording: a swing of ``amplitude`` [rad] about ``centre``."""
    t = np.linspace(0.0, 10.0, n)
    return centre + amplitude * np.sin(2 * np.pi * 0.17 * t + seed) * np.cos(2 * np.pi * 0.05 * t)


def _cam(q):
    """A cam balancer near its flattest about q = 0 (its torque is mostly a constant over a narrow swing)."""
    x = q + 1.4
    return 2500.0 * np.sin(x) * (1.0 + 0.4 * np.cos(2.0 * x))


def _columns(q, shape: bool):
    """The offset's column, and the second harmonic's beside it."""
    return np.column_stack([np.ones_like(q), *((np.sin(2 * q), np.cos(2 * q)) if shape else ())])


def _fit(q, tau, shape: bool):
    """(coefficients, standard deviations) of least squares of ``tau`` on the offset's (and the shape's) columns."""
    a = _columns(q, shape)
    beta, *_ = np.linalg.lstsq(a, tau, rcond=None)
    residual = tau - a @ beta
    std = np.sqrt(np.diag(residual @ residual / (len(tau) - len(beta)) * np.linalg.inv(a.T @ a)))
    return beta, std


def _entry(beta, std) -> dict:
    return {"label": "offset2", "feature_names": ["offset2"], "coefficients": [beta[0]], "std": [std[0]],
            "parameters": {"offset": beta[0]}}  # fmt: skip


#: Held-out swings wider than the training one, about its centre (the cam bends over them as over the training one).
WIDER = ((0.0, 0.6), (0.1, 0.5))
#: Held-out swings of which the second reaches far below the training one, where the cam bends another way.
BELOW = ((0.2, 0.7), (-0.35, 0.6))


def _verdict(truth, held=WIDER, seed=0):
    """The offset fitted alone and beside the shape on a narrow training swing of ``truth`` with noise, judged on two
    wider held-out swings as ``offset_split`` judges it: (verdict, RMSE per held-out swing with the offset alone and
    with both, the two fits, the held-out swings)."""
    rng = np.random.default_rng(seed)
    q = _swing(0.0, 0.25)
    tau = truth(q) + rng.normal(0.0, NOISE, q.size)
    alone, beside = _fit(q, tau, False), _fit(q, tau, True)
    shape_torque = _columns(q, True)[:, 1:] @ beside[0][1:]
    correlation = constant_correlation(shape_torque, beside[0][0])
    reason = split_reason(_entry(*alone), _entry(*beside), 1, correlation)
    held = [_swing(centre, amplitude, seed=k + 1) for k, (centre, amplitude) in enumerate(held)]
    measured = [truth(h) + rng.normal(0.0, NOISE, h.size) for h in held]
    rmse = [[float(np.sqrt(np.mean((m - _columns(h, s) @ b) ** 2))) for h, m in zip(held, measured)]
            for s, b in ((False, alone[0]), (True, beside[0]))]  # fmt: skip
    own, *_ = np.linalg.lstsq(_columns(q, True)[:, 1:], tau, rcond=None)  # the shape alone, in the offset's place
    shape_alone = float(np.mean([np.sqrt(np.mean((m - _columns(h, True)[:, 1:] @ own) ** 2))
                                 for h, m in zip(held, measured)]))  # fmt: skip
    split = {"new": RIPPLE.label, "carried": "offset2", "correlation": correlation,
             "sigmas": coefficient_shift(_entry(*alone), _entry(*beside))[0],
             "carried_alone": {"offset": alone[0][0]}, "carried_beside": {"offset": beside[0][0]}}  # fmt: skip
    entries = {RIPPLE.label: {"effect": "counterbalance"}, "offset2": {"effect": "torque_offset"}}
    verdict = one_of_the_two(split, [np.mean(rmse[0]), shape_alone, np.mean(rmse[1])], 1, reason, entries)
    return verdict, rmse, (alone, beside), held


def test_an_offset_and_the_shape_of_a_bending_cam_are_written_as_one_counterbalance():
    verdict, (offset_alone, both), (alone, beside), held = _verdict(_cam)
    split = verdict["split"]
    assert abs(split["correlation"]) > 0.9 and split["sigmas"] > 3.0  # one torque written as two ...
    assert verdict["label"] == RIPPLE.label  # ... of which offset_split keeps the offset
    joined = combined_verdict(verdict, RIPPLE, offset_alone, both)
    assert joined["combined"] == "counterbalance[j2]" and joined["label"] == RIPPLE.label
    assert joined["reason"].startswith("written with offset2 as one finding, counterbalance[j2]")
    # the truth agrees: over each held-out swing, the one counterbalance is the cam's torque, the offset is not
    for h in held:
        error_one = np.sqrt(np.mean((_cam(h) - _columns(h, True) @ beside[0]) ** 2))
        error_offset = np.sqrt(np.mean((_cam(h) - alone[0][0]) ** 2))
        assert error_one < 0.5 * error_offset
    # its constant is not the offset's number beside the shape, nor its own: one constant, the cam's with its bend
    term = counterbalance_term(RIPPLE)
    tau = _cam(held[0])
    q = np.zeros((held[0].size, 6))
    q[:, 1] = held[0]
    values = np.column_stack(term_values(term, q, q, q))
    c, *_ = np.linalg.lstsq(values, tau, rcond=None)
    assert c == pytest.approx(np.linalg.lstsq(_columns(held[0], True), tau, rcond=None)[0], rel=1e-9)


def test_a_shape_that_holds_on_one_held_out_recording_and_not_the_other_is_dropped():
    # the second held-out swing reaches where the cam bends another way than a second harmonic fitted over the
    # training swing: better on average, worse there, and the truth agrees that there it is not the cam's torque
    verdict, (offset_alone, both), (alone, beside), held = _verdict(_cam, BELOW)
    assert np.mean(both) < np.mean(offset_alone) and both[0] < offset_alone[0] and both[1] > offset_alone[1]
    assert verdict["label"] == RIPPLE.label and combined_verdict(verdict, RIPPLE, offset_alone, both) is None
    error_one = np.sqrt(np.mean((_cam(held[1]) - _columns(held[1], True) @ beside[0]) ** 2))
    assert error_one > np.sqrt(np.mean((_cam(held[1]) - alone[0][0]) ** 2))


def test_a_shape_the_held_out_swings_do_not_bend_with_is_dropped():
    # a balancer flat over the whole travel: the shape fitted over the narrow swing is noise, worse held out
    verdict, (offset_alone, both), _, _ = _verdict(lambda q: np.full_like(q, 2830.0))
    assert not bends(offset_alone, both)
    assert combined_verdict(verdict, RIPPLE, offset_alone, both) is None
    assert not bends([200.0, 150.0], [160.0, 151.0])  # lower on one held-out recording, not on the other
    assert not bends([], [])
    assert bends([200.0, 150.0], [160.0, 140.0])


def test_the_counterbalance_term_is_one_finding_in_the_offsets_place():
    term = counterbalance_term(RIPPLE)
    assert term.label == "counterbalance[j2]" and term.effect == EFFECT
    assert term.feature_names() == ["c_2", "counterbalance_sin2_q2", "counterbalance_cos2_q2"]
    assert FindingTerm.from_dict(term.to_dict()) == term and term_from_spec(term.spec).harmonic == 2
    # its constant takes the place of the offset the data chose on its joint, not a column beside it
    options = TrajectoryOptions(friction=("fc", "fv", "offset"), offset_joints=(1, 3))
    assert offsets_left_to_findings(options, [term]).offset_joints == (3,)
    assert offsets_left_to_findings(options, [RIPPLE]).offset_joints == (1, 3)
    # the numbers and the CasADi expression (the exported code) are one definition
    q = np.random.default_rng(1).uniform(-1.0, 1.0, (4, 6))
    numeric = np.column_stack(term_values(term, q, q, q))
    x = ca.SX.sym("q", 6)
    symbolic = ca.Function("f", [x], [ca.vertcat(*term_values(term, x, x, x))])
    assert np.array([symbolic(row).full().ravel() for row in q]) == pytest.approx(numeric, abs=1e-12)
    assert numeric[:, 0] == pytest.approx(1.0) and numeric[:, 1] == pytest.approx(np.sin(2 * q[:, 1]))
    c = [2830.0, -400.0, 300.0]
    assert term.candidate.physical_parameters(c) == pytest.approx(
        {"constant": 2830.0, "amplitude": 500.0, "harmonic": 2.0, "phase": np.arctan2(300.0, -400.0)}
    )


def test_the_shape_entry_becomes_the_counterbalance_and_the_file_is_versioned():
    verdict, rmse, _, _ = _verdict(_cam)
    joined = combined_verdict(verdict, RIPPLE, *rmse)
    shape = {"label": RIPPLE.label, "effect": "counterbalance", "kind": "torque", "joints": [2],
             "term": RIPPLE.to_dict(), "diagnosis": {"coefficients": [1.0, 2.0]}}  # fmt: skip
    other = {"label": "coupling[j1->j2]", "kind": "torque", "term": {"effect": "coupling", "joint": 2, "source": 1}}
    coupling = FindingTerm.from_dict(other["term"])
    offset = FindingTerm(effect="torque_offset", joint=1)
    found = {
        "label": offset.label,
        "effect": "counterbalance",
        "kind": "torque",
        "joints": [2],
        "term": offset.to_dict(),
    }
    (terms, corrections, entries), dropped = combined_findings(
        ([offset, RIPPLE, coupling], {}, [found, shape, other]), [joined]
    )
    assert [t.label for t in terms] == ["counterbalance[j2]", "coupling[j1->j2]"]  # one constant on joint 2
    (held,) = dropped
    assert held["label"] == "torque_offset[j2]" and held["reason"].startswith(
        "counterbalance[j2], written in the place"
    )
    assert entries[1] is other and entries[0]["label"] == "counterbalance[j2]" and entries[0]["effect"] == EFFECT
    assert entries[0]["combines"]["offset"] == "offset2" and entries[0]["combines"]["shape"] == RIPPLE.label
    assert entries[0]["diagnosis"] == shape["diagnosis"] and shape["label"] == RIPPLE.label  # the input unchanged
    document = {"version": 2, "findings": entries}
    assert versioned(document)["version"] == COUNTERBALANCE_VERSION in READABLE_VERSIONS
    assert versioned({"version": 3, "findings": [other]})["version"] == 3
