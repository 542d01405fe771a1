"""Virtual stand-ins for real arms the project does not have, written as their users' files (benchmarks/unseen_arms.py).

Each case writes a robot file and recordings the way a controller or a logger would: vendor column names, a
sample rate of its own with jittered time stamps, NaN rows, units other than SI, a payload stated in a sidecar,
a log that starts before the arm moves. The truth (links, payload, hidden effects, sensor noise) is kept beside
the files in a :class:`Case`, so every answer of the default commands can be checked against it.
"""

from __future__ import annotations

import dataclasses
import json
import sysconfig
from pathlib import Path

import numpy as np

from identification.virtual.counterbalance import cam_counterbalance
from identification.virtual.effects import Payload
from identification.virtual.lugre_exact import LuGreArrays, steady_state_friction
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.description import DriveParameters, LinkInertia
from psdm_casadi.robot import load_robot
from psdm_casadi.robot_writer import write_robot_file
from psdm_casadi.samples import kr6, serial_arm


@dataclasses.dataclass
class Case:
    """One unseen arm: its files and the truth behind them."""

    name: str
    what: str
    robot: Path
    train: tuple  # the training recordings (Paths)
    validate: Path
    extra: tuple = ()  # the CLI options the user needs for the log's layout (--columns, --rate)
    true_links: np.ndarray | None = None  # link masses of the truth [kg]
    payload_mass: float | None = None  # the flange load's truth [kg]; known (sidecar) or to identify
    payload_known: bool = True
    floor_nm: np.ndarray | None = None  # per joint, the truth model's RMSE floor on the validation recording [N m]
    hidden: tuple = ()  # (effect, joint 1-based) the diagnosis should name
    unstated: tuple = ()  # CLI options without the log's units: identify must refuse them (exit 2) ...
    refusal_words: tuple = ()  # ... with these words (the file, the field, the fix)
    friction_shapes: tuple = ()  # (shape, joint 1-based): the truth's friction is not Coulomb-viscous there
    effects: tuple = ()  # the hidden effects' truth as simulated (``identification.virtual`` load torques)
    data: tuple = ()  # identify's --data when it is not ``train`` (a configurations manifest listing them)


def ur5_urdf() -> Path:
    """The example-robot-data UR5 URDF (the vendor's file as ROS users get it)."""
    for base in {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}:
        path = Path(base) / "cmeel.prefix/share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"
        if path.exists():
            return path
    raise FileNotFoundError("example-robot-data's ur5_robot.urdf is not installed (pip install example-robot-data)")


def friction_shapes(robot) -> tuple:
    """``(shape, joint 1-based)`` where the truth's steady-state friction (``lugre_exact.steady_state_friction``:
    ``(fc + (fs - fc) exp(-(qd/vs)^2)) sign qd + fv |qd|^dv sign qd``) is not Coulomb-viscous, in the diagnosis's
    ``friction_shape`` names: ``stribeck`` where a hump rises above the Coulomb level (``fs > fc``), ``smooth_coulomb``
    where the viscous term is a power of the speed (``dv != 1``: a curve ``tanh(qd / v)`` bends the viscous line
    towards). A diagnosis that names one of them names physics the arm has."""
    out = []
    for j, drive in enumerate(robot.drives or ()):
        if drive.fs > drive.fc:
            out.append(("stribeck", j + 1))
        if drive.dv != 1.0:
            out.append(("smooth_coulomb", j + 1))
    return tuple(out)


def _reference(robot, duration: float, rng, still: float = 0.0, slow: float = 1.0):
    """Sum of sines per joint within half the limits (times ``slow``), after ``still`` seconds at rest."""
    t = np.arange(0.0, duration + 1e-9, 1e-3)
    moving = np.clip(t - still, 0.0, None)
    span = duration - still
    fade = 0.5 * (1.0 - np.cos(np.pi * np.minimum(1.0, np.minimum(moving, span - moving))))
    low, high = np.asarray(robot.q_min), np.asarray(robot.q_max)
    centre = np.clip(0.0, low + 0.25 * (high - low), high - 0.25 * (high - low))
    q = np.tile(centre, (t.size, 1))
    for j in range(robot.n_dof):
        omega = 2.0 * np.pi * rng.uniform(0.1, 0.5, 3) * slow
        phase, weight = rng.uniform(0.0, 2.0 * np.pi, 3), rng.uniform(0.5, 1.0, 3)
        room = min(high[j] - centre[j], centre[j] - low[j])
        scale = 0.5 * min(
            room / weight.sum(),
            slow * robot.qd_max[j] / (weight * omega).sum(),
            slow * robot.qdd_max[j] / (weight * omega**2).sum(),
        )
        x = (scale * weight * np.sin(np.outer(moving, omega) + phase)).sum(axis=1)
        q[:, j] = centre[j] + fade * (x - x[0])
    return t, q


