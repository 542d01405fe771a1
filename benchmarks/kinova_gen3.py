"""The Kinova Gen3 read as shipped, identified and diagnosed with the commands' defaults: the ``kinova_models`` key.

The shared logs (../shared/datasets/kinova_gen3_dynid, read at run time, never copied) have a sample-index
``Time`` column, joint-torque sensors ``TorqueSm1..7``, motor currents ``Cur1..7`` and reference columns
with NaN; the vendor URDF has two inertias that are not physical, and an undocumented tool was probably
mounted (README: 0.6-0.8 kg at the flange over Kinova's published masses). Through
``examples/kinova_gen3.toml`` (the URDF's kinematics; its ``[[link]]`` tables state Kinova's published inertials
where the URDF's differ and the tool as part of the last link; the vendor's nominal torque constants; 1 kHz):

- ``psdm identify`` validated on opti_traj_testing2 (beside the robot file's RMSE, that of the model identify
  replaces: the file's rigid body with its friction fitted, and the joints identify's own check finds worse,
  ``robot_file_check``; none in the sensor fit, the target ``sensor_fit_no_joint_worse_than_robot_file``: joints 5
  and 6 move one way only there, and with joint 6's friction fitted it was 0.202 -> 0.296 N m, so identify holds it to
  the robot file's fit, ``one_way_friction``), once from the joint-torque sensors on
  opti_traj_testing1 and RunTrajectory1 (``--columns t=Time,q=Position,tau=TorqueSm``; RunTrajectory1's dead
  TorqueSm1 channel found and only its joint-1 rows left out) and once from the currents on
  opti_traj_testing1, RunTrajectory1 and Trajectory1 (``i=Cur``, torque constants only), defaults
  otherwise: per-joint validation RMSE [N m] and R^2, the robot file's RMSE, and the identified links
  (mass, distance of the centre of mass from the joint) against the robot file's and the URDF's, with the
  links that end at the identification's mass bounds (0.5-2x the robot file's: none in either fit, the targets
  ``sensor_fit_no_link_at_mass_bound`` and ``current_fit_no_link_at_mass_bound``);
- ``psdm identify`` the other way round (``sensor_short``): trained on opti_traj_testing2 alone (2.3 s, only joint 2
  reverses), validated on opti_traj_testing1, sensors: the joints that move one way only have their undetermined
  friction held to the robot file's fit (``one_way_friction``), and no joint may be worse than the robot file (per
  joint with friction fitted, or alone where that is better: the ``(base)`` row; the target
  ``short_fit_no_joint_worse_than_robot_file``; with the friction fitted, joints 3, 5, 6 were: 0.24 -> 0.31,
  0.14 -> 0.29, 0.19 -> 0.42 N m); a joint still worse has its friction, then the links it carries, held at the robot
  file's (``worse_joint_hold``: joint 1's friction at the file alone's, links 6 and 7);
- ``psdm diagnose`` of the robot file on opti_traj_testing1/2 (sensors): with the tool stated, a further
  payload it names says the stated tool is off;
- the vendor URDF alone (``vendor_urdf``: no ``[[link]]`` tables, no tool): ``psdm identify`` on the sensors must
  name its two unusable inertias and a tool at the flange and go on, consistent; ``psdm diagnose`` of it weighs the
  tool;
- the identified link-side rigid body (no rotors, no friction) against the joint-torque sensors on the three logs
  that have them (``sensor_prediction``, per-log offsets removed, 10 Hz zero-phase filter): a model identified on the
  currents must predict what the sensors measure about as well as the sensors' own fit (trained on two of the logs);
- the currents against the sensors (``sensor_check``, no model of the arm needed): per joint, on the three logs with
  both, ``kt i = a tau_s + mu |tau_s| tanh(qd / v) + fc tanh(qd / v) + fv qd + Ia qdd + offset`` by least squares
  (10 Hz zero-phase filter): the gear's efficiency by power-flow direction ``eta = sqrt((1 - mu) / (1 + mu))``
  (``drive_loss``) and the rotors' inertia the currents hold and the sensors do not, beside the currents fit's own
  (``rotor_inertia``: its drive-inertia columns and the rotors the base parameters merge, ``merged_rotors``);
- the joint elasticities the diagnosis of the robot file names on joints 1 and 2 (``elasticity_check``, and the
  ``elasticity_notes`` of ``tool_diagnosis``: ``diagnosis.elasticity_evidence``): their torque acts in a band where
  the commanded trajectory holds almost nothing (an oscillation of the arm), which the currents carry as the sensors
  do (the same torque on both sides of the gear), and where the measured torque exceeds the file's rigid body for
  the recorded angles several times: a deflection between the recorded angle and the link, not a stand-in.

Joint 7 carries almost no gravity load and its sensor shows only noise and offset (README), so its RMSE
is reported but says little.

Usage::

    python benchmarks/kinova_gen3.py [--json] [--skip-diagnosis]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_support import DEFAULT_DATA_ROOT, ROOT, add_data_root_argument, at_data_root

KINOVA = DEFAULT_DATA_ROOT / "datasets" / "kinova_gen3_dynid"
ROBOT_FILE = ROOT / "examples" / "kinova_gen3.toml"
URDF_IN_EXAMPLE = "../../shared/datasets/kinova_gen3_dynid/gen3.urdf"  # replaced by the --data-root's URDF
TRAIN, VALIDATE = "opti_traj_testing1.csv", "opti_traj_testing2.csv"
SOURCES = {"sensor": "t=Time,q=Position,tau=TorqueSm", "current": "t=Time,q=Position,i=Cur"}
#: The short recording (2.3 s, on which only joint 2 reverses) trained on, validated on ``TRAIN`` (sensors): the joints
#: that move one way only there have their undetermined friction held to the robot file's fit (``one_way_friction``).
SHORT = ("opti_traj_testing2.csv",)
#: Training recordings per source: every log with that signal (RunTrajectory1's TorqueSm1 is zero: identify finds
#: it and leaves joint 1's rows of that recording out; Trajectory1 and the others have no sensor torque at all).
TRAINING = {"sensor": (TRAIN, "RunTrajectory1.csv"), "current": (TRAIN, "RunTrajectory1.csv", "Trajectory1.csv")}
#: A link is plausible when its mass is within this factor of the URDF's, its centre of mass lies within
#: its reach (the distance to the next joint, 0.15 m for the last link) plus this margin [m], and its rotational
#: spread about its centre of mass is not below its floor (``links_report``).
MASS_FACTOR, COM_MARGIN = 5.0, 0.1
#: The identification's default mass bounds (``--mass-bounds``), relative to the robot file's link masses, and how close
#: to one counts as at it.
MASS_BOUNDS, BOUND_TOLERANCE = (0.5, 2.0), 1e-3
#: The example states the tool as part of the last link (0.6 kg); a diagnosis that names a further payload heavier
#: than this [kg] says the stated tool is off.
RESIDUAL_TOOL_KG = 0.4


SENSOR_LOGS = (TRAIN, VALIDATE, "RunTrajectory1.csv")
KT = np.array([9.13] * 4 + [5.852] * 3)  # the robot file's torque constants (TorqueCur = Cur x kt)


def _columns(path: Path, prefix: str) -> np.ndarray:
    header = path.read_text().split("\n", 1)[0].strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, usecols=[header.index(f"{prefix}{j}") for j in range(1, 8)])
    return data[:-25]  # opti_traj_testing1's last 21 rows are at rest with garbage reference columns


def sensor_check(data: Path, cutoff: float = 10.0, velocity: float = 0.05) -> dict:
    """Per joint, the current torque against the joint-torque sensor (module docstring): scale ``a``, load-dependent
    coefficient ``mu`` with its efficiency, rotor inertia ``Ia``, and the residual RMS with and without ``mu``."""
    from identification.data.preprocessing import central_difference, zero_phase_filter

    rows = [[] for _ in range(7)]
    for k, name in enumerate(SENSOR_LOGS):
        path = data / name
        q, sensor, current = (_columns(path, p) for p in ("Position", "TorqueSm", "Cur"))
        t = np.arange(q.shape[0]) * 1e-3
        q, sensor, current = (zero_phase_filter(x, 1000.0, cutoff) for x in (q, sensor, current * KT))
        qd, qdd = central_difference(t, q)
        inner = slice(100, -100)
        for j in range(7):
            if np.all(_columns(path, "TorqueSm")[:, j] == 0):
                continue  # RunTrajectory1's dead TorqueSm1
            rows[j].append(np.column_stack([sensor[inner, j], current[inner, j], qd[inner, j], qdd[inner, j],
                                            np.full(q[inner].shape[0], k)]))  # fmt: skip
    out = {key: [] for key in ("scale", "mu", "efficiency", "Ia", "rms_with_mu", "rms_without_mu")}
    for j in range(7):
        s, c, qd, qdd, log = np.vstack(rows[j]).T
        sign = np.tanh(qd / velocity)
        offsets = np.column_stack([(log == k).astype(float) for k in np.unique(log)])
        full = np.column_stack([s, np.abs(s) * sign, sign, qd, qdd, offsets])
        x = np.linalg.lstsq(full, c, rcond=None)[0]
        plain = np.delete(full, 1, axis=1)
        residual = c - plain @ np.linalg.lstsq(plain, c, rcond=None)[0]
        mu = float(x[1] / x[0])
        out["scale"].append(float(x[0]))
        out["mu"].append(mu)
        out["efficiency"].append(float(np.sqrt((1 - mu) / (1 + mu))) if 0 <= mu < 1 else None)
        out["Ia"].append(float(x[4]))
        out["rms_with_mu"].append(float(np.std(c - full @ x)))
        out["rms_without_mu"].append(float(np.std(residual)))
    return out


def elasticity_check(data: Path, band=(3.5, 8.0)) -> dict:
    """Per joint, on the two optimised logs (their commanded trajectories hold almost nothing in ``band`` [Hz]), the
    band's torque from the joint-torque sensor against the currents' (gain and correlation: the same torque on both
    sides of the gear, not a sensor's), and the recorded acceleration's correlation with the commanded one there (an
    oscillation the controller does not ask for): what a joint elasticity of the diagnosis rests on
    (``diagnosis.elasticity_evidence``)."""
    from scipy.signal import butter, sosfiltfilt

    sos = butter(4, band, btype="band", fs=1000.0, output="sos")
    rows = {key: [] for key in ("sensor", "current", "qdd", "command")}
    for name in (TRAIN, VALIDATE):
        path = data / name
        q, sensor, current, command = (_columns(path, p) for p in ("Position", "TorqueSm", "Cur", "AccCmptd"))
        qdd = np.gradient(np.gradient(q, 1e-3, axis=0), 1e-3, axis=0)
        for key, x in zip(rows, (sensor, current * KT, qdd, np.nan_to_num(command))):
            rows[key].append(sosfiltfilt(sos, x, axis=0)[300:-300])
    s, c, a, r = (np.vstack(rows[key]) for key in rows)
    corr = [float(np.corrcoef(x[:, j], y[:, j])[0, 1]) for x, y in ((s, c), (a, r)) for j in range(7)]
    return {"band_hz": list(band), "sensor_to_current_gain": (np.sum(s * c, 0) / np.sum(c * c, 0)).tolist(),
            "sensor_current_correlation": corr[:7], "commanded_correlation": corr[7:],
            "sensor_band_rms": np.sqrt(np.mean(s**2, 0)).tolist()}  # fmt: skip


def sensor_prediction(robot, model_file: Path, data: Path, cutoff: float = 10.0) -> dict:
    """Per joint, the RMSE [N m] of a fit's link-side rigid body (its standard parameters without the rotors; no
    friction) against the joint-torque sensors of each log that has them, and pooled over the logs (per-log offsets
    removed: the sensors carry offsets), 10 Hz zero-phase filter, 100 samples trimmed at each end."""
    from identification.data.preprocessing import central_difference, zero_phase_filter
    from psdm_casadi.model_cache import ModelCache

    standard = np.array(json.loads(model_file.read_text())["standard"]["values"]).reshape(robot.n_dof, -1)
    standard[:, 10] = 0.0
    model = ModelCache().derive(robot)
    theta = model.base_parameters(standard)
    out, squares, counts = {}, np.zeros(robot.n_dof), np.zeros(robot.n_dof)
    for name in SENSOR_LOGS:
        q, raw = (_columns(data / name, p) for p in ("Position", "TorqueSm"))
        t = np.arange(q.shape[0]) * 1e-3
        q, sensor = zero_phase_filter(q, 1000.0, cutoff), zero_phase_filter(raw, 1000.0, cutoff)
        qd, qdd = central_difference(t, q)
        inner = slice(100, -100)
        error = sensor[inner] - model.regressor(q[inner], qd[inner], qdd[inner]) @ theta
        error -= error.mean(axis=0)
        dead = np.all(raw == 0, axis=0)  # RunTrajectory1's TorqueSm1
        rms = np.sqrt(np.mean(error**2, axis=0))
        out[name] = [None if dead[j] else float(rms[j]) for j in range(robot.n_dof)]
        squares += np.where(dead, 0.0, np.sum(error**2, axis=0))
        counts += np.where(dead, 0, error.shape[0])
    out["pooled"] = np.sqrt(squares / np.maximum(counts, 1)).tolist()
    return out


def run_cli(argv: list) -> tuple:
    """``(exit code, JSON printed on stdout or None, stderr text)`` of one in-process ``psdm`` command."""
    from psdm_casadi.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    text = out.getvalue().strip()
    try:
        payload = json.loads(text.splitlines()[-1]) if text else None
    except json.JSONDecodeError:
        payload = None
    return code, payload, err.getvalue()


def link_reach(robot) -> np.ndarray:
    """Per link, the distance from its joint to the next joint [m] (0.15 for the last link)."""
    from psdm_casadi.urdf import load_urdf_model

    model = load_urdf_model(Path(robot.urdf_path))
    reach = np.full(robot.n_dof, 0.15)
    for k in range(2, model.njoints):
        reach[model.parents[k] - 1] = float(np.linalg.norm(model.jointPlacements[k].translation))
    return reach


def links_report(robot, model_file: Path) -> dict:
    """The identified links against the robot file's (its ``[[link]]`` tables over the URDF's): masses, centre-of-mass
    distances, the share of the file's rotational spread each keeps in its weakest direction (``inertia_share``; below
    the floor ``inertia_floor.FLOOR_SHARE`` a link spins too easily and the forward dynamics turn stiff), whether each
    is plausible, and which sit at the identification's mass bounds (``MASS_BOUNDS``)."""
    from identification.calibration.inertia_floor import AT_FLOOR, FLOOR_SHARE, inertia_share, principal_inertia
    from psdm_casadi.robot import load_robot

    standard = np.array(json.loads(model_file.read_text())["standard"]["values"]).reshape(robot.n_dof, -1)
    file = robot.nominal_dynamic_parameters()
    share = np.array([inertia_share(standard[j], file[j]) for j in range(robot.n_dof)])
    spread_ok = share >= FLOOR_SHARE / AT_FLOOR
    mass = standard[:, 0]
    com = np.linalg.norm(standard[:, 1:4], axis=1) / np.maximum(mass, 1e-9)
    prior = np.array([link.mass for link in robot.links])
    urdf = np.array([link.mass for link in load_robot(robot.urdf_path).links])
    reach = link_reach(robot)
    mass_ok = (mass >= prior / MASS_FACTOR) & (mass <= prior * MASS_FACTOR)
    com_ok = com <= reach + COM_MARGIN
    low, high = MASS_BOUNDS
    at_bound = (mass >= high * prior * (1 - BOUND_TOLERANCE)) | (mass <= low * prior * (1 + BOUND_TOLERANCE))
    return {"mass": mass.tolist(), "robot_file_mass": prior.tolist(), "urdf_mass": urdf.tolist(),
            "com_distance": com.tolist(), "reach": reach.tolist(),
            "total_mass": float(mass.sum()), "robot_file_total_mass": float(prior.sum()),
            "urdf_total_mass": float(urdf.sum()), "last_link_excess_mass": float(mass[-1] - prior[-1]),
            "links_at_mass_bound": [j + 1 for j in range(robot.n_dof) if at_bound[j]],
            "inertia_share": share.tolist(), "inertia_floor": FLOOR_SHARE,
            "principal_inertia": [principal_inertia(standard[j]).tolist() for j in range(robot.n_dof)],
            "robot_file_principal_inertia": [principal_inertia(file[j]).tolist() for j in range(robot.n_dof)],
            "links_below_inertia_floor": [j + 1 for j in range(robot.n_dof) if not spread_ok[j]],
            "implausible_links": [j + 1 for j in range(robot.n_dof) if not (mass_ok[j] and com_ok[j] and spread_ok[j])],
            "plausible": bool(np.all(mass_ok & com_ok & spread_ok))}  # fmt: skip


