"""Calibrated-model files built without an identification, for the tests of what the loader refuses.

:func:`model_document` is the document ``CalibratedModel.from_fit`` writes for a robot whose "identified"
standard parameters are its robot file's nominal ones (consistent by construction) and whose base parameters
are their image under the derived model, as an identification writes them. The tests edit copies of it.
"""

from __future__ import annotations

import copy
import json

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.pseudo_inertia import pseudo_inertia_eigenvalues
from identification.calibration.trajectory_fit import TrajectoryFit
from psdm_casadi.derive import derive_psdm
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, load_robot

SCARA_FILE = BUILTIN_ROBOTS_DIR / "scara.toml"


def nominal_fit(robot, model, friction=("fc", "fv")) -> TrajectoryFit:
    """A TrajectoryFit holding the robot file's nominal standard parameters and a few drive values."""
    standard = np.asarray(robot.nominal_dynamic_parameters(), dtype=float).reshape(robot.n_dof, -1)
    theta = model.base_parameters(standard)
    names = tuple(f"{term}{j + 1}" for j in range(robot.n_dof) for term in friction)
    drive = np.linspace(0.5, 2.0, len(names))
    return TrajectoryFit(
        standard=standard, theta=theta, drive=drive, drive_names=names, inertia_joints=(),
        friction_terms=tuple(friction), coulomb_velocity=0.05, theta_ols=theta, drive_ols=drive,
        theta_std=np.full(theta.size, 0.01), drive_std=np.full(drive.size, 0.01), sigma=np.ones(robot.n_dof),
        condition_number=10.0, consistent=True, checked=True,
        min_pseudo_inertia_eigenvalue=float(pseudo_inertia_eigenvalues(standard[:, :10]).min()),
        cutoff_hz=(10.0,), decimation=(1,), n_samples=1000, solver_status="Solve_Succeeded", seconds=0.0,
    )  # fmt: skip


def model_document(robot_file=SCARA_FILE) -> dict:
    """The calibrated-model document of ``robot_file``'s nominal parameters (module docstring)."""
    robot = load_robot(robot_file)
    model = derive_psdm(robot)
    written = CalibratedModel.from_fit(robot, model, nominal_fit(robot, model), robot_source=robot_file)
    return copy.deepcopy(written.document)


def model_text(document: dict) -> str:
    """The file text of a (possibly edited) document; NaN is written as the bare ``NaN`` JSON readers accept."""
    return json.dumps(document, indent=1)