def _jittered(rec, rate: float, rng, jitter: float, gap: tuple | None = None, nan_rows: int = 0):
    """(t, q, tau) sampled at ``rate`` with time-stamp jitter [s], an optional gap (start, length) [s] of dropped
    samples, and ``nan_rows`` rows whose values are NaN (a logger's dropouts)."""
    step = max(1, int(round(1.0 / (rate * float(np.median(np.diff(rec.t)))))))
    keep = np.arange(0, rec.n_samples, step)
    t, q, tau = rec.t[keep], rec.q[keep], rec.tau[keep]
    if gap is not None:
        inside = (t >= gap[0]) & (t < gap[0] + gap[1])
        t, q, tau = t[~inside], q[~inside], tau[~inside]
    stamps = t + rng.normal(0.0, jitter, t.size) * (jitter > 0)
    stamps = np.maximum.accumulate(stamps)  # a logger's clock never runs back
    stamps[1:] = np.maximum(stamps[1:], stamps[:-1] + 1e-6)
    q, tau = q.copy(), tau.copy()
    if nan_rows:
        rows = rng.choice(np.arange(10, t.size - 10), nan_rows, replace=False)
        q[rows] = np.nan
        tau[rows] = np.nan
    return stamps, q, tau


def _simulate(robot, reference, rate, noise, rng, extras=(), payload=None):
    """(recording with torque noise ``noise`` [N m per joint], the truth model's RMSE floor per joint): the noise and
    the LuGre friction's departure from its steady state, which no steady-state friction model predicts."""
    options = SimulationOptions(
        rate=rate, record_tau=True, record_current=False, tau_noise_std=0.0, payload=payload, q_noise_std=0.0
    )
    rec, truth = simulate_recording(robot, reference, options, rng, extras=extras)
    tau = rec.tau + rng.normal(0.0, 1.0, rec.tau.shape) * np.asarray(noise)
    dynamic = truth.tau_friction - steady_state_friction(truth.qd, LuGreArrays.from_drives(robot.drives))
    floor = np.sqrt(np.asarray(noise, dtype=float) ** 2 + np.mean(dynamic**2, axis=0))
    return rec.with_tau(tau), floor


def _write_csv(path: Path, header: list, columns: list) -> Path:
    data = np.column_stack(columns)
    fmt = ["%.6f"] + ["%.9g"] * (data.shape[1] - 1)  # time stamps to the microsecond (Unix seconds need 16 digits)
    np.savetxt(path, data, delimiter=",", header=",".join(header), comments="", fmt=fmt)
    return path


def _friction_drives(robot, scale: float) -> tuple:
    """Coulomb-viscous-ish LuGre drives scaled to the arm's torques (the virtual robot needs drives)."""
    return tuple(
        DriveParameters(kt=1.0, fc=0.8 * scale, fs=1.0 * scale, vs=0.05, fv=1.5 * scale, sigma0=1e4, sigma1=30.0)
        for _ in range(robot.n_dof)
    )