def identify(robot, source: str, folder: Path, data: Path, log, robot_file: Path | None = None, short=False) -> dict:
    """One ``psdm identify`` with the defaults (of the example, or of ``robot_file``); its validation, consistency,
    warnings and links. ``short``: trained on the short recording, validated on the long one (``SHORT``)."""
    robot_file = folder / ROBOT_FILE.name if robot_file is None else robot_file
    out = folder / f"{robot_file.stem}_{source}{'_short' if short else ''}.json"
    names, held_out = (SHORT, TRAIN) if short else (TRAINING[source], VALIDATE)
    training = [str(data / name) for name in names]
    argv = ["identify", str(robot_file), "--data", *training, "--validate", str(data / held_out),
            "--columns", SOURCES[source], "--out", str(out), "--json"]  # fmt: skip
    start = time.perf_counter()
    code, payload, err = run_cli(argv)
    seconds = time.perf_counter() - start
    log(f"kinova {source}{' short' if short else ''} ({robot_file.name}): psdm identify exit {code} in {seconds:.0f} s")
    if code != 0 or payload is None:
        return {"exit_code": code, "error": err.strip().splitlines()[-1] if err.strip() else "no output"}
    validation = payload["validation"][0]
    warnings = payload.get("warnings", [])
    tool = [w for w in warnings if w.startswith(f"link {robot.n_dof} ") and "tool at the flange" in w]
    missing = [w for w in warnings if "has no torque measurement" in w]
    drive = payload.get("drive", {})
    inertia = [drive.get(f"Ia{j + 1}") for j in range(robot.n_dof)]
    rotor = np.array(json.loads(out.read_text())["standard"]["values"]).reshape(robot.n_dof, -1)[:, 10]
    pressed = [f for f in payload.get("envelope_findings", []) if f.get("pressed", True)]  # not merely resting
    return {"exit_code": code, "columns": SOURCES[source], "training": list(names), "validation": held_out,
            "seconds": seconds, "one_way_friction": payload.get("one_way_friction"),
            "drive_loss": payload.get("drive_loss", []), "drive_inertia": inertia, "rotor_inertia": rotor.tolist(),
            "drive_inertia_reference": payload.get("envelope", {}).get("drive_inertia_reference", []),
            "sensor_prediction": sensor_prediction(robot, out, data),
            "links_pushed": sorted({f["link"] + 1 for f in pressed
                                    if set(f["bounds"]) & {"envelope", "mass upper", "mass lower"}}),
            "drives_pushed": sorted({f["link"] + 1 for f in pressed if f["bounds"][0].startswith("drive")}),
            "column_text": payload["columns"].get("drive_loss_joints"),
            "consistent": payload["consistent"], "names_tool_at_flange": bool(tool), "missing_torque": missing,
            "names_unusable_urdf_inertias": [w.split(" is unusable")[0] for w in warnings if " is unusable" in w],
            "rmse": validation["rmse"], "r2": validation["r2"], "rmse_robot_file": validation.get("rmse_prior"),
            "rmse_robot_file_baseline": validation.get("rmse_robot_file_baseline"),
            "worse_than_robot_file": (payload.get("robot_file_check") or {}).get("worse_joints"),
            "baselines": (payload.get("robot_file_check") or {}).get("baselines"),
            "worse_joints": payload.get("worse_joints"),
            "warnings": warnings, "links": links_report(robot, out)}  # fmt: skip


