"""A load nobody stated on a recording a model is judged on: found in its residual, judged a body or not, said.

A held-out recording that carries a load its sidecar does not state (a gripper the user forgot to declare, a part
picked up) shows, on the joints the load turns, a torque no model of the arm explains. Judged as it stands, every
candidate model looks bad there, the judges that compare models (identify's column choices, the robot file's baseline,
the never-worse margins) compare them on a torque none can explain, and the user is told nothing about the load.

The load is found by the one flange fit the project has (``payload_check.new_payload``): the 10 inertial parameters of
a body fixed to the flange, fitted to the recording's residual of a model held fixed, its standard deviations allowing
for the residual's correlation and the model's own estimation error. It is a load when that fit passes its rules (the
body removes at least ``payload_check.MIN_DROP`` of the weighted residual and its mass is ``payload_check.MIN_Z``
standard deviations above zero: a positive mass) and the body is one a flange can carry (:func:`judge_load`):

- its centre of mass within ``REACH`` of the flange origin, and its mass's RMS distance from the origin (from the
  trace of its inertia) within it too: a tool, a gripper or a held part sits within half a metre of the flange; a body
  farther out is a lever that takes up an error of the arm's own (a link's centre of mass, a spring) more likely than
  a load, and is not taken off;
- a body at all: its pseudo-inertia (``pseudo_inertia``, Wensing, Kim and Slotine 2017) positive semi-definite within
  ``CONSISTENT_SIGMAS`` standard deviations of its smallest eigenvalue (a short recording fixes a small load's inertia
  poorly: a point mass fitted with noise is indefinite by a little).

Each comparison allows ``CONSISTENT_SIGMAS`` of the estimate's standard deviation. A plausible load is taken off the
recording (``payload_check.without_load``) as a point mass at its centre of mass, unless the fit shows its rotational
inertia beyond its uncertainty (``P_INERTIA``): the flange body's inertia columns are nearly those of the wrist links
and rotors, and a model's error there moves them; then as the body nearest the fit (the pseudo-inertia's negative
eigenvalues set to zero): ``psdm identify`` judges on the arm, and identify, ``psdm validate`` and ``psdm diagnose
MODEL`` report the arm's RMSE beside the one with the load left in, the load (mass, centre of mass, their standard
deviations, how clearly it stands out) and the sidecar that declares it. An implausible one is reported, not taken off.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from identification.calibration.payload_check import NewPayload, model_columns, new_payload, validation_with_payload
from identification.calibration.pseudo_inertia import link_from_pseudo_inertia, pseudo_inertia
from identification.data.configuration import sidecar_path

__all__ = [
    "CONSISTENT_SIGMAS",
    "P_INERTIA",
    "REACH",
    "LoadCheck",
    "UnstatedLoad",
    "find_unstated_load",
    "judge_load",
    "judge_recording",
    "point_mass",
]

REACH = 0.5  # [m] from the flange origin: where the centre of mass and the mass of a carried load lie
CONSISTENT_SIGMAS = 3.0  # the standard deviations each plausibility bound allows the fitted body
P_INERTIA = 1e-3  # the load's rotational inertia is taken off only where the fit shows it this clearly


@dataclass(frozen=True)
class UnstatedLoad:
    """A load a recording carries beyond what is stated for it (module docstring).

    ``found`` is the flange fit (``payload_check.NewPayload``); ``body`` the 10 inertial parameters taken off (about
    the flange origin: a point mass at the centre of mass, or with ``inertia_shown`` the nearest body to the fit);
    ``problems`` why it is not a load a flange carries (empty: plausible, taken off)."""

    found: NewPayload
    body: tuple
    problems: tuple = ()
    inertia_shown: bool = False

    @property
    def plausible(self) -> bool:
        return not self.problems

    @property
    def z(self) -> float:
        """How clearly the mass stands out: its standard deviations above zero."""
        return self.found.mass / self.found.mass_std if self.found.mass_std > 0 else float("inf")

    def sidecar(self) -> str:
        """The sidecar that declares the load, with its file name (``A.payload.json`` beside ``A.csv``)."""
        mass = float(f"{self.found.mass:.3g}")
        com = [round(float(v), 3) + 0.0 for v in self.found.com]
        return f"{sidecar_path(self.found.recording).name} {json.dumps({'mass': mass, 'com': com})}"

    def to_dict(self) -> dict:
        return {**self.found.to_dict(), "z": self.z, "plausible": self.plausible, "problems": list(self.problems),
                "reach_m": REACH, "taken_off": self.plausible, "parameters": list(self.body),
                "inertia_shown": self.inertia_shown,
                "sidecar": self.sidecar()}  # fmt: skip

    def judged(self) -> dict:
        """The load as taken off: mass, centre of mass and the 10 parameters of the body (about the flange origin)."""
        f = self.found
        return {"mass": f.mass, "mass_std": f.mass_std, "com": list(f.com), "parameters": list(self.body)}

    def sentence(self, left_in=None) -> str:
        """One line for a command's output: the load, how sure, what was done with it and the fix. ``left_in``: the
        per-joint RMSE with the load left in (the RMSE reported is the arm's)."""
        f, path = self.found, self.found.recording
        com = ", ".join(f"{v:.3f}" for v in f.com)
        spread = ", ".join(f"{v:.2g}" for v in f.com_std)
        head = (f"{path} carries a load at the flange that nothing states: {f.mass:.3g} +- {f.mass_std:.2g} kg (its "
                f"mass {self.z:.0f} standard deviations above zero; it explains {100 * f.residual_drop:.0f} % of the "
                f"residual), centre of mass [{com}] +- [{spread}] m in the flange frame.")  # fmt: skip
        if not self.plausible:
            return (
                f"{head} Not taken off: {'; '.join(self.problems)}, so it more likely takes up an error of the "
                "arm's own (a link, a spring): 'psdm diagnose' names what the model lacks. If the arm did carry a "
                f'load, declare it in a sidecar: {sidecar_path(path).name} {{"mass": M, "com": [x, y, z]}}.'
            )
        done = "Taken off before judging: the RMSE reported is the arm's"
        if left_in is not None:
            done += " (with the load left in: " + "/".join("-" if v is None else f"{v:.3g}" for v in left_in) + " N m)"
        return (f"{head} {done}. Declare it in a sidecar: {self.sidecar()} (or {{\"unknown\": \"tool\"}} to have "
                "identify weigh it).")  # fmt: skip


def judge_load(found: NewPayload) -> UnstatedLoad:
    """The :class:`UnstatedLoad` of a flange fit: the body taken off and the reasons it is not a plausible load
    (module docstring)."""
    x = np.asarray(found.parameters, dtype=float)
    covariance = np.nan_to_num(np.asarray(found.covariance, dtype=float))
    problems = []
    mass, com = x[0], x[1:4] / x[0]
    distance = float(np.linalg.norm(com))
    gradient = np.zeros(10)  # d|c| = (c/|c|) . (dh - c dm) / m
    if distance > 0:
        gradient[0], gradient[1:4] = -distance / mass, com / distance / mass
    if distance - CONSISTENT_SIGMAS * _std(gradient, covariance) > REACH:
        problems.append(f"its centre of mass lies {distance:.2g} m from the flange, beyond the {REACH:g} m a carried "
                        "load reaches")  # fmt: skip
    trace = x[4] + x[6] + x[9]  # tr(I) about the origin = 2 sum m r^2: the mass's RMS distance sqrt(tr / 2m)
    radius = float(np.sqrt(max(trace, 0.0) / (2.0 * mass)))
    gradient = np.zeros(10)
    if radius > 0:
        gradient[[4, 6, 9]] = 1.0 / (4.0 * mass * radius)
        gradient[0] = -trace / (4.0 * mass**2 * radius)
    if radius - CONSISTENT_SIGMAS * _std(gradient, covariance) > REACH:
        problems.append(f"its mass is spread {radius:.2g} m (RMS) from the flange, beyond the {REACH:g} m a carried "
                        "load reaches")  # fmt: skip
    values, vectors = np.linalg.eigh(pseudo_inertia(x))
    unit = np.eye(10)
    gradient = np.array([vectors[:, 0] @ pseudo_inertia(unit[k]) @ vectors[:, 0] for k in range(10)])
    if values[0] < -CONSISTENT_SIGMAS * _std(gradient, covariance):
        problems.append(f"it is no body (its pseudo-inertia's smallest eigenvalue {values[0]:.2g} kg m^2 is negative "
                        f"beyond {CONSISTENT_SIGMAS:g} standard deviations)")  # fmt: skip
    shown = _inertia_shown(x, covariance)
    body = (
        point_mass(mass, com)
        if not shown
        else link_from_pseudo_inertia(vectors @ np.diag(np.clip(values, 0.0, None)) @ vectors.T)
    )
    return UnstatedLoad(found, tuple(float(v) for v in body), tuple(problems), shown)


def point_mass(mass, com) -> np.ndarray:
    """The 10 inertial parameters about the flange origin of a point mass at ``com``."""
    h = mass * np.asarray(com, dtype=float)
    inertia = mass * (np.dot(com, com) * np.eye(3) - np.outer(com, com))
    return np.array([mass, *h, inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2],
                     inertia[2, 2]])  # fmt: skip