def cobot_currents(folder: Path, rng) -> Case:
    """A UR5 from its vendor URDF logging motor currents over RTDE at 500 Hz (0-based column names, jitter, NaN
    rows), carrying a 2 kg gripper stated in the sidecar; currents x motor kt x gear ratio are the torques."""
    urdf = ur5_urdf()
    gear, motor_kt = 101.0, 0.125
    body = f'format = "psdm-robot/1"\n[urdf]\npath = "{urdf}"\n\n'
    links = ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link")
    rotors = (0.4, 0.4, 0.3, 0.1, 0.1, 0.1)  # motor inertia x gear^2 (the URDF has none; a real UR's drives do)
    body += "".join(f'[[link]]\nname = "{n}"\nrotor_inertia = {r}\n\n' for n, r in zip(links, rotors))
    body += "[[drive]]\nkt = 1.0\nfc = 1.0\nfs = 1.2\nvs = 0.05\nfv = 2.0\n\n" * 6
    truth_file = folder / "ur5_truth.toml"
    truth_file.write_text(body)
    robot = load_robot(truth_file)
    user = folder / "ur5.toml"
    user.write_text(
        body.replace("kt = 1.0\nfc = 1.0\nfs = 1.2\nvs = 0.05\nfv = 2.0\n", f"kt = {gear * motor_kt}\n")
        + f"[transmission]\ngear_ratios = [{', '.join(['101'] * 6)}]\nmotor_kt = [{', '.join(['0.125'] * 6)}]\n"
        + '\n[recording]\nside = { q = "joint", tau = "motor" }\n'
    )
    payload = Payload(mass=2.0, com=np.array([0.0, 0.0, 0.06]))
    current_noise = 0.02  # [A] at the motor
    noise = np.full(6, current_noise * gear * motor_kt)
    files = []
    for name in ("train", "validate"):
        reference = _reference(robot, 12.0 if name == "train" else 8.0, rng)
        rec, floor = _simulate(robot, reference, 1000.0, noise, rng, payload=payload)
        t, q, tau = _jittered(rec, 500.0, rng, jitter=2e-4, nan_rows=3)
        current = tau / (gear * motor_kt)
        header = ["timestamp"] + [f"actual_q_{j}" for j in range(6)] + [f"actual_current_{j}" for j in range(6)]
        path = _write_csv(folder / f"rtde_{name}.csv", header, [t + 1733380000.0, q, current])
        path.with_suffix(".payload.json").write_text(json.dumps({"mass": 2.0, "com": [0.0, 0.0, 0.06]}))
        files.append(path)
    return Case(
        name="cobot_currents_payload",
        what="UR5 vendor URDF, RTDE 500 Hz: motor currents x kt x gear, 0-based names, jitter, NaN rows, 2 kg stated",
        robot=user,
        train=tuple(files[:-1]),
        validate=files[-1],
        extra=("--columns", "t=timestamp,q=actual_q_,i=actual_current_"),
        true_links=np.array([link.mass for link in robot.links]),
        payload_mass=2.0,
        floor_nm=floor,
        friction_shapes=friction_shapes(robot),
    )


def _kr6_robot():
    """The KR6 Agilus DH table with a 50 kg-class arm's links and drives (as a user writes it from a datasheet)."""
    base = kr6()
    masses = [7.0, 8.0, 5.0, 3.0, 1.5, 0.5]
    links = tuple(
        LinkInertia(mass=m, com=np.array([0.02, 0.01, 0.03]) * (1 + i % 2), inertia=np.diag([0.04, 0.035, 0.03]) * m)
        for i, m in enumerate(masses)
    )
    joints = tuple(
        dataclasses.replace(j, q_min=-2.5, q_max=2.5, qd_max=3.0, qdd_max=12.0, tau_max=400.0) for j in base.joints
    )
    return dataclasses.replace(
        base.with_links(links),
        joints=joints,
        name="KR6-like industrial arm",
        rotor_inertia=np.array([0.3, 0.3, 0.12, 0.04, 0.04, 0.03]),
        drives=_friction_drives(base, 2.0),
    )


