"""``--friction lugre`` with payload configurations: the LuGre fits see the arm's friction, the loads taken out.

The truth is the virtual Denso with LuGre friction of ``lugre_recordings_data`` (its bristles integrated exactly by the
virtual robot), recorded empty, with a known load and with an unknown one at the flange
(``identification.virtual.effects.Payload``). The unknown load's mass and centre of mass and the LuGre parameters are
checked against that truth, and ``psdm identify --friction lugre`` takes a stated payload (it refused it before).
"""

import json

import numpy as np
import pytest

from identification.calibration.lugre_identify import identify_lugre_trajectories
from identification.calibration.trajectory_fit import TrajectoryOptions
from identification.data.configuration import PayloadConfiguration
from identification.data.io import save_recording
from identification.data.payload import Payload
from identification.virtual.effects import Payload as VirtualPayload
from tests.identification.lugre_recordings_data import CUTOFF, TRUTH, lugre_recording

KNOWN = Payload(mass=0.6, com=(0.0, 0.02, 0.04))
UNKNOWN = VirtualPayload(mass=0.8, com=(0.03, 0.0, 0.06))
#: relative error of the sliding friction recovered beside the loads, at speeds past the Stribeck dip (>= 2.5 vs of
#: every joint: the truth's Stribeck term is below 0.2 % of fs there; the split of fc, fs and vs inside the dip is
#: loosely determined by 36 s of recordings, 6 % off at 0.3 rad/s on joint 1, the load or not)
SLIDING_TOLERANCE = 0.05
SPEEDS = np.linspace(0.5, 1.0, 6)  # [rad/s]


def sliding(fc, fs, vs, fv):
    """The steady-state LuGre friction (dv = 1) at ``SPEEDS``, (joints, speeds)."""
    fc, fs, vs, fv = (np.asarray(x, dtype=float)[:, None] for x in (fc, fs, vs, fv))
    return fc + (fs - fc) * np.exp(-((SPEEDS / vs) ** 2)) + fv * SPEEDS


@pytest.fixture(scope="module")
def recorded(denso):
    known = VirtualPayload(mass=KNOWN.mass, com=KNOWN.com)
    return [lugre_recording(denso, 1, 12.0), lugre_recording(denso, 3, 12.0, (known,)),
            lugre_recording(denso, 4, 12.0, (UNKNOWN,))]  # fmt: skip


CONFIGURATIONS = [PayloadConfiguration(), PayloadConfiguration("mass", payload=KNOWN, stated=True),
                  PayloadConfiguration("tool", unknown=True, stated=True)]  # fmt: skip


@pytest.mark.slow
def test_lugre_with_stated_payloads_recovers_the_load_and_the_friction(denso, denso_model, recorded):
    options = TrajectoryOptions(friction=("fc", "fs", "fv"), cutoff_hz=CUTOFF)
    result = identify_lugre_trajectories(denso, denso_model, recorded, options, configurations=CONFIGURATIONS)
    (tool,) = result.fit.payloads
    assert tool.name == "tool" and tool.identifiable
    assert abs(tool.mass - UNKNOWN.mass) < 0.1 * UNKNOWN.mass, tool.mass
    assert np.linalg.norm(np.subtract(tool.com, UNKNOWN.com)) < 0.02, tool.com
    found = result.lugre.parameters
    identified = sliding(*([getattr(p, name) for p in found] for name in ("fc", "fs", "vs", "fv")))
    truth = sliding(*(TRUTH[name] for name in ("fc", "fs", "vs", "fv")))
    error = np.abs(identified - truth) / truth
    assert error.max() < SLIDING_TOLERANCE, np.round(error.max(axis=1), 3)  # the loads did not pass for friction
    arm = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    z = np.abs((result.fit.theta_ols - arm) / result.fit.theta_std)
    assert z.max() < 6.0, np.round(z, 1)  # the arm shared by the three configurations, the loads not in it


@pytest.mark.slow
def test_identify_lugre_takes_a_stated_payload(recorded, tmp_path, capsys):
    from psdm_casadi.cli import main

    for name, recording in zip(("empty", "mass", "tool"), recorded):
        save_recording(recording, tmp_path / f"{name}.npz")
    (tmp_path / "mass.payload.json").write_text('{"mass": 0.6, "com": [0.0, 0.02, 0.04]}')
    (tmp_path / "tool.payload.json").write_text('{"unknown": "tool"}')
    out = tmp_path / "model.json"
    argv = ["identify", "denso_vs6556g", "--data", *(str(tmp_path / f"{n}.npz") for n in ("empty", "mass", "tool")),
            "--friction", "lugre", "--cutoff", str(CUTOFF), "--out", str(out), "--json"]  # fmt: skip
    assert main(argv) == 0
    (payload,) = json.loads(capsys.readouterr().out)["payloads"]
    assert payload["name"] == "tool" and payload["mass"] == pytest.approx(UNKNOWN.mass, rel=0.1)
    document = json.loads(out.read_text())
    assert document["drive"]["friction_shape"] == "lugre"
    assert [c["kind"] for c in document["configurations"]] == ["none", "known", "unknown"]