def diagnose_tool(folder: Path, data: Path, log, robot_file: Path | None = None) -> dict:
    """``psdm diagnose`` of the robot file on the sensor recordings: the payload it names (the tool), if any."""
    robot_file = folder / ROBOT_FILE.name if robot_file is None else robot_file
    argv = ["diagnose", str(robot_file), "--train", str(data / TRAIN), "--validate", str(data / VALIDATE),
            "--columns", SOURCES["sensor"], "--out", str(folder / f"diag_{robot_file.stem}"), "--json"]  # fmt: skip
    start = time.perf_counter()
    code, payload, err = run_cli(argv)
    seconds = time.perf_counter() - start
    log(f"kinova: psdm diagnose ({robot_file.name}, sensors) exit {code} in {seconds:.0f} s")
    if code != 0 or payload is None or "findings" not in payload:
        return {"exit_code": code, "error": err.strip().splitlines()[-1] if err.strip() else "no output"}
    found = [f for f in payload["findings"] if f["effect"] == "payload"]
    tool = found[0]["parameters"] if found else None
    return {"exit_code": code, "seconds": seconds, "findings": [f["label"] for f in payload["findings"]],
            "tool_mass": None if tool is None else tool["mass"],
            "tool_com": None if tool is None else [tool.get(f"com_{a}") for a in "xyz"],
            "rmse_before": payload["rmse_before"], "rmse_after": payload["rmse_after"],
            "elasticity_notes": [n for f in payload["findings"] if f["effect"] == "joint_elasticity"
                                 for n in f.get("notes", []) if "behind a spring" in n]}  # fmt: skip