def industrial_degrees(folder: Path, rng) -> Case:
    """A six-axis industrial arm from a DH table, traced at 1 kHz by its controller: positions in degrees, torques
    in mN m, vendor column names; the trace starts 2 s before the arm moves."""
    robot = load_robot(write_robot_file(_kr6_robot(), folder / "kr6.toml", overwrite=True))
    noise = np.full(6, 0.3)
    files = []
    for name in ("train", "validate"):
        reference = _reference(robot, 14.0 if name == "train" else 9.0, rng, still=2.0)
        rec, floor = _simulate(robot, reference, 1000.0, noise, rng)
        t, q, tau = _jittered(rec, 1000.0, rng, jitter=0.0)
        header = ["Time"] + [f"AxisPos_A{j + 1}" for j in range(6)] + [f"MotorTorque_A{j + 1}" for j in range(6)]
        files.append(_write_csv(folder / f"trace_{name}.csv", header, [t, np.degrees(q), 1000.0 * tau]))
    return Case(
        name="industrial_dh_degrees_mNm",
        what="KR6-like DH table, controller trace 1 kHz: degrees, mN m, vendor names, 2 s at rest first",
        robot=robot.source,
        train=tuple(files[:-1]),
        validate=files[-1],
        extra=("--columns", "t=Time,q=AxisPos_A:deg,tau=MotorTorque_A:mNm"),
        unstated=("--columns", "t=Time,q=AxisPos_A,tau=MotorTorque_A"),
        # the fix as the option to pass for this file: its own columns with the unit added (cli.column_hint)
        refusal_words=("trace_", "q1", "positions in degrees?", "--columns t=Time,q=AxisPos_A:deg,tau=MotorTorque_A"),
        true_links=np.array([link.mass for link in robot.links]),
        floor_nm=floor,
        friction_shapes=friction_shapes(robot),
    )


def industrial_slow(folder: Path, rng) -> Case:
    """The KR6-like arm moved slowly through gravity poses (a tenth of its speeds) with a known 5 kg tool stated in
    each recording's sidecar, logged at 250 Hz in psdm's own CSV columns: gravity alone excites the links."""
    robot = load_robot(write_robot_file(_kr6_robot(), folder / "kr6.toml", overwrite=True))
    payload = Payload(mass=5.0, com=np.array([0.0, 0.0, 0.1]))
    noise = np.full(6, 0.3)
    files = []
    for name in ("train", "validate"):
        rec, floor = _simulate(robot, _reference(robot, 20.0, rng, slow=0.1), 1000.0, noise, rng, payload=payload)
        t, q, tau = _jittered(rec, 250.0, rng, jitter=0.0)
        header = ["t"] + [f"q{j + 1}" for j in range(6)] + [f"tau{j + 1}" for j in range(6)]
        path = _write_csv(folder / f"slow_{name}.csv", header, [t, q, tau])
        path.with_suffix(".payload.json").write_text(json.dumps({"mass": 5.0, "com": [0.0, 0.0, 0.1]}))
        files.append(path)
    return Case(
        name="industrial_slow_gravity_tool",
        what="KR6-like DH arm, slow gravity poses (0.1 x its speeds), 250 Hz, known 5 kg tool in the sidecars",
        robot=Path(robot.source),
        train=tuple(files[:-1]),
        validate=files[-1],
        true_links=np.array([link.mass for link in robot.links]),
        payload_mass=5.0,
        floor_nm=floor,
        friction_shapes=friction_shapes(robot),
    )


def heavy_counterbalance(folder: Path, rng) -> Case:
    """The heavy industrial arm (benchmarks/heavy_arm.py) with a cam counterbalance on joint 2, slow gravity-only
    motions at 250 Hz, 10 s training and 10 s validation, in a plain psdm CSV. The cam is a balancer: it opposes
    joint 2's gravity torque at every angle, its first harmonic taking a seeded 40-90 % of the gravity amplitude at
    the motions' centre pose (``identification.virtual.counterbalance``)."""
    from heavy_arm import heavy_industrial_arm

    robot = heavy_industrial_arm(folder)
    low, high = np.asarray(robot.q_min), np.asarray(robot.q_max)
    centre = np.clip(0.0, low + 0.25 * (high - low), high - 0.25 * (high - low))  # as ``_reference`` centres them
    share = float(rng.uniform(0.4, 0.9))
    counterbalance = cam_counterbalance(robot, 1, centre, share, lobe=0.4)
    noise = np.full(6, 5.0)
    files = []
    for name in ("train", "validate"):
        reference = _reference(robot, 10.0, rng, slow=0.5)
        rec, floor = _simulate(robot, reference, 1000.0, noise, rng, extras=(counterbalance,))
        t, q, tau = _jittered(rec, 250.0, rng, jitter=0.0)
        header = ["t"] + [f"q{j + 1}" for j in range(6)] + [f"tau{j + 1}" for j in range(6)]
        files.append(_write_csv(folder / f"heavy_{name}.csv", header, [t, q, tau]))
    return Case(
        name="heavy_counterbalance_slow",
        what=f"heavy 6-axis arm (~1 t), cam counterbalance on J2 taking {share:.0%} of its gravity, slow motions, "
        "250 Hz, 10 s + 10 s",
        robot=Path(robot.source),
        train=tuple(files[:-1]),
        validate=files[-1],
        true_links=np.array([link.mass for link in robot.links]),
        floor_nm=floor,
        hidden=(("counterbalance", 2),),
        friction_shapes=friction_shapes(robot),
    )


