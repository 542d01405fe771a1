"""A torque offset read with the robot file's rigid body held (``calibration.file_held_offset``).

Known truth: the virtual Denso (its robot file) with a hidden load torque on joint 2 and 0.1 N m of torque noise,
fitted with a torque offset on joint 2 (as the column choice takes one where the data want it). A gas-spring
balancer taking half of joint 2's gravity amplitude is read as a balancer; a sensor's constant offset is not, nor, with
a sensor offset, a robot file whose links are a fifth heavier than the arm's: the share of the file's gravity torque
the residual takes away is the truth's (1 - 1 / 1.2), within what the file's masses may be off by (the mass bounds'
35 %), which holds it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.file_held_offset import file_held_offsets
from identification.calibration.offset_or_balancer import BALANCER
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.virtual import effects as xp
from identification.virtual.counterbalance import balance, gas_spring_counterbalance
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.description import LinkInertia
from trajopt.experiments import sine_experiment


def _reading(denso, denso_model, truth, extras):
    """(the reading of joint 2's offset, the recorded training poses): 8 s of ``truth`` with ``extras`` to train on,
    8 s held out; the fit and the reading on ``denso``'s file."""
    rng = np.random.default_rng(5)
    reference = sine_experiment(truth, duration=16.0, rng=rng).reference()
    simulation = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    recording, _ = simulate_recording(truth, reference, simulation, rng, extras=extras)
    train, held_out = recording.time_slice(-np.inf, 8.0), recording.time_slice(8.0, np.inf)
    options = TrajectoryOptions(friction=("fc", "fv", "offset"), offset_joints=(1,))
    fit = identify_trajectories(denso, denso_model, [train], options)
    calibrated = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=str(denso.source))
    found = file_held_offsets((denso, denso_model, [train], options, None), fit, calibrated, [held_out], (1,))
    return found.get(1), train.q


def test_a_gas_spring_the_offset_stands_for_is_read_with_the_truth_s_share(denso, denso_model):
    centre = np.mean(sine_experiment(denso, duration=16.0, rng=np.random.default_rng(5)).reference()[1], axis=0)
    gas = gas_spring_counterbalance(denso, 1, centre, 0.5, a=0.05, b=0.15, stiffening=0.35)
    reading, q = _reading(denso, denso_model, denso, [gas])
    assert balance(denso, gas, q[::10]).opposing == 1.0  # a balancer on every recorded pose
    assert reading.balancer and reading.verdict.verdict == BALANCER, reading.sentence()
    assert "the links absorbed a counterbalance" in reading.sentence()


@pytest.mark.parametrize("heavier", [1.0, 1.2])
def test_a_sensor_offset_is_not_a_balancer_even_with_the_file_s_links_off(denso, denso_model, heavier):
    # the arm's links lighter than the file states (the file ``heavier`` times the truth): the file-held residual
    # takes 1 - 1/heavier of the file's gravity torque away, a torque of the angle its masses can be off by
    links = tuple(dataclasses.replace(k, mass=k.mass / heavier) if isinstance(k, LinkInertia) else k
                  for k in denso.links)  # fmt: skip
    truth = dataclasses.replace(denso, links=links)
    offset = np.zeros(denso.n_dof)
    offset[1] = 0.8
    reading, _ = _reading(denso, denso_model, truth, [xp.TorqueOffset(offset=tuple(offset))])
    assert reading is not None and not reading.balancer, reading.sentence()
    assert reading.share == pytest.approx(1.0 - 1.0 / heavier, abs=0.05)  # the file's gravity torque's excess
    assert "no torque of the angle the file's masses cannot hold" in reading.sentence()
