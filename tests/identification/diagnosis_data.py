"""Synthetic train/validation recordings for the diagnosis tests (known hidden effects), and the CLI run on them."""

import contextlib
import io
import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.data.recording import Recording
from identification.diagnosis.candidates import CandidateLibrary
from identification.diagnosis.context import build_context, lugre_parameters, simulate_friction
from identification.diagnosis.diagnose import (
    DiagnosisOptions,
    DiagnosisProblem,
    prepare_problem,
    refine_terms,
    select_terms,
)
from identification.diagnosis.rigid_body_choice import recalibration_parts
from identification.virtual import effects as xp
from identification.virtual.recording_pair import recording_pair as virtual_recording_pair
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import LinkInertia
from trajopt.experiments import sine_experiment

#: The virtual Denso's hidden cam counterbalance on joint 2 and the payload beside it (issue 25's heavy-arm case).
CAM = xp.CamCounterbalance(joint=1, amplitude=12.0, lobe=0.3)
PAYLOAD = xp.Payload(mass=1.5, com=(0.0, 0.0, 0.05))


def recording_pair(robot, extras, seed, train_s=10.0, val_s=5.0):
    """A training and a validation recording of ``robot`` carrying ``extras``, torque-sensor style, along sine
    experiments (``identification.virtual.recording_pair``)."""

    def sine(duration, rng):
        return sine_experiment(robot, duration=duration, rng=rng).reference()

    return virtual_recording_pair(robot, extras, seed, sine, (train_s, val_s))


def scara_recording(robot, seed, offset, friction=(0.3, 0.2), armature=0.0, noise=0.02, duration=6.0, rate=200.0,
                    centre=(0, 0, 0.1, 0), effect=None):  # fmt: skip
    """Two sines per joint of the SCARA about ``centre`` (default the middle of its range); the true torque (Pinocchio)
    with Coulomb-viscous ``friction`` (fc [N m], fv [N m s/rad]), a torque ``offset`` per joint, ``armature`` [kg m^2]
    per joint times its acceleration (a drive inertia, of either sign), ``effect(q)`` (n_samples, n_dof) [N m] if given
    and ``noise`` [N m]."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    centre, amplitude = np.asarray(centre, dtype=float), np.array([0.6, 0.6, 0.035, 1.0])
    q, qd, qdd = (np.zeros((t.size, robot.n_dof)) for _ in range(3))
    for j in range(robot.n_dof):
        w, phase = rng.uniform(1.5, 3.0, 2), rng.uniform(0.0, 2 * np.pi, 2)
        a, arg = amplitude[j] / w, w[:, None] * t + phase[:, None]
        q[:, j] = centre[j] + (a[:, None] * np.sin(arg)).sum(0)
        qd[:, j] = (a[:, None] * w[:, None] * np.cos(arg)).sum(0)
        qdd[:, j] = -(a[:, None] * w[:, None] ** 2 * np.sin(arg)).sum(0)
    fc, fv = friction
    tau = PinocchioOracle(robot).rnea(q, qd, qdd) + fc * np.tanh(qd / 0.05) + fv * qd + offset + armature * qdd
    tau = tau if effect is None else tau + effect(q)
    return Recording(t=t, q=q, tau=tau + rng.normal(scale=noise, size=tau.shape), name=f"scara{seed}")


def nominal_change(robot, rigid, moved, joint):
    """The torque [N m] on ``joint`` a transmission effect that only moves the recorded angle (backlash, elasticity)
    adds to the nominal model, exactly: the rigid-body torque and the robot file's LuGre friction (filtered like the
    recording) on the context ``rigid`` of the recording without it minus on ``moved``, the same plant with it."""
    p = lugre_parameters(robot.drives[joint])
    friction = [ctx.lowpass(simulate_friction(p, ctx.full_t, ctx.full_qd[:, joint])) for ctx in (rigid, moved)]
    return rigid.tau_rigid[:, joint] - moved.tau_rigid[:, joint] + friction[0] - friction[1]


def sine_recording(robot, seed: int, duration: float, extras=(), noise: float = 0.1):
    """A sine-experiment recording of ``robot`` with its friction and ``extras`` (torque sensors, ``noise`` N m) and
    the simulator's truth: the recording and the truth's parts, as ``simulate_recording`` returns them."""
    rng = np.random.default_rng(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the sine experiment may graze a limit
        reference = sine_experiment(robot, duration=duration, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=noise)
    return simulate_recording(robot, reference, options, rng, extras=list(extras))


def rigid_recording(robot, extras, seed=3, duration=8.0):
    """An 8 s sine-experiment recording of ``robot`` carrying ``extras``, torque sensors with 0.1 N m noise and no
    friction: what the rigid body and its envelope see."""
    rng = np.random.default_rng(seed)
    reference = sine_experiment(robot, duration=duration, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    recording, _ = simulate_recording(robot, reference, options, rng, extras=extras)
    return recording


def sine_context(robot, model, seed, duration=3.0):
    """The diagnosis context of a noise-free sine-experiment recording of ``robot`` (torque sensors), filtered at
    15 Hz on a 100 Hz grid: the candidates' columns are evaluated on it."""
    rng = np.random.default_rng(seed)
    rec, _ = simulate_recording(
        robot,
        sine_experiment(robot, duration=duration, rng=rng).reference(),
        SimulationOptions(record_tau=True, record_current=False),
        rng,
    )
    return build_context(robot, model, preprocess(rec, PreprocessOptions(cutoff_hz=15.0)), rate_hz=100.0)