def _inertia_shown(x, covariance) -> bool:
    """Whether the fit shows the load's rotational inertia about its centre of mass: its six components (the fitted
    inertia less a point mass's at the fitted centre) beyond their uncertainty, chi-square at ``P_INERTIA``. The
    flange body's inertia columns are nearly those of the wrist links and rotors, so a model's error there moves
    them: on a virtual cobot a 2 kg point mass read 0.06 kg m^2 about x (chi-square 5.8 of 6 degrees of freedom)."""
    about_com = x[4:] - point_mass(x[0], x[1:4] / x[0])[4:]
    block = covariance[4:, 4:]
    if not np.any(block):
        return False
    return bool(about_com @ np.linalg.pinv(block, hermitian=True) @ about_com > chi2.isf(P_INERTIA, 6))


def _std(gradient, covariance) -> float:
    return float(np.sqrt(max(gradient @ covariance @ gradient, 0.0)))


@dataclass(frozen=True)
class LoadCheck:
    """A calibrated model judged on a raw recording that states no load (:func:`find_unstated_load`): per joint RMSE
    and R^2, the prepared recording and the prediction (with a plausible load: the arm's, the load's torque added to
    the prediction), the load found (or None) and the RMSE with the load left in."""

    rmse: np.ndarray
    r2: np.ndarray
    prepared: object
    predicted: np.ndarray
    load: UnstatedLoad | None
    rmse_left_in: np.ndarray

    @property
    def taken_off(self) -> bool:
        return self.load is not None and self.load.plausible