def vendor_urdf(folder: Path, data: Path, log, diagnosis: bool) -> dict:
    """The vendor URDF alone (its kinematics, inertials and no tool; the example's torque constants and rate):
    ``psdm identify`` on the sensors must name its unusable inertias and a tool at the flange, go on and stay
    consistent; ``psdm diagnose`` of it weighs the tool (it also takes up the URDF's too-light links: README)."""
    from psdm_casadi.robot import load_robot

    path = folder / "kinova_gen3_vendor.toml"
    drives = "".join(f"[[drive]]\nkt = {kt}\n\n" for kt in KT)
    path.write_text(f'format = "psdm-robot/1"\nname = "kinova_gen3_vendor"\n\n[urdf]\npath = "{data / "gen3.urdf"}"\n\n'
                    f"[recording]\nsample_rate = 1000.0\n\n{drives}")  # fmt: skip
    fit = identify(load_robot(path), "sensor", folder, data, log, robot_file=path)
    tool = diagnose_tool(folder, data, log, robot_file=path) if diagnosis else None
    return {"identify": fit, "diagnosis": tool,
            "names_unusable_inertias": len(fit.get("names_unusable_urdf_inertias", [])) == 2,
            "names_tool": bool(fit.get("names_tool_at_flange")),
            "diagnosis_tool_mass": None if tool is None else tool.get("tool_mass")}  # fmt: skip


