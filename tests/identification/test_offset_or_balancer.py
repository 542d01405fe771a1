"""A large torque offset against a balancer, decided from the data (``calibration.offset_or_balancer``).

Known truth: a joint swinging about a pose, its torque either a constant (a sensor's zero error, a re-zeroed sensor's)
or a balancer's ``a sin(q - q_hang)`` of the same mean, plus white noise. Over a wide swing the two are told apart on
the training blocks and on a held-out part; over a small swing near horizontal, where a balancer's torque is as
constant as an offset, they are not, and the verdict says so.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.column_choice import ColumnChoice, ColumnRequest
from identification.calibration.offset_or_balancer import (
    BALANCER,
    OFFSET,
    UNDECIDED,
    offset_or_balancer,
)
from identification.diagnosis.counterbalance_naming import COUNTERBALANCE, name_counterbalances
from identification.diagnosis.report import Finding

HANG = 0.3  # the joint's hanging angle [rad]: the balancer's torque is a sin(q - HANG)


def _part(rng, truth, centre, swing, n=2000, phase=0.0, noise=0.05):
    """(q, tau): the joint swinging ``swing`` [rad] peak to peak about ``centre``, torque ``truth(q)`` + noise."""
    t = np.linspace(0.0, 20.0, n)
    q = centre + 0.25 * swing * (np.sin(0.9 * t + phase) + np.sin(2.3 * t + 2.0 * phase))
    return q, truth(q) + noise * rng.standard_normal(n)


def _balancer(q):
    return 3.0 * np.sin(q - HANG) / np.sin(1.2)  # 3 N m at q - HANG = 1.2 rad, the recorded centre


def _offset(q):
    return np.full_like(q, 3.0)


@pytest.mark.parametrize(
    ("truth", "swing", "noise", "verdict"),
    [
        (_offset, 1.4, 0.05, OFFSET),  # a re-zeroed sensor on a joint swung widely: told from a balancer
        (_balancer, 1.4, 0.05, BALANCER),
        (_balancer, 0.04, 0.5, UNDECIDED),  # a small swing: the balancer's 0.02 N m of change is lost in the noise
        (_offset, 0.04, 0.5, UNDECIDED),
    ],
)
def test_a_constant_and_a_balancer_are_told_apart_where_the_swing_shows_them(rng, truth, swing, noise, verdict):
    centre = HANG + 1.2
    train = [_part(rng, truth, centre, swing, noise=noise)]
    held = [_part(rng, truth, centre, swing, phase=0.7, noise=noise)]
    found = offset_or_balancer(1, train, held)
    assert found.verdict == verdict, found.judges
    assert [route for route, *_ in found.judges] == ["4 training blocks", "the held-out part"]
    assert found.swing == pytest.approx(np.ptp(train[0][0]))
    assert found.named == (verdict != OFFSET)
    for _, constant, balancer, margin in found.judges:  # each judge's numbers: the winner lower beyond the margin
        if verdict == OFFSET:
            assert constant < balancer - margin and constant == pytest.approx(0.05, rel=0.2)
        if verdict == BALANCER:
            assert balancer < constant - margin and balancer == pytest.approx(0.05, rel=0.2)
    assert f"recorded swing of {found.swing:.3g} rad" in found.sentence() and "joint 2" in found.sentence()


def test_judges_that_disagree_leave_it_undecided(rng):
    """Training a balancer, the held-out part a constant (the balancer taken off, say): no verdict either way."""
    centre = HANG + 1.2
    found = offset_or_balancer(1, [_part(rng, _balancer, centre, 1.4)], [_part(rng, _offset, centre, 1.4)])
    assert found.verdict == UNDECIDED and "cannot tell a balancer from a constant" in found.sentence()


def _finding(value: float, joint: int = 1) -> Finding:
    return Finding("torque_offset", f"torque_offset[j{joint + 1}]", (joint,), {"offset": value}, (value,),
                   (f"offset_{joint + 1}",), "bias", "sig", (1.0, 1.0), (0.5, 0.5), -10.0, 0.5)  # fmt: skip


def test_the_diagnosis_names_an_offset_a_counterbalance_only_where_the_data_do_not_say_offset(rng):
    """Joint 2: gravity torque 10 N m, recorded peak 20 N m, a 3 N m offset (30 % and 15 %: no sensor's by size)."""
    centre = HANG + 1.2
    q, _ = _part(rng, _offset, centre, 1.4)
    context = SimpleNamespace(q=np.column_stack([0 * q, q]), gravity=np.column_stack([0 * q, np.full_like(q, 10.0)]),
                              tau=np.full((q.size, 2), 20.0))  # fmt: skip
    finding = _finding(3.0)
    train, held = _part(rng, _offset, centre, 1.4), _part(rng, _offset, centre, 1.4, phase=0.7)
    verdicts = {1: offset_or_balancer(1, [train], [held])}
    (kept,) = name_counterbalances([finding], context, verdicts)
    assert kept.effect == "torque_offset" and kept.coefficients == (3.0,)
    assert "a sensor offset" in kept.notes[-1] and "30% of its gravity torque" in kept.notes[-1]
    balancer = [_part(rng, _balancer, centre, 1.4), _part(rng, _balancer, centre, 1.4, phase=0.7)]
    (named,) = name_counterbalances([finding], context, {1: offset_or_balancer(1, balancer[:1], balancer[1:])})
    assert named.effect == COUNTERBALANCE and "follows joint 2's angle as a balancer's does" in named.explanation
    (by_size,) = name_counterbalances([finding], context)  # no data: the reading by size
    assert by_size.effect == COUNTERBALANCE


def test_the_column_choice_line_does_not_list_an_offset_the_spring_replaced():
    choice = ColumnChoice("coulomb-viscous", (0, 1, 2), (), ColumnRequest(), replaced_offsets=(1,))
    (line,) = [s for s in choice.describe() if s.startswith("torque offset")]
    assert (
        line
        == "torque offset: joints 1, 3 (chosen from the data; on joint 2 replaced by the counterbalance spring kept)"
    )
    document = choice.to_dict()
    assert document["offset_joints"] == [1, 3] and document["offset_joints_replaced"] == [2]
    assert choice.offset_joints == (0, 1, 2)  # the data's choice, as made
