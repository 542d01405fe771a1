"""The floor under each link's rotational inertia (``inertia_floor``) and the warning before an export writes a link
below it (issue 25, item 1: plausible, not only consistent).

References: closed forms of uniform boxes (a box shrunk by ``s`` about its centre keeps ``s^2`` of its second moment
per unit mass), NumPy's eigenvalues of the pseudo-inertia minus the floor (the cone the chart and the barrier keep), a
virtual Denso whose truth (its robot file with a CAD error) is known, trained on a short recording with noisy
torques so that three of its links are hardly determined, and the shared Kinova Gen3 logs (slow; skipped without
them), whose vendor URDF's wrist links the sensors hardly see.
"""

from __future__ import annotations

import json
import re
from unittest import mock

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from identification.calibration import consistent_fit
from identification.calibration.barrier_path import pivots
from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.consistent_fit import chart_start
from identification.calibration.inertia_floor import AT_FLOOR, FLOOR_SHARE, inertia_share, link_floors, stiff_links
from identification.calibration.pseudo_inertia import link_from_log_cholesky, pseudo_inertia
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.description import physical_to_dynamic
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import LinkInertia
from tests.conftest import DATASETS, DENSO_FILE
from trajopt.experiments import sine_experiment

KINOVA = DATASETS / "kinova_gen3_dynid"


def _box(mass, centre, half, rotation):
    a, b, c = 2 * np.asarray(half)
    inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return physical_to_dynamic(mass, centre, rotation @ inertia @ rotation.T)


def _floor_cone(link, floor):
    """``J - m diag(F, 0)``: positive semi-definite exactly when the link keeps its floor (module docstring)."""
    matrix = pseudo_inertia(link)
    matrix[:3, :3] -= link[0] * floor
    return matrix


def test_a_box_shrunk_about_its_centre_keeps_the_square_of_its_shrink():
    rng = np.random.default_rng(1)
    for _ in range(5):
        rotation = Rotation.random(random_state=rng).as_matrix()
        centre, half = rng.normal(size=3) * 0.2, rng.uniform(0.02, 0.3, 3)
        file = _box(rng.uniform(0.5, 5.0), centre, half, rotation)
        for shrink in (0.3, 0.5, 1.0, 1.7):
            other = _box(rng.uniform(0.5, 5.0), centre + rng.normal(size=3) * 0.1, shrink * half, rotation)
            assert inertia_share(other, file) == pytest.approx(shrink**2, rel=1e-9)  # any mass, any centre
        assert inertia_share(physical_to_dynamic(2.0, centre, np.zeros((3, 3))), file) == pytest.approx(0.0, abs=1e-12)


def test_the_chart_and_the_barrier_keep_exactly_the_links_on_or_above_their_floor():
    rng = np.random.default_rng(2)
    symbol = ca.SX.sym("v", 10)
    for _ in range(20):
        base = rng.normal(size=(3, 3))
        floor = 0.01 * base @ base.T
        link = link_from_log_cholesky(rng.normal(size=10), 1e-6, floor)  # any chart point keeps the floor
        assert np.linalg.eigvalsh(_floor_cone(link, floor))[0] > 0
        np.testing.assert_allclose(link_from_log_cholesky(chart_start(link, 1e-6, floor), 1e-6, floor), link,
                                   rtol=1e-8, atol=1e-12)  # fmt: skip
        steps = ca.Function("p", [symbol], pivots(symbol, 0.0, 1.0, floor))
        for candidate in (link, physical_to_dynamic(link[0], link[1:4] / link[0], np.zeros((3, 3)))):
            inside = np.linalg.eigvalsh(_floor_cone(candidate, floor))[0] > 0
            assert all(float(d) > 0 for d in steps(candidate)) == inside  # Sylvester on the moved cone


