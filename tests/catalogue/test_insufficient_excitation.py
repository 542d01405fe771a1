"""Bad inputs: recordings that do not excite what is identified from them (issue 17, "nonsense with exit 0").

A robot that stood still, held one joint, sat at a constant offset or dithered by a fraction of a
milliradian gave ``psdm diagnose`` a 37 kg payload and ``psdm identify`` a mass matrix with eigenvalue
-7e12, both with exit 0. Each case here must be refused with exit 2, naming the file, the joint and what
to record instead, before any fit (the CSVs are short, so every case is fast).
"""

from __future__ import annotations

import io
from dataclasses import replace

import numpy as np
import pytest

from psdm_casadi.robot import load_robot
from tests.catalogue.harness import BadInput, check_refusal

ROBOT = load_robot("denso_vs6556g")
N = ROBOT.n_dof
RATE = 100.0
HOME = 0.5 * (ROBOT.q_min + ROBOT.q_max)
SPAN = ROBOT.q_max - ROBOT.q_min
PAYLOAD = '{"mass": 2.0, "com": [0.05, 0.0, 0.05]}\n'


def _t(duration=4.0):
    return np.arange(0.0, duration, 1.0 / RATE)


def _csv(q, signal="tau", value=None) -> str:
    """A recording CSV (t, q1..q6, tau1..6 or i1..6) of positions ``q`` sampled at RATE; torques ``value``, by
    default a slow sine per joint (a torque column constant throughout is a dead channel, refused before the
    motion is judged)."""
    t = np.arange(q.shape[0]) / RATE
    default = 0.5 * np.sin(2.0 * np.pi * 0.3 * np.outer(t, np.arange(1, q.shape[1] + 1)))
    other = default if value is None else np.broadcast_to(value, q.shape)
    prefix = "tau" if signal == "tau" else "i"
    header = ",".join(["t"] + [f"q{j + 1}" for j in range(N)] + [f"{prefix}{j + 1}" for j in range(N)])
    buffer = io.StringIO()
    np.savetxt(buffer, np.column_stack([t, q, other]), fmt="%.9g", delimiter=",", header=header, comments="")
    return buffer.getvalue()


def _moving(seed=0, duration=4.0):
    """Every joint on two sines about the middle of its range: a quarter of the range, well above the thresholds."""
    rng = np.random.default_rng(seed)
    t = _t(duration)
    f = rng.uniform(0.4, 0.8, (2, N))
    return HOME + 0.12 * SPAN * (
        np.sin(2 * np.pi * f[0] * t[:, None]) + 0.5 * np.sin(2 * np.pi * f[1] * t[:, None] + 1)
    )


def _still(offset=0.0, duration=4.0):
    return np.tile(HOME + offset, (_t(duration).size, 1))


def _one_still(joint, seed=0):
    q = _moving(seed)
    q[:, joint] = HOME[joint] + 0.2
    return q


def _dither(amplitude=1e-4):
    t = _t()
    return HOME + amplitude * np.sin(2 * np.pi * 2.0 * t[:, None] + np.arange(N))


def _sub_step(joint, step=1e-3):
    """Every joint quantised to ``step``; ``joint`` toggles between two encoder counts (moves less than a step)."""
    q = _moving()
    q[:, joint] = HOME[joint] + 0.4 * step * np.sin(2 * np.pi * 3.0 * _t()) + 0.3 * step
    return step * np.round(q / step)


def _sweep(joint, duration=4.0):
    """Joint ``joint`` out by 1 rad and back (motor sweep), the others held."""
    t = _t(duration)
    q = _still(duration=duration)
    q[:, joint] += 1.0 - np.abs(2.0 * t / duration - 1.0)
    return q


def _oscillation(joint, amplitude=0.5):
    """Joint ``joint`` sliding both ways (peak 1.6 rad/s), the others held: a friction experiment."""
    q = _still()
    q[:, joint] += amplitude * np.sin(2 * np.pi * 0.5 * _t())
    return q


def _one_way(joint):
    """Joint ``joint`` moves out at 0.5 rad/s and stays there: it never slides back."""
    q = _still()
    q[:, joint] += 0.5 * np.minimum(_t(), 2.0)
    return q


def _data(overrides=None) -> dict:
    """A calibration data directory (identification.data.dataset) whose recordings all move as designed, with
    ``overrides`` (file name -> (q, current)) replacing some."""
    files = {
        "data/payload.json": PAYLOAD,
        "data/motor_j1_nominal.csv": _csv(_sweep(0), "i"),
        "data/motor_j1_payload.csv": _csv(_sweep(0), "i"),
        "data/gravity.csv": _csv(_moving(1), "i"),
        "data/friction_j1.csv": _csv(_oscillation(0), "i"),
        "data/excitation.csv": _csv(_moving(2), "i"),
    }
    files.update({f"data/{name}": _csv(q, "i", value) for name, (q, value) in (overrides or {}).items()})
    return files


def _diagnose(name, train, validate, expect):
    argv = ("diagnose", "denso_vs6556g", "--train", "{tmp}/A.csv", "--validate", "{tmp}/B.csv")
    return BadInput(name, argv, expect, files={"A.csv": _csv(train), "B.csv": _csv(validate)})


def _identify(name, expect, file, q, current=None):
    """``psdm identify`` on the data directory with ``file`` replaced by positions ``q`` (currents ``current``)."""
    argv = ("identify", "denso_vs6556g", "--data", "{tmp}/data", "--out", "{tmp}/out", "--model", "{model}")
    return BadInput(name, argv, expect, files=_data({file: (q, current)}))