#: The HX-210's DH table as its datasheet gives it (standard DH: a, alpha, d, theta offset) with its limits
#: (q_min, q_max, qd_max, qdd_max, tau_max).
HX210_JOINTS = (
    (0.312, "-pi/2", 0.670, "0.0", -3.14, 3.14, 1.83, 3.5, 30000.0),
    (1.075, "0.0", 0.0, "-pi/2", -1.05, 1.57, 1.57, 3.0, 40000.0),
    (0.225, "-pi/2", 0.0, "0.0", -2.4, 1.2, 1.57, 3.5, 20000.0),
    (0.0, "pi/2", 1.280, "0.0", -6.28, 6.28, 2.27, 6.0, 1500.0),
    (0.0, "-pi/2", 0.0, "0.0", -2.18, 2.18, 2.27, 6.0, 1500.0),
    (0.0, "0.0", 0.215, "0.0", -6.28, 6.28, 3.67, 8.0, 800.0),
)


def _cylinder(mass: float, radius: float, length: float, axis: int) -> np.ndarray:
    """A solid cylinder's inertia about its centre of mass (xx, yy, zz, xy, xz, yz), its axis along ``axis``."""
    side = mass * (3.0 * radius**2 + length**2) / 12.0
    diagonal = [side, side, side]
    diagonal[axis] = 0.5 * mass * radius**2
    return np.array([*diagonal, 0.0, 0.0, 0.0])


def _hx210_truth(folder: Path):
    """The HX-210's truth: the datasheet's joints, CAD-like links, rotors and LuGre drives of a 210 kg-class arm."""
    rows = "".join(
        f'[[joint]]\nname = "A{j + 1}"\na = {a}\nalpha = "{alpha}"\nd = {d}\ntheta = "{theta}"\nq_min = {lo}\n'
        f"q_max = {hi}\nqd_max = {qd}\nqdd_max = {qdd}\ntau_max = {tau}\n\n"
        for j, (a, alpha, d, theta, lo, hi, qd, qdd, tau) in enumerate(HX210_JOINTS)
    )
    joints = folder / "hx210_joints.toml"
    joints.write_text('format = "psdm-robot/1"\nname = "HX-210 heavy arm"\nconvention = "standard"\n'
                      f"gravity = [0.0, 0.0, -9.80665]\n\n[assumptions]\ndrive_inertia = true\n\n{rows}")  # fmt: skip
    links = (
        LinkInertia(mass=330.0, com=np.array([-0.12, 0.28, 0.02]), inertia=_cylinder(330.0, 0.40, 0.7, 1)),
        LinkInertia(mass=185.0, com=np.array([-0.52, 0.0, 0.16]), inertia=_cylinder(185.0, 0.18, 1.1, 0)),
        LinkInertia(mass=235.0, com=np.array([-0.08, 0.04, 0.06]), inertia=_cylinder(235.0, 0.30, 0.5, 2)),
        LinkInertia(mass=105.0, com=np.array([0.0, -0.55, 0.0]), inertia=_cylinder(105.0, 0.15, 1.1, 1)),
        LinkInertia(mass=32.0, com=np.array([0.0, 0.04, 0.0]), inertia=_cylinder(32.0, 0.12, 0.25, 2)),
        LinkInertia(mass=8.0, com=np.array([0.0, 0.0, -0.04]), inertia=_cylinder(8.0, 0.11, 0.06, 2)),
    )
    # Coulomb, viscous, bristle stiffness and damping per joint (static friction 1.2 x Coulomb below 0.03 rad/s)
    friction = ((260, 620, 4e7, 3000), (310, 720, 4e7, 3000), (210, 420, 3e7, 2400), (55, 80, 4e6, 300),
                (48, 70, 4e6, 280), (22, 28, 2e6, 120))  # fmt: skip
    drives = tuple(DriveParameters(kt=1.0, fc=fc, fs=1.2 * fc, vs=0.03, fv=fv, dv=1.0, sigma0=s0, sigma1=s1)
                   for fc, fv, s0, s1 in friction)  # fmt: skip
    base = load_robot(joints)
    rotors = np.array([420.0, 460.0, 260.0, 38.0, 34.0, 14.0])
    truth = dataclasses.replace(base, links=links, rotor_inertia=rotors, drives=drives, source=None)
    return base, load_robot(write_robot_file(truth, folder / "hx210_truth.toml", overwrite=True))


