"""The compiled real-time-iteration MPC on a calibrated model: the file `psdm identify` wrote, friction included.

The controller's model is the calibrated model's full torque (``codegen.calibrated.build_calibrated_functions``:
the rigid body of the identified base parameters plus each joint's identified friction and offset, the
same Functions ``psdm codegen model.json`` exports and ``psdm validate`` predicts with), inverted for the
forward dynamics, its derivatives through the inverse dynamics. ``friction=False``: the calibrated model
already holds the friction the drives have. The step (one Gauss-Newton SQP step, the QP by HPIPM) is one
compiled C function (``trajopt.mpc_rti``); the plant is Pinocchio's aba on the robot file's parameters with
the drives' friction, which shares no code with the model.

Without a model file the script first makes one: the virtual Denso runs a sine experiment (``psdm simulate``)
and ``psdm identify`` fits it (about 20 s).

Run: python examples/mpc_rti_calibrated.py [MODEL.json] [--steps 100]
"""

import argparse
import shlex
import tempfile
from pathlib import Path

import numpy as np

from codegen.calibrated import build_calibrated_functions
from identification.calibration.calibrated_model import read_calibrated_model
from psdm_casadi.cli import main as psdm
from psdm_casadi.oracle import PinocchioOracle
from trajopt.mpc import MPCOptions
from trajopt.mpc_loop import build_pinocchio_plant, simulate_closed_loop
from trajopt.mpc_model import build_forward_dynamics_jacobian
from trajopt.mpc_rti import build_rti, compile_rti

# 5 ms intervals of 4 semi-implicit Euler steps: the identified friction's sign is smoothed over the file's
# coulomb_velocity (0.05 rad/s), four times steeper than the robot file's law, and on the light wrist one step
# of 5 ms would be unstable (with one step the tracking error is 3 mrad instead of 1)
OPTIONS = MPCOptions(horizon=20, dt=0.005, integrator="euler", rk4_steps=4, max_iter=4, tol=1e-3)


def identified_denso(folder) -> Path:
    """A calibrated-model file of the virtual Denso: simulate a sine experiment, identify it."""
    folder = Path(folder)
    for command in (
        f"simulate denso_vs6556g --experiment sine --duration 8 --rate 500 --seed 1 --tau --out {folder / 'sim'}",
        f"identify denso_vs6556g --data {folder / 'sim' / 'sine.csv'} --out {folder / 'model.json'} --no-html",
    ):
        assert psdm(shlex.split(command)) == 0, f"psdm {command} failed"
    return folder / "model.json"


def calibrated_rti(model_file, options=OPTIONS):
    """(RTI controller, LoadedModel): the real-time iteration on the file's calibrated model (not compiled yet)."""
    loaded = read_calibrated_model(model_file)  # checked: format, robot text, base parameters, consistency
    functions = build_calibrated_functions(loaded.calibrated, loaded.model, loaded.robot)
    jacobian = build_forward_dynamics_jacobian(
        functions.forward_dynamics, functions.inverse_dynamics, functions.mass_matrix
    )
    controller = build_rti(
        loaded.robot, functions.forward_dynamics, options, friction=False, forward_dynamics_jacobian=jacobian
    )
    return controller, loaded


def reference_for(robot):
    """(q_ref, qd_ref) at t: a 0.5 Hz sine on every joint about the middle of its range, from rest."""
    middle = (robot.q_min + robot.q_max) / 2
    amplitude = np.minimum(0.3, 0.2 * (robot.q_max - robot.q_min))
    omega, phase = 2 * np.pi * 0.5, np.linspace(0, np.pi / 2, robot.n_dof)

    def reference(t):
        q_ref = middle + amplitude * (np.sin(omega * t + phase) - np.sin(phase))
        return q_ref, amplitude * omega * np.cos(omega * t + phase)

    return reference


def run(model_file, folder, n_steps):
    """(robot, ClosedLoopResult): the compiled controller against the plant for n_steps intervals."""
    controller, loaded = calibrated_rti(model_file)
    controller = compile_rti(controller, Path(folder) / "rti")
    robot = loaded.robot
    reference = reference_for(robot)
    plant = build_pinocchio_plant(robot)  # the robot file's parameters with the drives' friction
    guess = PinocchioOracle(robot).gravity(reference(0.0)[0])
    return robot, simulate_closed_loop(controller, plant, reference, n_steps, torque_guess=guess)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", nargs="?", help="calibrated-model file (psdm identify --out); default: make one")
    parser.add_argument("--steps", type=int, default=100)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="psdm-rti-") as folder:
        model_file = args.model or identified_denso(folder)
        robot, result = run(model_file, folder, args.steps)
    cpu = np.mean(result.step_cpu_s[1:]) * 1e3
    print(
        f"{robot.name}: tracking RMSE {result.tracking_rmse * 1e3:.3f} mrad over {args.steps} steps of "
        f"{OPTIONS.dt * 1e3:.0f} ms; mean step {np.mean(result.step_time_s[1:]) * 1e3:.3f} ms wall, {cpu:.3f} ms CPU"
    )
    assert result.limit_violation(robot) == 0.0, "a joint or torque limit was crossed"
    assert result.tracking_rmse < 2e-3, "the MPC lost track of the reference"


if __name__ == "__main__":
    main()
