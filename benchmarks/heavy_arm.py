"""A heavy industrial-class arm for the diagnosis benchmark, and CAD-like errors of a robot file's inertia.

``heavy_industrial_arm`` scales the Denso VS-6556G robot file geometrically: lengths by ``LENGTH``, masses by
``MASS`` (so link inertias by ``MASS * LENGTH**2``), reflected rotor inertias by the same factor (the rotors
keep dominating the joint torque, as on large arms with high gear ratios), and friction, torque constants and
torque limits by ``MASS * LENGTH`` (the gravity torque scale). Speeds and accelerations are lowered to those of
a 200 kg-class arm. The result is a six-axis arm of about 1 t whose base joints carry several kN m; a payload
of 100-200 kg at the flange changes their torque by a large fraction.

``cad_error`` returns the same robot with every link's mass, centre of mass and inertia off by 10-20 % (a
random sign per quantity, drawn with a seed), the way CAD values are off from a real arm: the simulation uses
the perturbed robot as the truth and the diagnosis the unperturbed robot file.

The arm is written to a robot file (``write_robot_file``, in a temporary folder removed at exit) and read back, so
its calibrated models can be stored (a model file keeps the robot file's text) and exported.

Run as a script, it checks the plausible identification (issue 25) on the arm with a hidden cam counterbalance on
its shoulder (the diagnosis benchmark's ``heavy_counterbalance``: a balancer opposing the shoulder's gravity torque
at every angle, taking a seeded 40-90 % of its amplitude, ``counterbalance_share``), CAD-off inertias in the truth, a
10 s training and a 10 s validation recording at 250 Hz, as a user would on the command line:

1. ``psdm identify ROBOT --data train.csv --validate val.csv --out model.json`` (default options): does every link
   stay inside its physical envelope (``envelope_respected``: its mass within the bounds, its mass distribution in
   its bounding ellipsoid), and did identify's first fit name each hidden effect the links absorb where it acts
   (``absorbed_effect_named``: the counterbalance on the joint the truth puts it on, joint 2, in the model file's
   record of that fit's report, ``identification.counterbalance.named_by``; the payload at the flange,
   ``identification.payload.named``)? It is read from that record, not from the envelope findings the file keeps: the
   routes that follow the first fit take a named effect into the model, and the written model then leaves no link
   pushed for it (``stays_inside_unpushed``: none pushed). A counterbalance also named on another joint does not
   count against it (``spring_joints`` shows what was taken). ``payload_named``: that record names the payload
   (``identification.payload.named``) and, where identify estimated the body it named (``identification.payload.mass``,
   the payload route's point mass at the flange), its mass is within ``PAYLOAD_RTOL`` of the truth's; false where no
   payload is hidden. ``counterbalance_taken``: identify kept a spring on joint 2
   (``calibration.counterbalance_column``: tried where its report names a counterbalance, kept where it lowers joint 2
   on the held-out recording and in each block of the training recording's cross-validation, the second opinion, the
   blocks together beyond their noise, and no joint is worse); ``counterbalance_named`` counts it as named.
   ``counterbalance_stated``: the report names a counterbalance on joint 2, first or among the alternatives, in an
   envelope finding or a parameter the fit holds back (``held_named``: a counterbalance absorbed inside link 2's
   envelope, held by the pull towards the robot file), or in the counterbalance it tried (``named_by``: also a torque
   offset no sensor has, ``calibration.offset_reading``, or one joint's gravity torque alone off the file's,
   ``calibration.gravity_departure``), or identify took it.
   ``payload_taken``: identify took the tool as a payload at the flange (``calibration.payload_route``: where its
   report names a payload and a spring was tried, the payload is preferred to a spring taking the same torque unless
   the spring is clearly better out of sample), with ``payload_mass_kg`` against the truth's ``payload_mass_true_kg``
   and its standard deviation ``payload_mass_std_kg`` (``identification.payload.mass_std``: the recording's noise,
   ``payload_mass_std_noise_kg``, and the robot file's links, whose CAD errors the recording cannot separate from it);
   ``spring_joints`` the joints of the springs written; ``rmse_held_out`` every joint's RMSE on the held-out
   recording (identify never saw it without ``--validate``). ``envelope_respected`` is judged around the robot file
   carrying the payload identify took (the envelope its fit kept).
2. ``psdm diagnose model.json --train train.csv --validate val.csv`` (``diagnose_model_finds_counterbalance``; as a
   fraction of the seeds, ``identify_then_diagnose_finds_counterbalance``: with links pushed against their envelope
   the diagnosis starts from the robot file's rigid body the model file keeps, ``calibration.diagnosis_prior``), and
   the command the identify report suggests, ``psdm diagnose ROBOT ...`` against the robot file
   (``diagnose_finds_counterbalance``): is a spring or an unnamed effect found on joint 2? The free rigid-body
   recalibration of ``rigid_body="auto"`` absorbs the counterbalance into link 2; the diagnosis keeps the spring
   because a rigid body recalibrated inside its physical envelope still needs it (``diagnosis.envelope_check``).
   ``diagnose_finds_payload``: ``psdm diagnose ROBOT`` names the tool, its mass (``diagnose_payload_mass_kg``) within
   ``PAYLOAD_RTOL`` of the truth's; the free recalibration takes it into the wrist links, a rigid body inside its
   envelope cannot (``diagnosis.hidden_payload``).

``--identify both`` runs step 1 twice, with ``--validate val.csv`` and without (``psdm identify ROBOT --data
train.csv``: identify then judges the spring by the block cross-validation over the training recording alone,
``calibration.counterbalance_folds``), one row each (``identify_validate``); ``--identify train`` only without.
Steps 2 follow each identify.

Each key is true when it holds on every row; ``counts`` gives how many rows it holds on (``3/3``). Per row,
``identify_s`` is identify's wall time and ``identify_cpu_s`` this process's CPU time for it (on a loaded machine the
wall time also counts the others' work); ``counterbalance_reason`` is identify's verdict on the counterbalance, with
its numbers.

    python benchmarks/heavy_arm.py [--seeds 0 1] [--identify validate|train|both] [--json]
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import dataclasses
import io
import json
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_support import DENSO_FILE, print_json, print_table

from psdm_casadi.robot import LinkInertia, load_robot
from psdm_casadi.robot_writer import write_robot_file

LENGTH = 3.2  # length scale over the Denso VS-6556G
MASS = 45.0  # mass scale
SPEED = 0.4  # speed and acceleration limits relative to the Denso's


def heavy_industrial_arm(folder=None):
    """The scaled Denso (see the module docstring), named ``heavy industrial arm``, read back from the robot file
    ``heavy_industrial_arm.toml`` written in ``folder`` (default: a temporary folder removed at exit)."""
    if folder is None:
        folder = tempfile.mkdtemp(prefix="psdm-heavy-arm-")
        atexit.register(shutil.rmtree, folder, True)
    path = write_robot_file(_scaled_denso(), Path(folder) / "heavy_industrial_arm.toml", overwrite=True)
    return load_robot(path)


def _scaled_denso():
    denso = load_robot(DENSO_FILE)
    inertia_scale, torque_scale = MASS * LENGTH**2, MASS * LENGTH
    joints = tuple(
        dataclasses.replace(
            j,
            a=j.a * LENGTH,
            d=j.d * LENGTH,
            qd_max=j.qd_max * SPEED,
            qdd_max=j.qdd_max * SPEED,
            tau_max=j.tau_max * torque_scale,
        )
        for j in denso.joints
    )
    links = tuple(
        LinkInertia(
            mass=link.mass * MASS, com=np.asarray(link.com) * LENGTH, inertia=np.asarray(link.inertia) * inertia_scale
        )
        for link in denso.links
    )
    drives = tuple(
        dataclasses.replace(
            d,
            kt=d.kt * torque_scale,
            fc=d.fc * torque_scale,
            fs=d.fs * torque_scale,
            fv=d.fv * torque_scale,
            sigma0=d.sigma0 * torque_scale,
            sigma1=d.sigma1 * torque_scale,
        )
        for d in denso.drives
    )
    return dataclasses.replace(
        denso,
        name="heavy industrial arm",
        joints=joints,
        links=links,
        rotor_inertia=np.asarray(denso.rotor_inertia, dtype=float) * inertia_scale,
        drives=drives,
        source=None,
    )


def cad_error(robot, rng, low: float = 0.1, high: float = 0.2):
    """``robot`` with each link's mass, centre of mass and inertia tensor scaled by ``1 +- U(low, high)``."""

    def factor():
        return 1.0 + float(rng.choice([-1.0, 1.0])) * float(rng.uniform(low, high))

    links = tuple(
        LinkInertia(
            mass=link.mass * factor(), com=np.asarray(link.com) * factor(), inertia=np.asarray(link.inertia) * factor()
        )
        for link in robot.links
    )
    return robot.with_links(links)