def evaluate_kinova(log, data: Path = KINOVA, diagnosis: bool = True) -> dict:
    """The ``kinova_models`` entry: both fits, the URDF's unusable inertias, the tool (module docstring).

    ``data`` is the dataset folder (``--data-root``); the example robot file is used with its URDF there.
    """
    from psdm_casadi.robot import load_robot

    if not (data / TRAIN).exists():
        return {"skipped": True, "reason": f"data absent in {data}"}
    with tempfile.TemporaryDirectory(prefix="psdm-kinova-") as tmp:
        text = ROBOT_FILE.read_text().replace(
            "../../shared/datasets/kinova_gen3_dynid/gen3.urdf", str(data / "gen3.urdf")
        )
        (Path(tmp) / ROBOT_FILE.name).write_text(text)
        robot = load_robot(Path(tmp) / ROBOT_FILE.name)
        fits = {source: identify(robot, source, Path(tmp), data, log) for source in SOURCES}
        short = identify(robot, "sensor", Path(tmp), data, log, short=True)
        tool = diagnose_tool(Path(tmp), data, log) if diagnosis else None
        vendor = vendor_urdf(Path(tmp), data, log, diagnosis)
    replaced = load_robot(robot.urdf_path).replaced_inertias  # the URDF's own (the robot file states them)
    unusable = [{"link": r.link.strip("'"), "joint": r.joint + 1, "problem": r.problem} for r in replaced]
    mass = None if tool is None else tool.get("tool_mass")
    stated = robot.links[-1].mass - load_robot(robot.urdf_path).links[-1].mass
    return {"skipped": False, **fits, "sensor_short": short, "urdf_unusable_inertias": unusable, "tool_diagnosis": tool,
            "short_fit_no_joint_worse_than_robot_file": short.get("exit_code") == 0
            and not short.get("worse_than_robot_file"),
            "sensor_fit_no_joint_worse_than_robot_file": fits["sensor"].get("exit_code") == 0
            and not fits["sensor"].get("worse_than_robot_file"),
            "tool_stated_in_robot_file_kg": stated, "sensor_check": sensor_check(data), "vendor_urdf": vendor,
            "elasticity_check": elasticity_check(data),
            "diagnosis_finds_no_further_tool": tool is None or mass is None or mass < RESIDUAL_TOOL_KG,
            "sensor_fit_no_link_at_mass_bound": not fits["sensor"].get("links", {}).get("links_at_mass_bound", [0]),
            "current_fit_no_link_at_mass_bound": not fits["current"].get("links", {}).get("links_at_mass_bound", [0]),
            "ran_on_defaults": all(f.get("exit_code") == 0 for f in fits.values())}  # fmt: skip