def heavy_gas_spring(folder: Path, rng, duration: float = 30.0) -> Case:
    """A 210 kg-class six-axis arm (HX-210: 1 t of links, rotors of 14-460 kg m^2, Coulomb friction of 22-310 N m)
    with a gas-spring counterbalance on joint 2 (a strut on levers of 0.18 and 0.55 m, 35 % stiffer compressed)
    taking a seeded 50-80 % of joint 2's gravity amplitude at the motions' centre pose, as its user meets it: a
    robot file written from the datasheet and a CAD export whose link masses, centres of mass, inertias and rotor
    inertias are each 10-20 % off, no friction in it; 250 Hz logs in psdm's CSV columns, each starting with 1.5 s at
    rest, ``duration`` s unloaded and ``duration`` s with a known 150 kg payload (sidecars) to train on, half that
    held out; torque noise of 14-1.2 N m."""
    from identification.virtual.counterbalance import gas_spring_counterbalance

    base, truth = _hx210_truth(folder)

    def off() -> float:  # a datasheet's 10-20 % either way
        return 1.0 + float(rng.choice([-1.0, 1.0])) * float(rng.uniform(0.10, 0.20))

    links = tuple(LinkInertia(mass=k.mass * off(), com=np.asarray(k.com) * off(),
                              inertia=np.asarray(k.inertia) * off()) for k in truth.links)  # fmt: skip
    rotors = np.asarray(truth.rotor_inertia) * np.array([off() for _ in range(6)])
    user = dataclasses.replace(base, links=links, rotor_inertia=rotors, source=None)
    robot = write_robot_file(user, folder / "hx210.toml", overwrite=True)
    low, high = np.asarray(truth.q_min), np.asarray(truth.q_max)
    centre = np.clip(0.0, low + 0.25 * (high - low), high - 0.25 * (high - low))  # as ``_reference`` centres them
    share = float(rng.uniform(0.5, 0.8))
    gas = gas_spring_counterbalance(truth, 1, centre, share, a=0.18, b=0.55, stiffening=0.35)
    payload = Payload(mass=150.0, com=np.array([0.0, 0.0, 0.25]))
    noise = np.array([14.0, 16.0, 10.0, 2.5, 2.0, 1.2])
    files = []
    for name, seconds, load in (("train_empty", duration, None), ("train_150kg", duration, payload),
                                ("validate", duration / 2, None)):  # fmt: skip
        reference = _reference(truth, seconds, rng, still=1.5, slow=0.8)
        rec, floor = _simulate(truth, reference, 1000.0, noise, rng, extras=(gas,), payload=load)
        t, q, tau = _jittered(rec, 250.0, rng, jitter=2e-5)
        header = ["t"] + [f"q{j + 1}" for j in range(6)] + [f"tau{j + 1}" for j in range(6)]
        path = _write_csv(folder / f"{name}.csv", header, [t, q, tau])
        stated = {"mass": 0} if load is None else {"mass": 150.0, "com": [0.0, 0.0, 0.25]}
        path.with_suffix(".payload.json").write_text(json.dumps(stated))
        files.append(path)
    return Case(
        name="heavy_gas_spring_datasheet",
        what=f"HX-210 (210 kg class, 1 t of links), gas spring on J2 taking {share:.0%} of its gravity, datasheet "
        f"masses 10-20 % off, 250 Hz, {duration:g} s + {duration:g} s with a known 150 kg, {duration / 2:g} s held out",
        robot=robot,
        train=tuple(files[:-1]),
        validate=files[-1],
        true_links=np.array([link.mass for link in truth.links]),
        floor_nm=floor,
        hidden=(("counterbalance", 2),),
        friction_shapes=friction_shapes(truth),
        effects=(gas,),
    )


