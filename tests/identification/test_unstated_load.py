"""A training recording that carries a load no file states: identify takes it as an unknown payload of its own.

The truth is the virtual Denso's (``identification.virtual``): its nominal links, and an 8 kg body at the flange on
one of two recordings that no sidecar mentions. Before, identify warned ("loaded.csv looks as if it carries ...")
and fitted one arm across both loads: the links absorbed the load (on a 210 kg-class arm with an unstated 85 kg
gripper, joint 2 validated at 4.8 x its noise floor and its counterbalance went unnamed).
"""

import warnings
from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.identify_route import identify_recordings
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.calibration.unstated_load import take_unstated_loads
from identification.data.configuration import PayloadConfiguration
from identification.virtual.effects import Payload as VirtualPayload
from identification.virtual.simulation import SimulationOptions, simulate_recording
from trajopt.experiments import sine_experiment

LOAD = VirtualPayload(mass=8.0, com=(0.0, 0.02, 0.08))


def _record(robot, seed, extras=(), name="run.csv"):
    rng = np.random.default_rng(seed)
    reference = sine_experiment(robot, duration=8.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=True)
    with warnings.catch_warnings():  # the sine experiment may graze a limit: irrelevant here
        warnings.simplefilter("ignore")
        return replace(simulate_recording(robot, reference, options, rng, extras=extras)[0], name=name)


@pytest.fixture(scope="module")
def pair(denso):
    """The virtual Denso empty, then with the 8 kg load that nothing states."""
    return [_record(denso, 11, name="empty.csv"), _record(denso, 12, (LOAD,), name="loaded.csv")]


def _fit_of(denso, denso_model, recordings, options):
    return lambda trial: identify_trajectories(denso, denso_model, recordings, options, configurations=trial)


def _mass_error(denso, standard) -> float:
    """The largest relative error of the moving links' masses against the truth."""
    truth = np.array([link.mass for link in denso.links])
    heavy = truth > 0
    return float(np.max(np.abs(np.asarray(standard)[heavy, 0] / truth[heavy] - 1.0)))


def test_an_unstated_load_becomes_an_unknown_payload_of_its_recording(denso, denso_model, pair):
    options = TrajectoryOptions()
    found = _fit_of(denso, denso_model, pair, replace(options, consistency=False))
    configurations, unstated = take_unstated_loads(found, pair, None)
    (taken,) = unstated.found
    assert taken.name == "loaded.csv" and abs(taken.mass - LOAD.mass) < 3 * taken.mass_std, taken
    assert configurations[0].kind == "none" and configurations[1].kind == "unknown"
    assert configurations[1].name == "unstated load (loaded.csv)", configurations[1]
    said = unstated.describe()
    assert said.startswith("loaded.csv carries") and "loaded.payload.json" in said and '{"mass": 0}' in said, said
    fit = identify_trajectories(denso, denso_model, pair, options, configurations=configurations)
    (payload,) = fit.payloads
    assert abs(payload.mass - LOAD.mass) < max(3 * payload.mass_std, 0.05 * LOAD.mass), payload
    # the arm: its links no longer hold the load, as one arm fitted across both loads did (what identify wrote before)
    mixed = identify_trajectories(denso, denso_model, pair, options)
    assert _mass_error(denso, fit.standard) < 0.5 * _mass_error(denso, mixed.standard), (
        _mass_error(denso, fit.standard),
        _mass_error(denso, mixed.standard),
    )


@pytest.mark.slow
def test_identify_takes_the_unstated_load_and_says_so(denso, denso_model, pair):
    """``identify_recordings`` (the command's route) takes it by default, says so first and stores it in the model
    file: the configurations block (which ``psdm diagnose MODEL`` reads for the recording) and the decision."""
    result = identify_recordings(denso, denso_model, pair, TrajectoryOptions(), configurations=None)
    assert [f.name for f in result.unstated.found] == ["loaded.csv"]
    (entry,) = [c for c in result.calibrated.configurations if c["kind"] == "unknown"]
    assert entry["name"] == "unstated load (loaded.csv)" and entry["recordings"] == ["loaded.csv"], entry
    mass, std = entry["payload"]["mass"], entry["payload"]["mass_std"]
    assert abs(mass - LOAD.mass) < max(3 * std, 0.05 * LOAD.mass), (mass, std)
    assert result.describe()[0].startswith("unstated load: loaded.csv carries"), result.describe()
    assert result.calibrated.document["identification"]["unstated_loads"]["taken"][0]["recording"] == "loaded.csv"


def test_a_stated_load_is_the_users_and_equal_loads_take_nothing(denso, denso_model, pair):
    """A sidecar that says ``{"mass": 0}`` is a statement: identify keeps it (and warns, as before). Two unloaded
    recordings: nothing is taken."""
    options = TrajectoryOptions(consistency=False)

    def fit_of(recordings):
        return _fit_of(denso, denso_model, recordings, options)

    stated = [PayloadConfiguration(), PayloadConfiguration(stated=True)]  # loaded.csv: {"mass": 0}
    kept, unstated = take_unstated_loads(fit_of(pair), pair, stated)
    assert kept == stated and not unstated.found and "stated" in unstated.reason, unstated
    empty = [pair[0], _record(denso, 14, name="empty_again.csv")]
    kept, unstated = take_unstated_loads(fit_of(empty), empty, None)
    assert not unstated.found and all(c.kind == "none" for c in kept), unstated