def kinova_missed(result) -> list:
    """The target checks (``kinova_models ...``) the result misses: a fit that failed, an implausible link, no tool."""
    if result is None or result.get("skipped"):
        return []
    missed = []
    for source in SOURCES:
        fit = result[source]
        if fit.get("exit_code") != 0:
            missed.append(f"kinova kinova_models: {source} fit failed ({fit.get('error')})")
        elif not fit["links"]["plausible"]:
            missed.append(f"kinova kinova_models: {source} fit, implausible links {fit['links']['implausible_links']}")
    if not result["diagnosis_finds_no_further_tool"]:
        missed.append(f"kinova kinova_models: the diagnosis of the robot file (tool stated) names a further payload "
                      f"of {result['tool_diagnosis']['tool_mass']:.2f} kg")  # fmt: skip
    vendor = result["vendor_urdf"]
    if vendor["identify"].get("exit_code") != 0 or not vendor["identify"]["consistent"]:
        missed.append(
            f"kinova kinova_models: the vendor URDF alone, identify failed ({vendor['identify'].get('error')})"
        )
    else:
        if not (vendor["names_unusable_inertias"] and vendor["names_tool"]):
            missed.append("kinova kinova_models: the vendor URDF alone, identify does not name its unusable inertias "
                          "and the tool")  # fmt: skip
        below = vendor["identify"]["links"]["links_below_inertia_floor"]
        if below:  # a wrist the sensors hardly see, collapsed to a point: stiff forward dynamics
            missed.append(f"kinova kinova_models: the vendor URDF alone, links below their inertia floor {below}")
    if not result["sensor_fit_no_joint_worse_than_robot_file"]:
        missed.append(f"kinova kinova_models: sensor fit worse than the robot file on joints "
                      f"{result['sensor'].get('worse_than_robot_file')}")  # fmt: skip
    if not result["short_fit_no_joint_worse_than_robot_file"]:
        short = result["sensor_short"]
        missed.append(f"kinova kinova_models: trained on {SHORT[0]}, worse than the robot file on joints "
                      f"{short.get('worse_than_robot_file')} ({short.get('error', 'exit 0')})")  # fmt: skip
    for source in SOURCES:  # a link the data do not press stays off its bounds (the masses as the bounds state them)
        if not result[f"{source}_fit_no_link_at_mass_bound"]:
            missed.append(f"kinova kinova_models: {source} fit, links at a mass bound "
                          f"{result[source].get('links', {}).get('links_at_mass_bound')}")  # fmt: skip
    return missed