def held_out_pair(robot, extras, duration=16.0, split=8.0) -> tuple:
    """(training, held out): ``rigid_recording`` of ``robot`` carrying ``extras`` for ``duration`` s, split at
    ``split`` s (by default 8 s of each)."""
    recording = rigid_recording(robot, extras, duration=duration)
    return recording.time_slice(-np.inf, split), recording.time_slice(split, np.inf)


def saved_pair(robot, extras, folder: Path) -> tuple:
    """``held_out_pair`` written as ``folder/train.csv`` and ``folder/val.csv`` (replacing them): their paths."""
    paths = (folder / "train.csv", folder / "val.csv")
    for recording, path in zip(held_out_pair(robot, extras), paths):
        save_recording(recording, path, overwrite=True)
    return paths


def cli_json(argv) -> dict:
    """What ``psdm argv`` (each argument ``str``-ed, ``--json`` among them) printed last as JSON, its progress and
    warnings swallowed; asserts the command succeeded (exit 0)."""
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(io.StringIO()):
        assert main([str(a) for a in argv]) == 0
    return json.loads(stdout.getvalue().strip().splitlines()[-1])


SPRING_K, SPRING_Q0 = 40.0, 0.2  # the hidden spring of ``hidden_spring_files`` (joint 2 of the Denso)


def hidden_spring_files(folder: Path, robot, model, robot_source, duration: float, rate: float) -> Path:
    """``folder`` holding ``train.csv`` and ``valid.csv``, sine-experiment recordings of ``robot`` (seeds 30, 31,
    torque sensors with 0.1 N m noise) carrying a spring on joint 2 (``SPRING_K``, ``SPRING_Q0``), and ``model.json``,
    the model identified on the training recording without it (``robot_source``: the robot file it names)."""
    recordings = []
    for k, name in enumerate(("train.csv", "valid.csv")):
        rng = np.random.default_rng(30 + k)
        reference = sine_experiment(robot, duration=duration, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=rate)
        extras = [xp.Spring(joint=1, stiffness=SPRING_K, q0=SPRING_Q0)]
        recording, _ = simulate_recording(robot, reference, options, rng, extras=extras)
        save_recording(recording, folder / name)
        recordings.append(recording)
    fit = identify_trajectories(robot, model, recordings[:1], TrajectoryOptions())
    CalibratedModel.from_fit(robot, model, fit, robot_source=robot_source).save(folder / "model.json")
    return folder


def cad_off(robot, rng):
    """``robot`` with each link's mass, centre of mass and inertia scaled by 1 +- U(0.1, 0.2) (a random sign each): a
    robot file from CAD whose links are 10-20 % off (the prior of the hidden-payload and hidden-balancer tests)."""

    def factor():
        return 1.0 + float(rng.choice([-1.0, 1.0])) * float(rng.uniform(0.1, 0.2))

    links = tuple(LinkInertia(mass=link.mass * factor(), com=np.asarray(link.com) * factor(),
                              inertia=np.asarray(link.inertia) * factor()) for link in robot.links)  # fmt: skip
    return replace(robot, links=links)


def identified_diagnosis(robot, model, recording, split: float = 8.0) -> tuple:
    """The identified diagnosis of ``recording`` without a candidate (Coulomb-viscous friction and the rigid body
    identified; trained before ``split`` s, validated after): ``(problem, recal, selection, final, options)``, the
    prior's problem, the recalibration's, its selection and final fit, and the options they ran with."""
    train, validation = recording.time_slice(-np.inf, split), recording.time_slice(split, np.inf)
    wide = DiagnosisOptions(friction="coulomb_viscous", cutoff_hz=15.0, rate_hz=200.0, samples="diagnosis",
                            library=CandidateLibrary(()))  # fmt: skip
    problem = prepare_problem(robot, model, train, [validation], wide)
    recal = DiagnosisProblem(**recalibration_parts(problem, model))
    identified = replace(wide, rigid_body="identified")
    selection = select_terms(robot, recal, identified)
    return problem, recal, selection, refine_terms(recal, selection, identified), identified