#: The hidden effects (the diagnosis benchmark's makers): a cam counterbalance on joint 2 and a 100-200 kg payload.
EFFECTS = ("heavy_counterbalance", "heavy_payload")
#: The truth's effects (``diagnosis.MAKERS``' kinds) the links absorb -> what identify's report calls them.
ABSORBED = {"cam_counterbalance": "counterbalance", "gas_spring_counterbalance": "counterbalance", "payload": "payload"}
# a counterbalance is found when diagnose names one of these on joint 2 (the diagnosis benchmark's ACCEPTED)
COUNTERBALANCE_NAMES = ("spring", "unnamed_effect", "gas_spring", "counterbalance")
PAYLOAD_RTOL = 0.3  # a payload diagnose (or identify) names is the tool: its mass within this fraction of the truth's


def _cli(argv) -> tuple:
    """(exit code, parsed JSON on stdout or None) of one ``psdm`` command run in this process."""
    from psdm_casadi.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main([str(a) for a in argv])
    try:
        return code, json.loads(out.getvalue())
    except json.JSONDecodeError:
        return code, None


def _inside(robot, document) -> bool:
    """Every link of the model file within its mass bounds and inside its bounding ellipsoid (1e-6 slack), around the
    robot file carrying the payload identify took (``payload_route``: the envelope its fit kept)."""
    from identification.calibration.carried_payload import carrying_payloads
    from identification.calibration.envelope import envelope_fill, link_envelopes
    from psdm_casadi import derive_psdm

    robot = carrying_payloads(robot, derive_psdm(robot), document.get("findings") or [])
    standard = np.asarray(document["standard"]["values"], dtype=float).reshape(robot.n_dof, -1)
    low, high = document["standard"]["envelope"]["mass_ratio"]
    prior = robot.nominal_dynamic_parameters()
    for i, envelope in enumerate(link_envelopes(robot, [i for i in range(robot.n_dof) if prior[i, 0] > 0])):
        if envelope is None:
            continue
        mass_ok = low * prior[i, 0] * (1 - 1e-6) <= standard[i, 0] <= high * prior[i, 0] * (1 + 1e-6)
        if not mass_ok or envelope_fill(standard[i], envelope) > 1.0 + 1e-6:
            return False
    return True