def print_spread(links) -> None:
    """Per link, the share of the robot file's rotational spread it keeps (``links_report``), and links 6 and 7's
    principal inertias about their centre of mass against the file's (the wrist the sensors hardly see)."""
    print("           inertia share of the file's (floor " + f"{links['inertia_floor']:g}): "
          + " ".join(f"{v:.3g}" for v in links["inertia_share"])
          + f"; below the floor: links {links['links_below_inertia_floor'] or 'none'}")  # fmt: skip
    for j in (5, 6):
        own, file = links["principal_inertia"][j], links["robot_file_principal_inertia"][j]
        print(f"           link {j + 1}: principal inertia {'/'.join(f'{v:.2g}' for v in own)} kg m^2 (robot file "
              f"{'/'.join(f'{v:.2g}' for v in file)})")  # fmt: skip


def print_short(fit) -> None:
    """The rows of the fit trained on the short recording (``SHORT``): identified, robot file, robot file with friction,
    and what identify held (``one_way_friction``)."""
    print(f"  trained on {SHORT[0]} (2.3 s; only joint 2 reverses), validated on {TRAIN}:")
    if fit.get("exit_code") != 0:
        print(f"  {'sensor':<8} FAILED: {fit.get('error')}")
        return
    print(f"  {'sensor':<8} " + " ".join(f"{v:7.3f}" for v in fit["rmse"]))
    print(f"  {'(file)':<8} " + " ".join(f"{v:7.3f}" for v in fit["rmse_robot_file"] or []))
    print(f"  {'(base)':<8} " + " ".join(f"{v:7.3f}" for v in fit["rmse_robot_file_baseline"] or [])
          + f"   identify's check, joints worse: {fit.get('worse_than_robot_file') or 'none'}")  # fmt: skip
    print_one_way(fit)


def print_one_way(fit) -> None:
    """What identify held of the friction of the joints that move one way only in training (``one_way_friction``)."""
    held = fit.get("one_way_friction") or {}
    print(f"           baseline per joint (robot_file_check): {', '.join(fit.get('baselines') or []) or '-'} "
          "(friction: the robot file with friction fitted; alone: the robot file alone)")  # fmt: skip
    mended = fit.get("worse_joints") or {}
    if mended.get("worse_joints"):
        print(f"           worse than the robot file first: joints {mended['worse_joints']}; held (worse_joint_hold): "
              f"friction {mended.get('held_friction') or 'none'}, links {mended.get('held_links') or 'none'}; "
              f"still worse: {mended.get('left_worse') or 'none'}")  # fmt: skip
    if not held.get("one_way_joints"):
        return
    decided = "; the held-out recording decided it" if held.get("decided_by_held_out") else ""
    print(f"           one way only: joints {held.get('one_way_joints') or 'none'}; friction held to the robot file's "
          f"fit on joints {held.get('held_joints') or 'none'} (fitted, the model was worse on joints "
          f"{held.get('worse_joints') or 'none'}{decided})")  # fmt: skip


