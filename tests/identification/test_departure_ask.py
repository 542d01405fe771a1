"""A counterbalance the links take inside their envelopes is asked for by its gravity departure (``departure_ask``).

Truth: the four-joint cobot's robot file (``torque_scale_data``) with a point mass on link 2 that opposes half of
joint 2's gravity torque, as the data's own least squares would hold a balancer on joint 2 (joint 1 is vertical and
carries no gravity; no later joint carries link 2, so the torque is joint 2's alone). Its departure from the file's
gravity torque is Pinocchio's gravity torque of the point alone. The rule then names a counterbalance on joint 2 that
the bounds refuse less than ``NAME_SIGMA`` noise levels (the heavy virtual arm's, slow in ``test_envelope_evidence``)
where that departure is at least as large, and no other.
"""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.clear_ask import NAME_SIGMA, UNNAMED, named_where_asked
from identification.calibration.departure_ask import departed_noise
from identification.calibration.envelope_report import EnvelopeFinding
from psdm_casadi.derive import derive_psdm
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import load_robot
from tests.identification.torque_scale_data import cobot

SIGMA = np.array([1.0, 0.5, 1.0, 1.0])  # the joints' noise [N m]


def _point(robot, mass: float, x: float) -> np.ndarray:
    """The standard parameters of a point ``mass`` [kg] on link 2 at ``x`` [m] along its x axis, zero elsewhere."""
    change = np.zeros((robot.n_dof, 10))
    change[1, :4] = (mass, mass * x, 0.0, 0.0)
    change[1, [6, 9]] = mass * x**2  # iyy, izz of the point about the link's origin
    return change


def _gravity(robot, q, change) -> np.ndarray:
    """Pinocchio's gravity torque of ``change`` alone at ``q``: the file's with it minus the file's."""
    prior = robot.nominal_dynamic_parameters()
    with_change = prior.copy()
    with_change[:, :10] += change
    return PinocchioOracle(robot, with_change).gravity(q) - PinocchioOracle(robot, prior).gravity(q)


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """``(robot, model)`` of the cobot's robot file."""
    path = tmp_path_factory.mktemp("cobot") / "cobot.toml"
    path.write_text(cobot().robot_file((1.0,) * 4))
    robot = load_robot(path)
    return robot, derive_psdm(robot)


@pytest.fixture(scope="module")
def balanced(arm):
    """``(recordings, change, theta_ols)``: 400 poses within the limits, a point mass on link 2 whose gravity torque
    opposes half of joint 2's there, and the base parameters of the file with it."""
    robot, model = arm
    q = np.random.default_rng(4).uniform(np.maximum(robot.q_min, -np.pi), np.minimum(robot.q_max, np.pi), (400, 4))
    g_file = PinocchioOracle(robot, robot.nominal_dynamic_parameters()).gravity(q)[:, 1]
    units = {x: _gravity(robot, q, _point(robot, 1.0, x))[:, 1] for x in (0.2, -0.2, 0.5, -0.5, 1.0, -1.0)}
    x, unit = next((x, unit) for x, unit in units.items() if float(unit @ g_file) < 0.0)  # a kilogram opposing it
    change = _point(robot, -0.5 * float(g_file @ g_file) / float(unit @ g_file), x)
    prior = robot.nominal_dynamic_parameters().copy()
    prior[:, :10] += change
    return [SimpleNamespace(q=q)], change, model.base_parameters(prior)


def test_the_departure_is_the_data_gravity_torque_of_the_joint_alone_in_noise_levels(arm, balanced):
    (robot, model), (recordings, change, theta_ols) = arm, balanced
    q = recordings[0].q[::5]  # the departures' poses (``gravity_load.STRIDE``)
    truth = np.sqrt(np.mean(_gravity(robot, q, change)[:, 1] ** 2)) / SIGMA[1]
    departed = departed_noise(robot, model, recordings, theta_ols, {1: "named"}, lambda: SIGMA)
    assert departed[1] == pytest.approx(truth, rel=1e-6) and truth > NAME_SIGMA
    assert not np.any(np.delete(departed, 1))
    # only on the joints a departure named: none, nothing read
    assert not np.any(departed_noise(robot, model, recordings, theta_ols, {}, lambda: pytest.fail("read")))
    # least squares that leave the file's gravity torque (the bounds made the departure): nothing asked
    file = model.base_parameters(robot.nominal_dynamic_parameters())
    assert not np.any(departed_noise(robot, model, recordings, file, {1: "named"}, SIGMA))


def test_a_counterbalance_inside_the_envelopes_is_named_where_its_departure_asks_for_it(denso):
    """Link 2 named a counterbalance on joint 2 after its departure, the bounds refusing joint 2 0.84 noise levels:
    named where the data's departure there is ``NAME_SIGMA`` noise levels or more, as none below, and as none on
    joint 3 where the departure is joint 2's."""
    link2 = EnvelopeFinding(1, ("envelope",), 1.0, 1.0, 1.0, 0.3, 0.0, 0.0, "counterbalance", 4, 466.0, 16.2, 1e3,
                            effect_joint=1, alternatives=("payload",), evidence="a departure")  # fmt: skip
    refused = np.array([0.2, 0.84, 0.6, 0.3, 16.2, 0.0])
    on_2 = np.zeros(6)
    for size, named in ((25.1, "counterbalance"), (NAME_SIGMA, "counterbalance"), (0.9 * NAME_SIGMA, UNNAMED)):
        on_2[1] = size
        (finding,), _ = named_where_asked((link2,), (), refused, denso, departed=on_2)
        assert finding.absorbs == named, size
    (on_3,), _ = named_where_asked((replace(link2, effect_joint=2),), (), refused, denso, departed=25.1 * np.eye(6)[1])
    assert on_3.absorbs == UNNAMED
    (alone,), _ = named_where_asked((link2,), (), refused, denso)  # main's rule: the refused torque alone
    assert alone.absorbs == UNNAMED
