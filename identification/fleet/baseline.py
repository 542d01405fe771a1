"""A robot's baseline for the daily update: the rigid body held, the terms refitted and their baseline values.

The baseline is a calibrated-model file (``psdm identify``; its base parameters, Coulomb/viscous friction, offsets
and torque-type findings) or a robot file (its nominal parameters and drives' friction). The daily update
(:mod:`identification.fleet.update`) holds the rigid body ``theta`` and refits the columns listed here: friction
per joint, the tracked terms of the fleet (``layout.TrackedTerms``) and those the calibrated model carries, a
payload mass, and the torque constants when the recordings hold currents. The robot and its PSDM model are
loaded on the client, once per distinct model, and sent to the workers.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.coulomb_width import width_value
from identification.calibration.findings import FindingTerm
from identification.data.torque_constants import drive_kt
from identification.fleet.layout import RobotEntry, TrackedTerms

__all__ = ["Baseline", "SharedModels", "build_baseline", "structure_key", "tracked_finding_terms"]

FRICTION = ("fc", "fv")


@dataclass(frozen=True, eq=False)
class Baseline:
    """What the daily update of one robot holds and refits.

    Attributes
    ----------
    robot : RobotDescription
    theta : array, shape (n_base,)
        The rigid body held [the model's base parameters].
    friction : array, shape (n_dof, 2)
        Baseline Coulomb and viscous friction per joint [N m, N m s/rad].
    coulomb_velocity : float or tuple of float
        [rad/s] of the smooth sign ``tanh(qd / v)`` of the Coulomb column (one, or one per joint: ``coulomb_width``).
    kt : array, shape (n_dof,)
        Nominal torque constants [N m/A] (recordings of currents).
    terms : tuple of FindingTerm
        Extra linear terms refitted every day (springs, ripples, offsets).
    term_values : array
        Their baseline coefficients (0 where the baseline does not carry them).
    payload_com : tuple or None
        Flange point [m] of a refitted payload mass (baseline mass 0).
    model_key : str
        Names the PSDM model the update needs (one per distinct robot file).
    robot_source : str
        The robot file (or built-in name) a re-identification names as its source (``reidentify``).
    """

    robot: object
    theta: np.ndarray
    friction: np.ndarray
    coulomb_velocity: float | tuple
    kt: np.ndarray
    terms: tuple
    term_values: np.ndarray
    payload_com: tuple | None
    model_key: str
    robot_source: str = ""


def structure_key(robot) -> str:
    """Names the PSDM model of ``robot``: its model-cache key with unit link inertias and no drives.

    The PSDM regressor depends on the kinematics and the modelling assumptions, not on the inertia or friction
    values, so robots of one model with their own calibrated inertias (a fleet) share one derived model.
    """
    from psdm_casadi.model_cache import model_key

    unit = tuple(replace(link, mass=1.0, com=np.zeros(3), inertia=0.01 * np.eye(3)) for link in robot.links)
    return model_key(replace(robot, links=unit, rotor_inertia=np.ones(robot.n_dof), drives=None))


class SharedModels:
    """``derive(robot)`` once per :func:`structure_key` (the models of one run; ``derive`` is e.g. the model cache)."""

    def __init__(self, derive):
        self.derive = derive
        self.models = {}

    def __call__(self, robot):
        key = structure_key(robot)
        if key not in self.models:
            self.models[key] = self.derive(robot)
        return self.models[key]


def tracked_finding_terms(track: TrackedTerms) -> list:
    """The fleet's tracked terms as finding terms (0-based joints): springs, ripples, offsets."""
    terms = [FindingTerm("spring", j - 1) for j in track.spring]
    terms += [FindingTerm("torque_ripple", j - 1, harmonic=h) for j, h in track.ripple]
    terms += [FindingTerm("torque_offset", j - 1) for j in track.offset]
    return terms


def _merge(carried: list, tracked: list) -> tuple:
    """Terms and baseline coefficients: the calibrated model's, then the tracked ones it does not carry."""
    terms, values = [], []
    for term, coefficients in carried:
        terms.append(term)
        values.extend(float(c) for c in coefficients)
    for term in tracked:
        if term not in terms:
            terms.append(term)
            values.extend([0.0] * len(term.feature_names()))
    return tuple(terms), np.asarray(values, dtype=float)


def _robot_friction(robot) -> np.ndarray:
    return np.array([[d.fc, d.fv] for d in robot.drives], dtype=float)


def build_baseline(entry: RobotEntry, track: TrackedTerms, derive) -> tuple:
    """(Baseline, PSDM model) of a robot entry; ``derive(robot) -> PSDMModel`` (the model cache).

    Raises
    ------
    RobotFileError, ModelFileError
        For a baseline file that does not read (naming it).
    """
    tracked = tracked_finding_terms(track)
    if entry.baseline_kind == "calibrated":
        from identification.calibration.calibrated_model import read_calibrated_model

        loaded = read_calibrated_model(entry.baseline, derive=derive)
        calibrated, robot, model = loaded.calibrated, loaded.robot, loaded.model
        drive = calibrated.document["drive"]
        named = dict(zip(drive["names"], calibrated.drive))
        friction = np.array([[named.get(f"{t}{j + 1}", 0.0) for t in FRICTION] for j in range(robot.n_dof)])
        terms, values = _merge(calibrated.torque_findings, tracked)
        offsets = [FindingTerm("torque_offset", j) for j in range(robot.n_dof) if f"offset{j + 1}" in named]
        for term in offsets:  # the calibrated model's offsets are refitted as findings
            if term not in terms:
                terms, values = (*terms, term), np.append(values, named[f"offset{term.joint + 1}"])
        theta, cv = calibrated.theta, width_value(calibrated.coulomb_widths)
        source = str(calibrated.robot_file())
    else:
        from psdm_casadi.robot import load_robot

        robot = load_robot(entry.baseline)
        model = derive(robot)
        theta = model.base_parameters(robot.nominal_dynamic_parameters())
        friction, cv = _robot_friction(robot), 0.05
        source = str(entry.baseline)
        terms, values = _merge([], tracked)
    kt = drive_kt(robot) if robot.drives else np.ones(robot.n_dof)
    baseline = Baseline(robot, np.asarray(theta, dtype=float), friction, cv, kt, terms, values, track.payload_com,
                        structure_key(robot), source)  # fmt: skip
    return baseline, model