def print_kinova(result) -> None:
    """The table of both fits' validation RMSE, the links that are implausible, the URDF and the tool."""
    if result is None:
        return
    if result.get("skipped"):
        print(f"\nkinova: skipped ({result['reason']})")
        return
    print(f"\nkinova gen3 (validated on {VALIDATE}, defaults): validation RMSE [N m] per joint")
    for source in SOURCES:
        fit = result[source]
        if fit.get("exit_code") != 0:
            print(f"  {source:<8} FAILED: {fit.get('error')}")
            continue
        r2 = min(fit["r2"][:6])
        print(f"  {source:<8} " + " ".join(f"{v:7.3f}" for v in fit["rmse"]) + f"   R^2 >= {r2:.2f} on J1-6")
        print(f"  {'(file)':<8} " + " ".join(f"{v:7.3f}" for v in fit["rmse_robot_file"] or []))
        if fit.get("rmse_robot_file_baseline"):  # the model identify replaces (robot_file_check)
            print(
                f"  {'(base)':<8} "
                + " ".join(f"{v:7.3f}" for v in fit["rmse_robot_file_baseline"])
                + f"   identify's check, joints worse: {fit.get('worse_than_robot_file') or 'none'}"
            )
            print_one_way(fit)
        links = fit["links"]
        print(f"           total mass {links['total_mass']:.2f} kg (robot file {links['robot_file_total_mass']:.2f}, "
              f"URDF {links['urdf_total_mass']:.2f}); links at a mass bound: {links['links_at_mass_bound'] or 'none'} "
              f"(pushed there by the data, identify's report: links {fit['links_pushed'] or 'none'}, drives "
              f"{fit['drives_pushed'] or 'none'}); "
              f"implausible links: {links['implausible_links'] or 'none'}; a tool at the flange named: "
              f"{'yes' if fit['names_tool_at_flange'] else 'no'}")  # fmt: skip
        print_spread(links)
    print_short(result["sensor_short"])
    check = result["sensor_check"]
    print("  currents against the sensors (kt i = a tau_s + mu |tau_s| sign + friction + Ia qdd):")
    for key in ("scale", "mu", "efficiency", "Ia", "rms_with_mu", "rms_without_mu"):
        print(f"    {key:<15}" + " ".join("      -" if v is None else f"{v:7.3f}" for v in check[key]))
    current = result["current"]
    if current.get("exit_code") == 0:
        eta = {e["joint"]: e["efficiency"] for e in current["drive_loss"]}
        print(f"    {'currents fit':<15}eta " + (", ".join(f"J{j} {v:.3f}" for j, v in eta.items()) or "none chosen")
              + "; rotor inertia " + " ".join(f"{v:.3f}" for v in current["rotor_inertia"]))  # fmt: skip
        for entry in current["drive_inertia_reference"]:
            print(f"    joint {entry['joint']}'s rotor (inside the base parameters, not in the robot file) held near "
                  f"{entry['kg_m2']:.3f} kg m^2, the drive inertias of joints {entry['from_joints']}")  # fmt: skip
    print("  link-side rigid body against the joint-torque sensors, pooled over the 3 logs [N m]:")
    for source in SOURCES:
        if result[source].get("exit_code") == 0:
            pooled = result[source]["sensor_prediction"]["pooled"]
            print(f"    {source + ' fit':<15}" + " ".join(f"{v:7.3f}" for v in pooled))
    for entry in result["urdf_unusable_inertias"]:
        print(f"  URDF: {entry['link']} (joint {entry['joint']}) inertia unusable: {entry['problem']}")
    vendor = result["vendor_urdf"]
    if vendor["identify"].get("exit_code") == 0:
        fit = vendor["identify"]
        mass = vendor["diagnosis_tool_mass"]
        print("  vendor URDF alone (sensors)   " + " ".join(f"{v:7.3f}" for v in fit["rmse"])
              + f"; names its unusable inertias: {'yes' if vendor['names_unusable_inertias'] else 'no'}, a tool at the "
              f"flange: {'yes' if vendor['names_tool'] else 'no'}; diagnosis: payload "
              f"{'none' if mass is None else f'{mass:.3f} kg'}")  # fmt: skip
        print_spread(fit["links"])
    tool = result["tool_diagnosis"]
    if tool is not None and tool.get("exit_code") == 0:
        print(f"  diagnosis of the robot file (tool of {result['tool_stated_in_robot_file_kg']:.2f} kg stated): "
              f"{', '.join(tool['findings']) or 'nothing'}; further payload "
              f"{tool['tool_mass'] if tool['tool_mass'] is None else round(tool['tool_mass'], 3)} kg")  # fmt: skip
    elif tool is not None:
        print(f"  diagnosis of the robot file FAILED: {tool.get('error')}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    parser.add_argument("--skip-diagnosis", action="store_true", help="identify only (about a minute)")
    parser.add_argument("--data", type=Path, default=None, help="the dataset folder (default: DATA_ROOT/datasets/...)")
    add_data_root_argument(parser)
    args = parser.parse_args(argv)
    log = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    data = args.data if args.data is not None else at_data_root(KINOVA, args.data_root)
    result = evaluate_kinova(log, data, diagnosis=not args.skip_diagnosis)
    with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):
        print_kinova(result)
    if args.json:
        print(json.dumps({"kinova_models": result}, default=float))
    if result.get("skipped"):
        return 2
    for line in kinova_missed(result):
        print(f"MISSED {line}", file=sys.stderr)
    return 0 if not kinova_missed(result) else 1


if __name__ == "__main__":
    sys.exit(main())