def _joint(entry) -> int:
    """The 0-based joint an envelope finding's or held-back item's effect acts on (``effect_joint``, else ``joint``)."""
    return entry["effect_joint"] if entry.get("effect_joint", -1) >= 0 else entry["joint"]


def _on_joint_2(entry) -> bool:
    """Whether the report names a counterbalance on joint 2 there, first or among the alternatives."""
    return "counterbalance" in (entry["absorbs"], *entry.get("alternatives", ())) and _joint(entry) == 1


def _named_where_it_acts(document, truth) -> bool:
    """Whether identify's first fit named every effect of ``truth`` the links absorb (``ABSORBED``) where it acts, as
    the model file records that fit's report: a counterbalance on its joint (``identification.counterbalance.named_by``:
    the envelope report, a held-back gravity term, a torque offset no sensor has, or the joint's gravity torque alone
    off the file's), a payload at the flange (``identification.payload.named``: a pushed link or held-back parameter a
    body at the flange can give, first or as an alternative). False where none is hidden."""
    record = document["identification"]
    named_by = (record.get("counterbalance") or {}).get("named_by") or {}
    payload = bool((record.get("payload") or {}).get("named"))
    hidden = [(ABSORBED[kind], joint) for kind, joint, _, _ in truth if kind in ABSORBED]
    return bool(hidden) and all(payload if e == "payload" else str(j + 1) in named_by for e, j in hidden)