@pytest.fixture(scope="module")
def poorly_excited(denso, denso_model):
    """A Denso whose truth is its robot file with a CAD error, trained on 3 s of torques with 0.3 N m noise: fitted
    without the floor (``link_floors`` giving none) and with it."""
    rng = np.random.default_rng(0)
    links = [LinkInertia(mass=link.mass * f, com=np.asarray(link.com), inertia=np.asarray(link.inertia) * g)
             for link, f, g in zip(denso.links, rng.uniform(0.85, 1.15, 6), rng.uniform(0.7, 1.3, 6))]  # fmt: skip
    truth = denso.with_links(links)
    reference = sine_experiment(denso, duration=3.0, rng=np.random.default_rng(3)).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.3, friction=False)
    recording, _ = simulate_recording(truth, reference, options, np.random.default_rng(3))
    with mock.patch.object(consistent_fit, "link_floors", lambda robot, free=None: (None,) * robot.n_dof):
        free = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions())
    fit = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions())
    return truth, free, fit


def test_a_poorly_excited_link_stays_on_its_floor_and_the_truth_is_above_it(denso, poorly_excited):
    truth, free, fit = poorly_excited
    prior, true = denso.nominal_dynamic_parameters(), truth.nominal_dynamic_parameters()
    floored = [i for i, floor in enumerate(link_floors(denso)) if floor is not None]
    assert floored == [0, 1, 2, 3, 4]  # link 6 of the Denso has no mass in its file: no floor
    shares = {name: np.array([inertia_share(standard[i], prior[i]) for i in floored])
              for name, standard in (("free", free.standard), ("fit", fit.standard), ("truth", true))}  # fmt: skip
    assert np.all(shares["truth"] >= 2 * FLOOR_SHARE)  # the truth is well inside its floor
    assert np.sum(shares["free"] < FLOOR_SHARE / 2) >= 2, shares  # without it, links collapse to a point ...
    assert np.all(shares["fit"] >= FLOOR_SHARE / AT_FLOOR), shares  # ... with it, none is below
    assert fit.consistent and free.consistent
    # predicted torques against the truth's on states the recording did not hold: the floor costs nothing there
    rng = np.random.default_rng(5)
    q, qd, qdd = rng.uniform(-1.5, 1.5, (300, 6)), rng.uniform(-1, 1, (300, 6)), rng.uniform(-3, 3, (300, 6))
    expected = PinocchioOracle(truth).rnea(q, qd, qdd)
    error = {name: np.sqrt(np.mean((PinocchioOracle(denso, f.standard).rnea(q, qd, qdd) - expected) ** 2, axis=0))
             for name, f in (("free", free), ("fit", fit))}  # fmt: skip
    assert np.all(error["fit"] <= 1.05 * error["free"] + 0.01 * 0.3), error


def identify_options() -> set:
    """The options ``psdm identify`` parses (its subparser of the command line's parser)."""
    import argparse

    from psdm_casadi.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {s for a in sub.choices["identify"]._actions for s in a.option_strings}


