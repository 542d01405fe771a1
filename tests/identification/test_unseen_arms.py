"""Cases of ``benchmarks/unseen_arms.py`` at the seeds the defaults were not tuned on, run as the benchmark runs them
(identify, validate, diagnose, codegen on default settings) and judged against their truth.

- The KR6-like arm moved slowly through gravity poses (seed 1): its joints 1-3 reverse once, in the recording's fast
  start and stop, joints 4 and 6 a dozen times slowly. The Coulomb column's smoothing followed the joints' medians
  (0.05 rad/s kept) and joint 1 validated at 3.95 x its floor; from every reversal it is sharp enough
  (``coulomb_smoothing``).
- The heavy arm with a cam counterbalance and an unknown payload (``benchmarks/heavy_arm.py``, seed 2): identify put
  link 2 at 585 kg (its 2 x bound; file 292.5, the truth's within 20 % of it) and refused the spring it named, which
  raised joint 4 (90.07 -> 91.2 N m held out, margin 0.90) beside the payload's misfit. With the masses held as their
  bounds state them (``prior_pull``) and a joint over its margin worse only where the refits without each training
  block confirm it (``never_worse.TrainingRefits``: +0.58 N m, within it), it takes the cubic spring (joint 2 390.8
  -> 341.6 N m) and link 2 stays at 316 kg.
- The heavy arm with its cam counterbalance (``heavy_counterbalance_slow``) at seed 0: identify reads joint 2's offset
  (+2837 N m, 55 % of its gravity torque) as no sensor's, and the spring it tries does not hold on the held-out
  recording, which takes joint 2 to 0.6 rad against the training's 0.18 (225.8 -> 366.2 N m): the file keeps the
  offset as the counterbalance's stand-in. ``diagnose MODEL`` held it as a sensor's zero and named nothing on joint 2;
  it now leaves it to the diagnosis (``model_file.file_held``), which names the counterbalance.
- The same arm at seed 1 names a smooth Coulomb friction on joint 5 (+203 N m over 0.52 rad/s, every training block
  lower with it): the truth's viscous friction is ``fv |qd|^0.594``, which that column bends the Coulomb-viscous line
  towards (the noiseless truth's least squares gives +193 N m); the benchmark counts a friction shape the truth has as
  there (``unseen_cases.friction_shapes``), and the truth's Coulomb-viscous joints still count it false.
- The HX-210 traced by its controller (``heavy_trace_percent``) at seed 1: joint 2's offset (+546 N m) took most of
  the gas spring's torque over the recorded swing and links 2-3 its swing (link 3 at 128.5 kg, truth 235), each part
  under the file's error alone; the spring named by a held-back term did not lower joint 2 held out and was left.
  Counted together (``gravity_departure``: 33 % of joint 2's gravity torque) they name the counterbalance, whose
  spring is kept as one in place of what the links and offset held (link 3 at 219 kg).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest


@pytest.mark.slow
def test_the_slow_gravity_arm_at_seed_1_fits_to_its_floor_with_the_smoothing_of_its_reversals(
    benchmark_modules, tmp_path
):
    import unseen_arms

    row = unseen_arms.run_case("industrial_slow_gravity_tool", tmp_path, 1)
    assert row["identify_exit"] == 0, row.get("error")
    assert row["rmse_ratio"] <= 2.0, row  # every joint's validation RMSE within 2 x the truth model's (3.95 before)
    assert row["link_mass_ratio"] <= unseen_arms.LIMITS["link_mass_ratio"], row
    assert row["false"] == "-" and row["missed"] == "-", row  # load_dependent_friction[1] was named to make up for it
    assert row["passed"], row
    document = (tmp_path / "model.json").read_text()
    assert "not 0.05 (chosen from the data" in document  # the smoothing stated in the model file's column choice


@pytest.mark.slow
def test_the_heavy_arm_at_seed_2_takes_the_counterbalance_and_keeps_link_2_near_its_mass(benchmark_modules, tmp_path):
    from heavy_arm import run_case

    row = run_case(2, tmp_path)
    assert row["identify_exit"] == 0 and row["envelope_respected"], row
    assert row["counterbalance_taken"], row  # identify keeps the spring on joint 2 it tried
    # the truth's link 2 is the file's within 20 % (CAD-off inertias); the fit within 1.25 x of the file
    assert row["link2_mass_file_kg"] / 1.25 < row["link2_mass_kg"] < 1.25 * row["link2_mass_file_kg"], row
    assert row["rmse_j2_identified"] < 360.0, row  # 390.8 N m held out without the spring
    assert row["diagnose_model_finds_counterbalance"] and row["diagnose_finds_counterbalance"], row


@pytest.mark.slow
def test_the_heavy_arm_at_seed_0_names_the_counterbalance_its_model_file_holds_as_an_offset(
    benchmark_modules, tmp_path
):
    import unseen_arms

    row = unseen_arms.run_case("heavy_counterbalance_slow", tmp_path, 0)
    assert row["identify_exit"] == 0 and row["diagnose_exit"] == 0, row.get("error")
    assert "counterbalance[2]" in row["findings"].split(", "), row  # named by the diagnosis, not only held
    assert row["missed"] == "-" and row["false"] == "-", row


@pytest.mark.slow
def test_the_traced_heavy_arm_at_seed_1_takes_the_balancer_links_2_and_3_shared(benchmark_modules, tmp_path):
    import unseen_arms

    row = unseen_arms.run_case("heavy_trace_percent", tmp_path, 1)
    assert row["identify_exit"] == 0, row.get("error")
    assert "spring[j2] (kept)" in row["identify_named"], row  # "(named)" and left out before
    assert row["link_mass_ratio"] <= unseen_arms.LIMITS["link_mass_ratio"], row  # link 3 at 1.83 x before
    assert row["passed"], row


def test_a_friction_shape_counts_as_there_only_where_the_truth_s_friction_has_it(benchmark_modules, tmp_path):
    """The truth's steady-state friction decides: the heavy arm's drives (the paper's ``fv |qd|^dv``, ``dv`` < 1)
    have the smooth Coulomb bend on every joint; the KR6-like arm's (``dv`` = 1, ``fs`` > ``fc``) a Stribeck hump and
    no bend, so a smooth Coulomb finding there is false."""
    import unseen_arms
    from heavy_arm import heavy_industrial_arm
    from unseen_cases import Case, _kr6_robot, friction_shapes

    from identification.virtual.lugre_exact import LuGreArrays, steady_state_friction

    heavy = heavy_industrial_arm(tmp_path)
    qd = np.linspace(-1.5, 1.5, 601)
    for drive in heavy.drives:  # without the hump, the viscous power is what tanh(qd / 0.5) bends the line towards
        flat = dataclasses.replace(drive, fs=drive.fc)
        residual = []
        for dv in (drive.dv, 1.0):
            truth = steady_state_friction(qd[:, None], LuGreArrays.from_drives([dataclasses.replace(flat, dv=dv)]))
            plain = np.column_stack([np.tanh(qd / 1e-3), qd])
            bent = np.column_stack([plain, np.tanh(qd / 0.5)])
            residual.append([float(np.linalg.lstsq(a, truth[:, 0], rcond=None)[1][0]) for a in (plain, bent)])
            if dv != 1.0:
                assert np.linalg.lstsq(bent, truth[:, 0], rcond=None)[0][2] > 0  # concave: a positive bend
        (power_plain, power_bent), (linear_plain, _) = residual
        assert power_bent < 0.5 * power_plain and linear_plain < 1e-3 * power_plain, residual
    shapes = friction_shapes(heavy)
    assert {j for shape, j in shapes if shape == "smooth_coulomb"} == set(range(1, heavy.n_dof + 1))
    assert not {j for shape, j in friction_shapes(_kr6_robot()) if shape == "smooth_coulomb"}
    finding = {"effect": "friction_shape", "label": "friction_shape[j5,smooth_coulomb]", "joints": [5]}
    links = np.ones(6)
    for drives, false in ((shapes, "-"), (friction_shapes(_kr6_robot()), "friction_shape[5]")):
        case = Case("c", "", tmp_path, (), tmp_path, true_links=links, friction_shapes=drives)
        names, missed, wrong = unseen_arms._findings(case, {"findings": [finding]})
        assert (", ".join(wrong) or "-") == false and names == ["friction_shape[5]"]


def test_the_gas_spring_arm_s_robot_file_is_the_datasheet_s_and_identify_naming_its_balancer_counts(
    benchmark_modules, tmp_path
):
    """The HX-210 case (``heavy_gas_spring_datasheet``): the user's robot file holds each link mass 10-20 % off the
    truth's, the truth's gas spring on joint 2 opposes its gravity torque on every validation pose, holding up a
    large share of it, and the judge counts a counterbalance identify names or keeps on joint 2 (not missed) and a
    spring it keeps where none is hidden (false)."""
    import unseen_arms

    from identification.virtual.counterbalance import balance
    from psdm_casadi.robot import load_robot

    case = unseen_arms.build("heavy_gas_spring_datasheet", tmp_path, 0)
    file_masses = np.array([link.mass for link in load_robot(case.robot).links])
    off = np.abs(file_masses / case.true_links - 1.0)
    assert np.all((off >= 0.1 - 1e-9) & (off <= 0.2 + 1e-9)), off
    assert [p.name for p in case.train] == ["train_empty.csv", "train_150kg.csv"]
    assert '"mass": 150.0' in case.train[1].with_suffix(".payload.json").read_text()
    truth = load_robot(tmp_path / "hx210_truth.toml")
    q = np.loadtxt(case.validate, delimiter=",", skiprows=1)[::25, 1:7]
    held = balance(truth, case.effects[0], q)
    assert held.opposing == 1.0 and held.share > 0.3, held  # a balancer on every recorded pose
    record = {"joints": [2], "kept": True, "named_by": {"2": "a torque offset no sensor has"}}
    names, taken, false = unseen_arms.identify_named(case, {"identification": {"counterbalance": record}})
    assert names == ["spring[j2] (kept)"] and taken == {("counterbalance", 2)} and false == []
    record = {"joints": [3], "kept": True, "named_by": {"3": "the envelope report"}}
    assert unseen_arms.identify_named(case, {"identification": {"counterbalance": record}})[2] == ["spring[j3] (kept)"]
    record = {"joints": [], "kept": False, "named_by": {}}
    assert unseen_arms.identify_named(case, {"identification": {"counterbalance": record}}) == ([], set(), [])


def test_the_warming_cobot_s_files_are_the_vendor_s_and_its_logs_the_controller_s(benchmark_modules, tmp_path):
    """The warming cobot (``cobot_warming_currents``): the user's robot file has the vendor URDF's CAD masses, 4-14 %
    under the built arm's, no rotors (the truth has them), and joint 4's torque constant 10 % high; the logs are
    motor-side positions (gear x the joint's) at 500 Hz with one dropped 80 ms stretch, and the known load's sidecar
    is on the second training recording only."""
    import unseen_arms

    from psdm_casadi.robot import load_robot

    case = unseen_arms.build("cobot_warming_currents", tmp_path, 0)
    user, truth = load_robot(case.robot), load_robot(tmp_path / "truth" / "truth.toml")
    built = case.true_links / np.array([link.mass for link in user.links])
    assert np.all((built >= 1.04 - 1e-3) & (built <= 1.14 + 1e-3)), built
    assert not np.any(user.rotor_inertia)
    np.testing.assert_allclose(truth.rotor_inertia, [0.55, 0.55, 0.32, 0.32, 0.12, 0.06, 0.06])
    stated = np.array([d.kt for d in user.drives]) / np.array([d.kt for d in truth.drives])
    np.testing.assert_allclose(stated, [1, 1, 1, 1.1, 1, 1, 1], rtol=1e-5)
    data = np.loadtxt(case.validate, delimiter=",", skiprows=1)
    steps = np.diff(data[:, 0])
    assert np.median(steps) == pytest.approx(2e-3, rel=0.05) and steps.max() == pytest.approx(0.082, abs=2e-3)
    motor, gear = np.abs(data[:, 1:8]).max(axis=0), np.array([160, 160, 160, 160, 100, 160, 160])
    assert np.all(motor > np.array(truth.q_max)) and np.all(motor / gear < np.array(truth.q_max)), motor  # motor turns
    assert [p.with_suffix(".payload.json").exists() for p in (*case.train, case.validate)] == [False, True, False]


def test_the_belt_cobot_s_loads_are_in_its_manifest_and_its_logs_the_logger_s(benchmark_modules, tmp_path):
    """The belt cobot (``cobot_belt_payload_change``): the user's file is the vendor URDF (masses 5-12 % under the
    built arm's, no rotors) with the 7:1 belt of joint 6 in its gear ratios; its two training logs carry two different
    known loads stated only in the manifest, read back as stated; the logs are semicolon CSV with decimal commas in
    degrees and mA, which the reader takes to the truth's SI values (the motor currents times kt x gear are the
    torques, the ripple's joint turning through several of its 7 periods per turn)."""
    import unseen_arms

    from identification.data.configuration import recordings_with_configurations
    from identification.data.robot_recordings import load_robot_recording
    from psdm_casadi.robot import load_robot

    case = unseen_arms.build("cobot_belt_payload_change", tmp_path, 0)
    user, truth = load_robot(case.robot), load_robot(tmp_path / "truth" / "truth.toml")
    built = case.true_links / np.array([link.mass for link in user.links])
    assert np.all((built >= 1.05 - 1e-3) & (built <= 1.12 + 1e-3)), built
    assert not np.any(user.rotor_inertia) and truth.rotor_inertia[5] == pytest.approx(2.5e-4 * 49, rel=0.01)
    np.testing.assert_allclose([d.kt for d in user.drives], [d.kt for d in truth.drives])  # 7 x 0.35 on joint 6
    paths, stated = recordings_with_configurations([str(p) for p in case.data])
    assert [p.name for p in paths] == [p.name for p in case.train]
    assert [c.payload.mass for c in stated] == [1.9, 7.4] and not any(p.with_suffix(".payload.json").exists()
                                                                       for p in case.train)  # fmt: skip
    recording = load_robot_recording(case.validate, user, None, None)
    raw = np.loadtxt(case.validate, delimiter=";", skiprows=1, converters=lambda s: float(s.replace(",", ".")))
    np.testing.assert_allclose(recording.q, np.radians(raw[:, 1:7]), atol=1e-8)
    np.testing.assert_allclose(recording.joint_torque(np.array([d.kt for d in user.drives])),
                               raw[:, 7:] / 1000.0 * np.array([d.kt for d in truth.drives]), rtol=1e-9)  # fmt: skip
    assert np.ptp(recording.q[:, 5]) * 7 / (2 * np.pi) > 1.5  # the ripple's periods the held-out motion crosses