def _payload_named(document, truth) -> bool:
    """Whether identify's first fit named the truth's payload, as the model file records that fit's report
    (``identification.payload.named``: a pushed link or held-back parameter a body at the flange can give, first or as
    an alternative), with the mass of the body identify estimated for it (``identification.payload.mass``, where the
    payload route tried one) within ``PAYLOAD_RTOL`` of the truth's. The record states no joint: a payload is at the
    flange, where the truth puts it. False where no payload is hidden."""
    true = next((float(p["mass"]) for k, _, _, p in truth if k == "payload"), None)
    load = document["identification"].get("payload") or {}
    if true is None or not load.get("named"):
        return False
    return load.get("mass") is None or abs(float(load["mass"]) - true) <= PAYLOAD_RTOL * true


def _found_on_joint_2(payload) -> bool:
    return any(f["effect"] in COUNTERBALANCE_NAMES and 2 in f["joints"] for f in (payload or {}).get("findings", ()))


def _payload_mass(report):
    """The mass [kg] of the payload a diagnosis report names, or None."""
    found = [f for f in (report or {}).get("findings", ()) if f["effect"] == "payload"]
    return round(float(found[0]["parameters"]["mass"]), 1) if found else None


def _payload_found(report, truth) -> bool:
    """Whether a diagnosis report names the truth's payload with its mass within ``PAYLOAD_RTOL`` (no payload hidden:
    whether it names none)."""
    true = next((float(p["mass"]) for k, _, _, p in truth if k == "payload"), None)
    mass = _payload_mass(report)
    if true is None:
        return mass is None
    return mass is not None and abs(mass - true) <= PAYLOAD_RTOL * true


def _held_out(robot, model_file, val, identified, key):
    """Every joint's RMSE [N m] on the held-out recording: identify's own (``key``) when it was given it, else the
    written model's as ``psdm validate`` gives it (the unconstrained fit is not in the file: None)."""
    if identified and identified.get("validation"):
        return [round(v, 1) for v in identified["validation"][0][key]]
    if key != "rmse":
        return None
    _, validated = _cli(["validate", model_file, val, "--json"])
    return [round(v, 1) for v in validated["recordings"][0]["rmse"]] if validated else None


def _held_out_j2(robot, model_file, val, identified, key):
    """Joint 2's RMSE [N m] on the held-out recording (``_held_out``)."""
    rmse = _held_out(robot, model_file, val, identified, key)
    return None if rmse is None else rmse[1]