def find_unstated_load(robot, calibrated, model, recording, kt=None, name=None) -> LoadCheck:
    """The :class:`LoadCheck` of a calibrated model on a raw recording that states no load, as ``psdm validate``
    judges it: the flange fit on the model's residual (the model's own estimation error allowed for,
    ``payload_check.model_columns``) and its judgement; a plausible load taken off as
    ``payload_check.validation_with_payload`` takes a stated one."""
    error, r2, prepared, predicted = validation_with_payload(robot, calibrated, model, recording, kt)
    found = new_payload(robot, prepared, predicted, name, model_columns(calibrated, model, prepared))
    load = None if found is None else judge_load(found)
    if load is None or not load.plausible:
        return LoadCheck(error, r2, prepared, predicted, load, error)
    arm, r2, prepared, predicted = validation_with_payload(robot, calibrated, model, recording, kt, load.body)
    return LoadCheck(arm, r2, prepared, predicted, load, error)


def judge_recording(robot, calibrated, model, recording, kt=None, stated=None, name=None) -> LoadCheck:
    """The :class:`LoadCheck` of a calibrated model on a raw recording as ``psdm validate`` judges it: with a stated
    load (``stated``: its 10 inertial parameters, ``payload_fit.stated_payload``) that load's torque added to the
    prediction (``load`` None: nothing beyond it is looked for here), else :func:`find_unstated_load`."""
    if stated is None:
        return find_unstated_load(robot, calibrated, model, recording, kt, name)
    error, r2, prepared, predicted = validation_with_payload(robot, calibrated, model, recording, kt, stated)
    return LoadCheck(error, r2, prepared, predicted, None, error)
