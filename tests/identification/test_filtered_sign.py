"""The Coulomb column filtered like the torque (``filtered_sign``), chosen per joint (``filtered_choice``).

The truth is the Denso's rigid body by Pinocchio plus a sharp Coulomb friction ``fc sign(qd)`` (and viscous friction)
recorded at 200 Hz with white noise, so the prepared torque holds the filter's response to a sign at every reversal:
on a Coulomb joint the choice must take the filtered form, on a joint without Coulomb friction keep ``tanh`` (nothing
to gain), and the model fitted with it must predict a held-out recording better than the model with ``tanh`` of the
filtered velocity on every joint.
"""

from dataclasses import replace

import numpy as np

from identification.calibration.calibrated_model import FILTERED_VERSION, CalibratedModel
from identification.calibration.column_choice import choose_columns
from identification.calibration.model_preparation import model_preparation
from identification.calibration.trajectory_data import prepare_recording
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories, predict_torque
from identification.data.recording import Recording
from psdm_casadi.oracle import PinocchioOracle
from trajopt.experiments import sine_experiment

FC = np.array([3.0, 3.0, 2.0, 0.0, 1.0, 0.0])  # [N m]: none on joints 4 and 6


def recording(robot, seed):
    """The Denso's true torque: rigid body, Coulomb friction ``FC sign(qd)``, viscous 1 N m s/rad, noise of 0.05 N m,
    6 s at 200 Hz."""
    rng = np.random.default_rng(seed)
    experiment = sine_experiment(robot, duration=6.0, rng=rng)
    t = experiment.time_grid(200.0)
    q, qd, qdd = experiment.sample(t)
    tau = PinocchioOracle(robot).rnea(q, qd, qdd) + FC * np.sign(qd) + qd
    return Recording(t=t, q=q, tau=tau + rng.normal(scale=0.05, size=tau.shape), name=f"sine{seed}")


def held_out_rmse(robot, model, train, held, options) -> np.ndarray:
    fit = identify_trajectories(robot, model, [train], replace(options, consistency=False))
    ready = prepare_recording(held, None, fit.cutoff_hz[0], fit.edge_periods, fit.filtered_sign)[0]
    return np.sqrt(np.mean((predict_torque(model, fit, ready.q, ready.qd, ready.qdd, sign=ready.sign) - ready.tau) ** 2,
                           axis=0))  # fmt: skip


def test_a_sharp_coulomb_friction_takes_the_filtered_column_and_predicts_held_out_data_better(denso, denso_model):
    train, held = recording(denso, 1), recording(denso, 2)
    choice = choose_columns(denso, denso_model, [train])
    assert choice.filtered_joints == (0, 1, 2, 4)  # the joints with Coulomb friction
    assert choice.friction == "coulomb-viscous"  # no Stribeck hump mimics the filter's smearing of the step
    options = choice.options(TrajectoryOptions())
    assert options.filtered_sign == (0, 1, 2, 4)
    filtered = held_out_rmse(denso, denso_model, train, held, options)
    smooth = held_out_rmse(denso, denso_model, train, held, replace(options, filtered_sign=()))
    coulomb = FC > 0
    assert np.all(filtered[coulomb] < 0.6 * smooth[coulomb]), (filtered, smooth)
    assert np.all(filtered < 1.05 * smooth) and np.all(filtered < 0.1), (filtered, smooth)  # no joint worse
    assert any("filter applied to the raw velocity's sign on joints 1, 2, 3, 5" in line
               for line in choice.describe())  # fmt: skip


def test_the_model_file_records_the_filtered_joints_and_validate_computes_them(denso, denso_model):
    train = recording(denso, 4)
    options = TrajectoryOptions(consistency=False, filtered_sign=(0, 3))
    fit = identify_trajectories(denso, denso_model, [train], options)
    calibrated = CalibratedModel.from_fit(denso, denso_model, fit, robot_source="denso_vs6556g")
    assert calibrated.document["version"] == FILTERED_VERSION
    assert calibrated.document["identification"]["preparation"]["filtered_sign"] == [1, 4]
    assert model_preparation(calibrated.document).filtered_sign == (0, 3)
    held = recording(denso, 5)
    ready, predicted = calibrated.predict_recording(denso_model, held)
    assert np.all(np.isnan(ready.sign[:, [1, 2, 4, 5]]))
    moving = np.abs(ready.qd[:, [0, 3]]) > 0.3  # away from the reversals the sign, the filter ringing after it
    np.testing.assert_allclose(ready.sign[:, [0, 3]][moving], np.sign(ready.qd[:, [0, 3]])[moving], atol=0.2)
    np.testing.assert_allclose(predicted, predict_torque(denso_model, fit, ready.q, ready.qd, ready.qdd,
                                                         sign=ready.sign), rtol=1e-9, atol=1e-9)  # fmt: skip
    single = calibrated.predict(denso_model, ready.q, ready.qd, ready.qdd)  # at a state: tanh on every joint
    reversing = np.abs(ready.qd[:, 0]) < 0.02
    assert np.any(np.abs(single - predicted)[reversing, 0] > 0.1)
    assert np.allclose(single[:, 1], predicted[:, 1])