def run_case(seed: int, folder: Path, effects=EFFECTS, validate: bool = True) -> dict:
    """One seed: simulate, identify (with the held-out recording, or ``validate=False`` on the training recording
    alone), diagnose the model and the robot file (module docstring)."""
    import diagnosis  # the diagnosis benchmark's scenario (CAD-off truth, rate, durations)

    from identification.data.io import save_recording

    robot = heavy_industrial_arm(folder)
    simulated, cad = [], diagnosis.cad_error  # keep the truth's robot (its link 2 mass) the scenario simulates
    diagnosis.cad_error = lambda arm, rng: simulated.append(cad(arm, rng)) or simulated[-1]
    try:
        rng = np.random.default_rng(seed)
        truth, train, validation = diagnosis._scenario("heavy", robot, tuple(effects), rng, seed)
    finally:
        diagnosis.cad_error = cad
    data, val, out = folder / "train.csv", folder / "val.csv", folder / "model.json"
    save_recording(train, data)
    save_recording(validation, val)
    start, cpu = time.perf_counter(), time.process_time()
    held_out = ["--validate", val] if validate else []
    code, identified = _cli(["identify", robot.source, "--data", data, *held_out, "--out", out, "--json"])
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    document = json.loads(out.read_text())
    findings = [f for f in document["standard"].get("envelope_findings", []) if f.get("pressed", True)]
    named = [f for f in findings if f["absorbs"] == "counterbalance" and f["joint"] == 1]
    counter = document["identification"].get("counterbalance") or {}
    taken = bool(counter.get("kept")) and 2 in counter.get("joints", ())  # identify took a spring on joint 2
    tried = "2" in (counter.get("named_by") or {})  # identify's report named it there (and tried the spring)
    held = document["standard"]["envelope"].get("held_back", [])
    stated = [e for e in [*findings, *held] if _on_joint_2(e)]  # first or an alternative, envelope or held back
    diagnose = ["--train", data, "--validate", val, "--json"]
    _, from_model = _cli(["diagnose", out, *diagnose])
    _, from_file = _cli(["diagnose", robot.source, *diagnose])
    prior = robot.nominal_dynamic_parameters()
    standard = np.asarray(document["standard"]["values"], dtype=float).reshape(robot.n_dof, -1)
    load = document["identification"].get("payload") or {}
    spring_joints = sorted({j for f in document.get("findings") or [] if f["effect"] == "spring" for j in f["joints"]})
    return {
        "seed": seed,
        "identify_validate": validate,
        "amplitude_Nm": next((round(float(p["amplitude"]), 1) for k, _, _, p in truth if "amplitude" in p), None),
        "counterbalance_share": next((round(float(p["share"]), 2) for k, _, _, p in truth if "share" in p), None),
        "identify_exit": code,
        "identify_s": round(seconds, 1),
        "identify_cpu_s": round(cpu, 1),
        "envelope_respected": _inside(robot, document),
        "absorbed_effect_named": _named_where_it_acts(document, truth),
        "counterbalance_named": bool(named) or taken,
        "counterbalance_taken": taken,
        "counterbalance_stated": bool(stated) or taken or tried,
        "counterbalance_reason": counter.get("reason", ""),
        "payload_named": _payload_named(document, truth),
        "stays_inside_unpushed": not findings,
        "named": "; ".join(sorted({f"{f['absorbs']} (joint {f['joint'] + 1})" for f in findings})) or "-",
        "held_named": "; ".join(sorted({f"{h['absorbs']} (joint {_joint(h) + 1})" for h in held})) or "-",
        "link2_mass_kg": round(float(standard[1, 0]), 1),
        "link2_mass_file_kg": round(float(prior[1, 0]), 1),
        "link2_mass_truth_kg": round(float(simulated[-1].nominal_dynamic_parameters()[1, 0]), 1),
        "rmse_j2_identified": _held_out_j2(robot, out, val, identified, "rmse"),
        "rmse_j2_unconstrained": _held_out_j2(robot, out, val, identified, "rmse_ols"),
        "rmse_held_out": _held_out(robot, out, val, identified, "rmse"),
        "payload_taken": bool(load.get("kept")),
        "payload_mass_kg": round(load["mass"], 1) if load.get("kept") else None,
        "payload_mass_std_kg": round(load["mass_std"], 1) if load.get("mass_std") is not None else None,
        "payload_mass_std_noise_kg": round(load["mass_std_noise"], 1) if load.get("mass_std") is not None else None,
        "payload_mass_true_kg": next((round(float(p["mass"]), 1) for k, _, _, p in truth if k == "payload"), None),
        "spring_joints": spring_joints,
        "payload_reason": load.get("reason", ""),
        "diagnose_model_finds_counterbalance": _found_on_joint_2(from_model),
        "diagnose_finds_counterbalance": _found_on_joint_2(from_file),
        "diagnose_payload_mass_kg": _payload_mass(from_file),
        "diagnose_finds_payload": _payload_found(from_file, truth),
        "model_findings": ", ".join(f"{f['effect']}{f['joints']}" for f in (from_model or {}).get("findings", ())),
        "file_findings": ", ".join(f"{f['effect']}{f['joints']}" for f in (from_file or {}).get("findings", ())),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--effects", nargs="*", default=list(EFFECTS), help="hidden effects (diagnosis.MAKERS keys)")
    parser.add_argument(
        "--identify",
        choices=("validate", "train", "both"),
        default="validate",
        help="identify with --validate val.csv (default), on the training recording alone, or both",
    )
    args = parser.parse_args(argv)
    rows = []
    modes = {"validate": (True,), "train": (False,), "both": (True, False)}[args.identify]
    for seed in args.seeds:
        for validate in modes:
            with tempfile.TemporaryDirectory(prefix="psdm-heavy-bench-") as folder:
                rows.append(run_case(seed, Path(folder), args.effects, validate))
    keys = ("envelope_respected", "absorbed_effect_named", "counterbalance_named", "counterbalance_taken",
            "counterbalance_stated", "payload_named", "payload_taken", "diagnose_finds_counterbalance",
            "diagnose_model_finds_counterbalance", "diagnose_finds_payload")  # fmt: skip
    summary = {key: all(row[key] for row in rows) for key in keys}
    summary["counts"] = {key: f"{sum(bool(row[key]) for row in rows)}/{len(rows)}" for key in keys}
    found = sum(bool(row["diagnose_model_finds_counterbalance"]) for row in rows)
    summary["identify_then_diagnose_finds_counterbalance"] = found / len(rows)  # the route identify -> diagnose MODEL
    # the counterbalance in the model at the route's end: identify took it, or diagnose MODEL finds it
    ended = sum(bool(row["counterbalance_taken"] or row["diagnose_model_finds_counterbalance"]) for row in rows)
    summary["identify_or_diagnose_model_has_counterbalance"] = ended / len(rows)
    summary["identify_stays_inside_or_names_effect"] = all(
        row["envelope_respected"] and (row["absorbed_effect_named"] or row["stays_inside_unpushed"]) for row in rows
    )
    if args.json:
        print_json({"benchmark": "heavy_arm", "cases": rows, **summary})
        return 0
    print_table(rows, ["seed", "identify_validate", "counterbalance_share", "envelope_respected",
                       "absorbed_effect_named", "named", "held_named", "counterbalance_stated", "counterbalance_taken",
                       "payload_named", "payload_taken", "payload_mass_kg", "payload_mass_std_kg",
                       "payload_mass_true_kg",
                       "spring_joints",
                       "link2_mass_kg", "link2_mass_file_kg", "link2_mass_truth_kg", "rmse_j2_identified",
                       "rmse_j2_unconstrained",
                       "diagnose_model_finds_counterbalance", "diagnose_finds_counterbalance",
                       "diagnose_finds_payload", "diagnose_payload_mass_kg"])  # fmt: skip
    for row in rows:
        route = "with" if row["identify_validate"] else "without"
        print(f"seed {row['seed']} (identify {route} --validate): diagnose MODEL found [{row['model_findings']}]; "
              f"diagnose ROBOT found [{row['file_findings']}]")  # fmt: skip
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