def serial_bag(folder: Path, rng) -> Case:
    """A six-joint serial arm logged as a ROS 2 MCAP at 1 kHz (jittered stamps, a 60 ms gap of dropped messages,
    a gripper joint on the same topic), with an unknown 1.5 kg gripper named in the sidecar."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    robot = load_robot(write_robot_file(serial_arm(6), folder / "serial6.toml", overwrite=True))
    payload = Payload(mass=1.5, com=np.array([0.0, 0.02, 0.08]))
    noise = np.full(6, 0.1)
    store = get_typestore(Stores.ROS2_HUMBLE)
    joint_state = store.types["sensor_msgs/msg/JointState"]
    header_type, time_type = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    names = [*robot.joint_names, "gripper_finger"]
    files = []
    for name in ("empty", "train", "validate"):
        reference = _reference(robot, 8.0 if name != "train" else 12.0, rng)
        rec, floor = _simulate(robot, reference, 1000.0, noise, rng, payload=None if name == "empty" else payload)
        t, q, tau = _jittered(rec, 1000.0, rng, jitter=1e-4, gap=(4.0, 0.06))
        path = folder / f"arm_{name}.mcap"
        with Writer(folder / f"bag_{name}", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            topic = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
            for tk, qk, tauk in zip(t, q, tau):
                ns = 1_764_900_000 * 10**9 + int(round(tk * 1e9))
                message = joint_state(
                    header=header_type(stamp=time_type(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=""),
                    name=names,
                    position=np.append(qk, 0.01),
                    velocity=np.zeros(0),
                    effort=np.append(tauk, 0.0),
                )
                writer.write(topic, ns, store.serialize_cdr(message, "sensor_msgs/msg/JointState"))
        mcap = next((folder / f"bag_{name}").glob("*.mcap"))
        mcap.rename(path)
        path.with_suffix(".payload.json").write_text(
            json.dumps({"mass": 0} if name == "empty" else {"unknown": "gripper"})
        )
        files.append(path)
    return Case(
        name="serial_mcap_unknown_payload",
        what="6-joint serial arm, ROS 2 MCAP 1 kHz: jitter, 60 ms gap, extra gripper joint; unknown 1.5 kg gripper "
        "on 2 of 3 bags (sidecars)",
        robot=Path(robot.source),
        train=tuple(files[:-1]),
        validate=files[-1],
        true_links=np.array([link.mass for link in robot.links]),
        payload_mass=1.5,
        payload_known=False,
        floor_nm=floor,
        friction_shapes=friction_shapes(robot),
    )


def warming_cobot(folder: Path, rng) -> Case:
    """A 7-joint cobot logging motor-side positions and currents over a session in which its joints warm up
    (``unseen_warm_cobot``, which builds on this module)."""
    from unseen_warm_cobot import warming_cobot as build_case

    return build_case(folder, rng)


def belt_cobot(folder: Path, rng) -> Case:
    """A UR10-class cobot on motor currents, a 7:1 belt on joint 6, its known load changing between recordings
    (``unseen_belt_cobot``)."""
    from unseen_belt_cobot import belt_cobot as build_case

    return build_case(folder, rng)


def heavy_trace(folder: Path, rng) -> Case:
    """The HX-210 traced by its controller: 83.3 Hz, degrees, currents in % of rated, a cold start, an unstated
    gripper on one trace (``unseen_trace_heavy``)."""
    from unseen_trace_heavy import heavy_trace as build_case

    return build_case(folder, rng)


CASES = {
    "cobot_currents_payload": cobot_currents,
    "industrial_dh_degrees_mNm": industrial_degrees,
    "industrial_slow_gravity_tool": industrial_slow,
    "heavy_counterbalance_slow": heavy_counterbalance,
    "heavy_gas_spring_datasheet": heavy_gas_spring,
    "serial_mcap_unknown_payload": serial_bag,
    "cobot_warming_currents": warming_cobot,
    "cobot_belt_payload_change": belt_cobot,
    "heavy_trace_percent": heavy_trace,
}


def build(name: str, folder, seed: int = 0) -> Case:
    """Write case ``name``'s files into ``folder`` and return it with its truth."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return CASES[name](folder, np.random.default_rng(seed))


__all__ = ["CASES", "Case", "build", "friction_shapes"]