FIX_RECORD = "psdm excite"


def _ramp_on(joint):
    """Every joint on its sines but ``joint``, which moves one way only (a ramp): no reversal to fit LuGre on."""
    q = _moving()
    q[:, joint] = HOME[joint] + 0.1 * SPAN[joint] * _t() / _t()[-1]
    return q


CASES = [
    # psdm diagnose: every joint must move in the training and the validation recording
    _diagnose("diagnose: motionless training", _still(), _moving(1), ("A.csv", "joint 1", "joint 6", FIX_RECORD)),
    _diagnose("diagnose: motionless validation", _moving(0), _still(), ("B.csv", "joint 1", "validation", FIX_RECORD)),
    _diagnose("diagnose: joint 3 still in training", _one_still(2), _moving(1), ("A.csv", "joint 3 (J3)", "record")),
    _diagnose("diagnose: joint 5 still in validation", _moving(0), _one_still(4, 1), ("B.csv", "joint 5", "record")),
    _diagnose("diagnose: constant offset", _still(0.3), _moving(1), ("A.csv", "range 0 rad", FIX_RECORD)),
    _diagnose("diagnose: tiny dither", _dither(), _moving(1), ("A.csv", "joint 2", "must move", FIX_RECORD)),
    _diagnose("diagnose: joint 2 below one encoder step", _sub_step(1), _moving(1), ("A.csv", "joint 2", "record")),
    _diagnose(
        "diagnose: still robot with encoder noise",
        _still() + 2e-6 * np.random.default_rng(5).standard_normal((_t().size, N)),
        _moving(1),
        ("A.csv", "joint 4", FIX_RECORD),
    ),
    # psdm identify --friction lugre on recordings: every joint must reverse, refused before any fit
    BadInput(
        "identify --friction lugre: joint 2 never reverses",
        ("identify", "denso_vs6556g", "--data", "A.csv", "--friction", "lugre", "--out", "m.json"),
        ("A.csv joint 2", "both directions", "--friction stribeck"),
        files={"A.csv": _csv(_ramp_on(1))},
    ),
    # psdm identify: refused before step 1, the experiment named
    _identify("identify: motionless excitation", ("excitation.csv", "joint 1", FIX_RECORD), "excitation.csv", _still()),
    _identify(
        "identify: excitation with joint 6 still",
        ("excitation.csv", "joint 6 (J6)", FIX_RECORD),
        "excitation.csv",
        _one_still(5),
    ),
    _identify(
        "identify: excitation at a constant offset",
        ("excitation.csv", "inertial step", FIX_RECORD),
        "excitation.csv",
        _still(0.2),
        1.5,
    ),
    _identify(
        "identify: excitation dithering", ("excitation.csv", "must move", FIX_RECORD), "excitation.csv", _dither(2e-4)
    ),
    _identify(
        "identify: excitation below one encoder step",
        ("excitation.csv", "joint 4", FIX_RECORD),
        "excitation.csv",
        _sub_step(3),
    ),
    _identify(
        "identify: motionless friction experiment",
        ("friction_j1.csv", "joint 1", "psdm experiment friction --joint 1"),
        "friction_j1.csv",
        _still(),
    ),
    _identify(
        "identify: friction experiment sliding one way",
        ("friction_j1.csv", "both directions", "psdm experiment friction --joint 1"),
        "friction_j1.csv",
        _one_way(0),
    ),
    _identify(
        "identify: friction experiment dithering",
        ("friction_j1.csv", "joint 1", "record friction_j1"),
        "friction_j1.csv",
        _oscillation(0, amplitude=1e-4),
    ),
    _identify(
        "identify: motionless motor sweep",
        ("motor_j1_nominal.csv", "joint 1", "psdm experiment motor --joint 1"),
        "motor_j1_nominal.csv",
        _still(),
    ),
    _identify(
        "identify: motionless gravity jog",
        ("gravity.csv", "joint 2", "psdm experiment gravity"),
        "gravity.csv",
        _still(),
    ),
    _identify(
        "identify: gravity jog with joint 3 still",
        ("gravity.csv", "joint 3 (J3)", "gravity step"),
        "gravity.csv",
        _one_still(2, 1),
    ),
]


@pytest.fixture(scope="module")
def model_file(tmp_path_factory, denso_model):
    return str(denso_model.save(tmp_path_factory.mktemp("model") / "denso.npz"))


@pytest.mark.parametrize("case", CASES, ids=str)
def test_insufficient_excitation_is_refused(case, model_file, tmp_path, capsys, monkeypatch):
    case = replace(case, argv=tuple(a.replace("{model}", model_file) for a in case.argv))
    check_refusal(case, tmp_path, capsys, monkeypatch)


def test_the_well_excited_inputs_of_the_cases_pass_the_checks(denso, denso_model, tmp_path):
    """The cases differ from these by the one bad recording: the data directory and the pair pass the checks."""
    from identification.calibration.excitation import check_calibration_data
    from identification.data.dataset import load_calibration_data
    from identification.data.io import load_recording
    from identification.diagnosis.diagnose import DiagnosisOptions, check_motion
    from tests.catalogue.harness import write_files

    write_files(tmp_path, _data())
    check_calibration_data(denso, denso_model, load_calibration_data(tmp_path / "data", N))
    write_files(tmp_path, {"A.csv": _csv(_moving(0)), "B.csv": _csv(_moving(1))})
    check_motion(
        denso, load_recording(tmp_path / "A.csv", N), load_recording(tmp_path / "B.csv", N), DiagnosisOptions()
    )
