"""Scenarios of ``benchmarks/diagnosis.py`` (seed 0) that the diagnosis missed at identify's preparation (issue 25).

Diagnosed as the benchmark diagnoses them (identify's cutoff, grid and trims; the validation part's two halves as two
validation recordings), each must name its hidden effect on the right joint. They were missed when the diagnosis moved
from 15 Hz to identify's 10 Hz with one filter period trimmed at each end: the filter's start-up transient left in
the ends let a recalibrated rigid body beat a true delay (scenario 10) and stand in for the heavy arm's counterbalance
(30), and the sign of a velocity filtered at 10 Hz misplaced the reversals where a joint sticks, so that a
position-dependent friction (24) stayed in the residual (the sparse terms' sign: ``context.sign_velocity``). The
wrist elasticity (12) was lost when identify's three filter periods were trimmed (in the middle it explains 0.6 % of its
joint's torque, but the noise it leaves shrank the RMSE drop to 0.3 %, under the 0.4 % floor then judged on that
drop), and the Stribeck hump (25) at 10 Hz (its RMSE drop 0.0164 N m under the floor of 0.01645): the size floor is on
the torque a term explains (``metrics.explained_rms``), and an elasticity is not named where pre-sliding on its joint
fit better but did not hold (``FrictionRival.stand_in``: the unseen UR5-like arm's joint 5, issue 25). The heavy
arm's tool (30) was missed once its balancer was a physical one: the identified rigid body, reported there, took the
tool into the links; a rigid body inside its envelope cannot, and the tool is named (``hidden_payload``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest


@pytest.fixture(scope="module")
def bench():
    import sys

    path = str(Path(__file__).resolve().parents[2] / "benchmarks")
    sys.path.insert(0, path)
    try:
        import diagnosis

        yield diagnosis
    finally:
        sys.path.remove(path)


def _diagnosed(bench, index, seed=0):
    from identification.diagnosis import DiagnosisOptions, diagnose

    robot_key, effects = bench.SCENARIOS[index]
    robot, model = bench._load(robot_key)
    rng = np.random.default_rng(10_000 * seed + index)  # as the benchmark draws its scenarios
    truth, train, val = bench._scenario(robot_key, robot, effects, rng, 100 * seed + index)
    report = diagnose(robot, train, bench.split_validation(val, 2), DiagnosisOptions(), model=model)
    return truth, report


@pytest.mark.slow
@pytest.mark.parametrize(
    ("index", "effect", "joint"),
    [
        (10, "delay", None),
        (24, "unnamed_effect", 4),
        (30, "counterbalance", 1),
        (12, "joint_elasticity", 5),
        (25, "friction_shape", 5),
    ],
)
def test_the_hidden_effect_is_found_at_identify_s_preparation(bench, index, effect, joint):
    truth, report = _diagnosed(bench, index)
    assert bench._correct(report.findings, truth), report.summary()
    hit = [f for f in report.findings if f.effect == effect and (joint is None or joint in f.joints)]
    assert hit, report.summary()
    assert not report.findings_not_holding and bench._kept_raising_rmse(report) == 0
    if index == 30:  # the tool the identified rigid body took into the links is named (``hidden_payload``)
        (payload,) = [f for f in report.findings if f.effect == "payload"]
        assert payload.parameters["mass"] == pytest.approx(truth[1][3]["mass"], rel=0.15)  # 101.5 kg against 112.0
    if effect == "unnamed_effect":  # the term explains the effect: its joint's validation error falls by a third
        assert report.rmse_after[joint] < 0.67 * report.rmse_before[joint]
    if effect == "delay":  # 8 samples of 1 kHz (the scenario's truth)
        assert abs(hit[0].parameters["delay_s"] - truth[0][3]["delay_s"]) < 0.5 * truth[0][3]["delay_s"]
    if effect == "joint_elasticity":  # the stiffness within a quarter of the truth (1349 against 1133 N m/rad)
        truth_k = truth[0][3]["stiffness_Nm_per_rad"]
        assert hit[0].parameters["stiffness_Nm_per_rad"] == pytest.approx(truth_k, rel=0.25)
    if effect == "friction_shape":  # the hump's height above the Coulomb level and its velocity (1.34 N m, 0.110 rad/s
        # against 1.20 N m, 0.127 rad/s)
        assert hit[0].parameters["stribeck_peak_Nm"] == pytest.approx(truth[0][3]["height"], rel=0.25)
        assert hit[0].parameters["stribeck_velocity_rad_s"] == pytest.approx(truth[0][3]["velocity"], rel=0.25)


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "joint"), [(1, 4), (2, 5)])
def test_a_wide_backlash_is_named_with_its_width(bench, seed, joint):
    """The backlash scenario (11) at seeds 1 and 2: 0.43 and 0.30 deg of play, lost to the friction shapes the nominal
    model lacks while the column's friction part was the secant at 0.1 deg of half-play; named with the secant at the
    size its exact training profile puts lowest (``BacklashTerm.shape_variants``), the width within 3 % and 7 %."""
    truth, report = _diagnosed(bench, 11, seed)
    assert bench._correct(report.findings, truth), report.summary()
    hit = [f for f in report.findings if f.effect == "backlash" and joint in f.joints]
    assert hit and not report.findings_not_holding, report.summary()
    assert hit[0].parameters["backlash_rad"] == pytest.approx(truth[0][3]["backlash_rad"], rel=0.15)