def test_the_report_and_the_model_file_name_the_links_on_their_floor(poorly_excited):
    _, _, fit = poorly_excited
    entry = dict(fit.envelope_bounds)["inertia_floor"]
    assert entry["share"] == FLOOR_SHARE and entry["links"] == [1, 2, 3, 4, 5]
    named = {note["link"] for note in entry["at_floor"]}
    assert named and named <= {3, 4, 5}
    assert all(
        "psdm excite" in note["message"] and "rests on its floor" in note["message"] for note in entry["at_floor"]
    )
    # what the user can do names an option identify has (it said 'or keep the robot file's inertia of this link',
    # which no option does)
    identify = identify_options()
    for note in entry["at_floor"]:
        named = set(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", note["message"]))
        assert named and named <= identify, (named, note["message"])
        assert "--prior-uncertainty" in named


def test_an_export_warns_about_a_link_below_its_floor_and_not_about_one_on_it(denso, denso_model, poorly_excited,
                                                                              tmp_path, capsys):  # fmt: skip
    _, free, fit = poorly_excited
    below = {i + 1 for i in range(5) if inertia_share(free.standard[i], denso.nominal_dynamic_parameters()[i]) < 0.2}
    assert below
    for name, f in (("free", free), ("fit", fit)):
        CalibratedModel.from_fit(denso, denso_model, f, robot_source=DENSO_FILE).save(tmp_path / f"{name}.json")
    for command, suffix in (("export-urdf", "urdf"), ("export-mjcf", "xml")):
        capsys.readouterr()
        assert main([command, str(tmp_path / "free.json"), str(tmp_path / f"free.{suffix}")]) == 0
        err = capsys.readouterr().err
        warned = {int(w.split("link ")[1].split("'")[0]) for w in err.splitlines() if "plausible floor" in w}
        assert warned == below and (tmp_path / f"free.{suffix}").exists()  # a warning, not a refusal
        assert "psdm excite" in err and "--no-envelope" in err and "--prior-uncertainty" in err
        assert main([command, str(tmp_path / "fit.json"), str(tmp_path / f"fit.{suffix}")]) == 0
        assert "plausible floor" not in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.real_data
def test_the_kinova_wrist_keeps_its_floor_and_its_exported_forward_dynamics_are_not_stiff(tmp_path, capsys):
    """The vendor URDF (no tool, its own inertias) identified on the joint-torque sensors: links 6 and 7, which the
    sensors hardly see, collapsed towards a point without the floor and joint 7's forward dynamics turned stiff; with
    it they rest on their floor, the report says so, and the exported C's acceleration of joint 7 per N m stays
    within 2 x of the robot file's (the mass matrix by Pinocchio)."""
    if not (KINOVA / "opti_traj_testing1.csv").exists():
        pytest.skip(f"Kinova Gen3 data absent in {KINOVA}")
    from codegen.calibrated import build_calibrated_functions
    from identification.calibration.calibrated_model import load_calibrated_model
    from psdm_casadi.model_cache import ModelCache
    from psdm_casadi.robot import load_robot

    drives = "".join(f"[[drive]]\nkt = {kt}\n\n" for kt in [9.13] * 4 + [5.852] * 3)
    robot_file = tmp_path / "vendor.toml"
    robot_file.write_text(f'format = "psdm-robot/1"\nname = "kinova_vendor"\n\n[urdf]\npath = "{KINOVA / "gen3.urdf"}"'
                          f"\n\n[recording]\nsample_rate = 1000.0\n\n{drives}")  # fmt: skip
    argv = ["identify", str(robot_file), "--data", str(KINOVA / "opti_traj_testing1.csv"),
            str(KINOVA / "RunTrajectory1.csv"), "--validate", str(KINOVA / "opti_traj_testing2.csv"),
            "--columns", "t=Time,q=Position,tau=TorqueSm"]  # fmt: skip
    assert main([*argv, "--out", str(tmp_path / "model.json")]) == 0
    out = capsys.readouterr().out
    assert "AT ITS INERTIA FLOOR (note): link 7's" in out
    robot = load_robot(robot_file)
    prior = robot.nominal_dynamic_parameters()
    standard = np.array(json.loads((tmp_path / "model.json").read_text())["standard"]["values"]).reshape(7, -1)
    assert min(inertia_share(standard[i], prior[i]) for i in (5, 6)) >= FLOOR_SHARE / AT_FLOOR
    assert not stiff_links(robot, standard)
    calibrated = load_calibrated_model(tmp_path / "model.json")
    forward = build_calibrated_functions(calibrated, ModelCache().derive(robot), robot).forward_dynamics
    torque = np.zeros(7)
    torque[6] = -0.36
    file = np.linalg.inv(PinocchioOracle(robot).crba(np.zeros(7)))[6] @ torque
    still = np.zeros(7)  # forward dynamics are linear in the torque: the difference is M^-1 torque
    qdd = float(np.asarray(forward(still, still, torque) - forward(still, still, still)).ravel()[6])
    assert abs(qdd) < 2 * abs(file), (qdd, file)
    assert main(["codegen", str(tmp_path / "model.json"), "--out", str(tmp_path / "c"), "--json"]) == 0
    assert not [w for w in json.loads(capsys.readouterr().out)["warnings"] if "plausible floor" in w]
