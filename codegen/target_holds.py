"""What each export target can hold of a calibrated model, and what of a model it leaves out (URDF, MJCF).

The one statement the exporters share (``urdf_export``, ``mjcf_export``; the C export, ``calibrated``, holds the
whole torque the model predicts): every target holds the identified inertials; beyond them

=======================  ==========================  ==================================  ==========================
model part               URDF (``urdf_export``)      MJCF (``mjcf_export``)              C (``calibrated``)
=======================  ==========================  ==================================  ==========================
drive inertia ``Ia``     comment (no field)          ``armature``                        ``mass_matrix``
Coulomb ``fc``           ``<dynamics friction>``     ``frictionloss`` (a constraint)     ``fc tanh(qd / v)``
viscous ``fv``           ``<dynamics damping>``      ``damping``                         yes
linear spring finding    comment                     ``stiffness``, ``springref``        yes
gravity                  -z of the root (``world``)  ``<option gravity>``                yes
torque offset            comment                     comment                             yes
Stribeck hump, LuGre     comment (their values)      comment (their values)              yes (LuGre: a step)
other torque findings    comment                     comment                             yes
measurement corrections  comment                     comment                             stated in the header
=======================  ==========================  ==================================  ==========================

The model's Coulomb term is ``fc tanh(qd / v)``. URDF's ``friction`` is read by Pinocchio as that level;
MuJoCo's ``frictionloss`` is a dry-friction constraint whose force is at most ``fc`` in magnitude and opposes
the motion (the same level while sliding, anything within ``[-fc, fc]`` at rest).

``psdm diagnose MODEL --apply`` adds findings to a model: torque-type terms (a spring, a ripple, a coupling, ...)
that ``psdm validate`` and the C export add to the rigid-body torque, and measurement corrections (a delay, a
joint elasticity, a backlash) that ``psdm validate`` applies to the recorded signals. The functions here name
each part a target leaves out, with its parameters, for the per-joint comments and the warning the export
command prints. Rigid-body findings (a payload) are part of the standard parameters, and so of the inertials;
findings only reported were never part of the model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.findings import FindingTerm, term_values
from psdm_casadi.values import exact_text

__all__ = [
    "LEFT_OUT_KINDS",
    "MJCF",
    "URDF",
    "ExportTarget",
    "drive_inertias",
    "drive_terms",
    "findings_left_out",
    "findings_not_representable",
    "friction_left_out",
    "friction_not_representable",
    "is_linear_spring",
    "linear_springs",
    "offsets_not_representable",
]

N_LINK = 10  # m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz; the 11th standard parameter is the drive inertia

#: The finding kinds (``findings.FINDING_KINDS``) that change the model's torque or its signals, but not its body.
LEFT_OUT_KINDS = ("torque", "signal")


@dataclass(frozen=True)
class ExportTarget:
    """What one export target holds beyond the inertials (module docstring's table).

    Parameters
    ----------
    name : str
        "URDF" or "MJCF", in messages.
    friction_fields : str
        How it holds Coulomb friction and viscous damping (``friction = fc`` ...), in messages.
    drive_inertia : bool
        Whether it holds the drive inertia (MJCF ``armature``).
    linear_spring : bool
        Whether it holds a linear spring ``k q + c`` (MJCF ``stiffness``, ``springref``).
    """

    name: str
    friction_fields: str
    drive_inertia: bool
    linear_spring: bool

    @property
    def article(self) -> str:
        """ "a" or "an" before the name ("a URDF", "an MJCF")."""
        return "an" if self.name[0] in "AEFHILMNORSX" else "a"


URDF = ExportTarget("URDF", "<dynamics> friction = fc and damping = fv", drive_inertia=False, linear_spring=False)
MJCF = ExportTarget("MJCF", "joint frictionloss = fc and damping = fv", drive_inertia=True, linear_spring=True)


# --- the numbers every target writes -------------------------------------------------------------------------
def drive_terms(calibrated) -> dict:
    """``{"fc": array, "fv": array, "offset": array}`` per joint (zeros for terms the model lacks; a LuGre
    model's fc and fv from its LuGre block)."""
    drive = calibrated.document["drive"]
    values = dict(zip(drive["names"], calibrated.drive))
    n = calibrated.n_dof
    out = {term: np.array([values.get(f"{term}{j + 1}", 0.0) for j in range(n)]) for term in ("fc", "fv", "offset")}
    for j, p in enumerate(calibrated.lugre_parameters or ()):  # a mixed model's steady-state joints: None
        if p is not None:
            out["fc"][j], out["fv"][j] = p.fc, p.fv
    return out


def drive_inertias(calibrated, robot) -> np.ndarray:
    """Drive inertias [kg m^2 or kg] per joint the model predicts with: ``Ia`` where it has one, else 0.

    A joint has a drive inertia in the model when the robot file says so (``drive_inertia``, inside
    the base parameters), when it was identified as a column of its own (``Ia<j>`` of the drive), or when the fit
    held one inside the base parameters (``merged_rotors``: a non-zero drive inertia of the standard block).
    """
    separate = {j - 1 for j in calibrated.document["drive"]["inertia_joints"]}
    held = np.nan_to_num(calibrated.standard[:, N_LINK]) != 0.0
    has = np.array([bool(flag) or j in separate or held[j] for j, flag in enumerate(robot.drive_inertia)])
    return np.where(has, calibrated.standard[:, N_LINK], 0.0)


# --- friction ----------------------------------------------------------------------------------------------
def friction_left_out(calibrated) -> list | None:
    """Per joint, the friction values no target holds (``"fs = .., vs = .."``, LuGre: also sigma0, sigma1)."""
    lugre = calibrated.lugre_parameters
    if lugre is None:
        return _steady_left_out(calibrated)
    steady = _steady_left_out(calibrated) or ["none"] * len(lugre)  # a mixed model's steady-state joints
    names = ("fs", "vs", "sigma0", "sigma1")
    return [steady[j] if p is None else ", ".join(f"{name} = {exact_text(getattr(p, name))}" for name in names)
            for j, p in enumerate(lugre)]  # fmt: skip


def _steady_left_out(calibrated) -> list | None:
    """``friction_left_out`` of the drive columns' steady-state friction (None: Coulomb + viscous on every joint)."""
    drive = calibrated.document["drive"]
    power = drive.get("viscous_exponent") or []  # the viscous power law fv |qd|^dv: a target's damping is linear
    if "fs" not in drive["friction_terms"] and not power:
        return None
    values = dict(zip(drive["names"], calibrated.drive))
    out = [f"fs = {exact_text(values[f'fs{j + 1}'])}, vs = {exact_text(v)}"
           for j, v in enumerate(drive["stribeck_velocity"])] or [""] * len(power)  # fmt: skip
    dv = [f"viscous exponent dv = {exact_text(v)} (damping is fv, the power law's value at 1 rad/s)" if v != 1 else ""
          for v in power] or [""] * len(out)  # fmt: skip
    return ["; ".join(part for part in pair if part) or "none" for pair in zip(out, dv)]


def friction_not_representable(calibrated, target: ExportTarget = URDF) -> str | None:
    """The warning for a model whose friction ``target`` cannot hold (module docstring), or None (Coulomb + viscous)."""
    if friction_left_out(calibrated) is None:
        return None
    lugre = calibrated.lugre_parameters
    joints = [j + 1 for j, p in enumerate(lugre or ()) if p is not None]
    shape = "Stribeck" if lugre is None else "LuGre" if len(joints) == len(lugre) else f"LuGre on joint(s) {joints}"
    dynamics = " and the bristle dynamics (sigma0, sigma1)" if lugre is not None else ""
    if "fs" not in calibrated.document["drive"]["friction_terms"] and lugre is None:
        return (f"the model's viscous friction is a power law fv |qd|^dv on some joints; {target.name} holds only "
                f"linear viscous damping, so {target.friction_fields} are written and the exponent dv is NOT in the "
                f"{target.name} (its value is in a comment on each joint)")  # fmt: skip
    return (
        f"the model's friction is {shape}; {target.name} holds only Coulomb friction and viscous damping, so "
        f"{target.friction_fields} (the sliding level and the viscous slope) are written, and the static hump "
        f"(fs, vs){dynamics} are NOT in the {target.name} (their values are in a comment on each joint)"
    )


def offsets_not_representable(calibrated, target: ExportTarget = URDF) -> str | None:
    """The warning for a model with constant torque offsets, which neither URDF nor MJCF has a field for: their
    values and what to do with them (export-urdf wrote them as comments without a word: Panda offsets of -0.166,
    0.0613 and 0.0737 N m on joints 1, 3 and 6); None without offsets."""
    if "offset" not in calibrated.document["drive"]["friction_terms"]:
        return None
    offsets = drive_terms(calibrated)["offset"]
    named = ", ".join(f"joint {j + 1} {v:.4g}" for j, v in enumerate(offsets) if v != 0.0) or "all zero"
    return (
        f"the model's constant torque offsets ({named} N m) have no {target.name} field; they are in a comment on each "
        f"joint: add them to the torque your simulator or controller applies ('psdm codegen' puts them in the C)"
    )


# --- findings ------------------------------------------------------------------------------------------------
def linear_springs(calibrated) -> dict:
    """``{joint (0-based): (k, c)}`` of the torque findings that are linear springs ``k q_j + c`` [N m/rad, N m].

    A spring finding of order 1 (``findings.term_values`` gives its columns ``q_j, 1``): ``k`` and ``c`` are
    read from its torque at ``q_j = 0`` and ``q_j = 1``, so that they are the model's own numbers. Two springs on
    one joint add up.
    """
    out = {}
    n = calibrated.n_dof
    for term, values in calibrated.torque_findings:
        if not is_linear_spring(term):
            continue
        states = np.zeros((2, n))
        states[1, term.joint] = 1.0
        torque = sum(c * v for c, v in zip(values, term_values(term, states, np.zeros((2, n)), np.zeros((2, n)))))
        k, c = float(torque[1] - torque[0]), float(torque[0])
        previous = out.get(term.joint, (0.0, 0.0))
        out[term.joint] = (previous[0] + k, previous[1] + c)
    return out


def is_linear_spring(term) -> bool:
    """Whether a ``FindingTerm`` is a linear spring ``k q_j + c`` (MJCF ``stiffness``, ``springref``)."""
    return term.effect == "spring" and (term.spec is None or term.candidate.order == 1)


def _left_out_entries(calibrated, target: ExportTarget) -> list:
    entries = [e for e in calibrated.document.get("findings") or [] if e.get("kind") in LEFT_OUT_KINDS]
    if not target.linear_spring:
        return entries
    held = []
    for entry in entries:
        if entry.get("kind") == "torque" and entry.get("effect") == "spring":
            held.append(is_linear_spring(FindingTerm.from_dict(entry.get("term") or {})))
        else:
            held.append(False)
    return [entry for entry, inside in zip(entries, held) if not inside]


def _values_text(entry: dict, number, brief: bool = False) -> str:
    """``name = value`` of a finding's coefficients (torque) and physical parameters; ``brief``: the physical
    parameters alone where it states some (a coupling's were printed twice, as coefficients and as parameters)."""
    pairs = []
    values = (entry.get("parameters") or {}).values()
    physical = any(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
    if entry.get("kind") == "torque" and not (brief and physical):
        for name, value in zip(entry.get("feature_names") or (), entry.get("coefficients") or ()):
            pairs.append(f"{name} = {'absorbed' if value is None else number(value)}")
    for name, value in (entry.get("parameters") or {}).items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            pairs.append(f"{name} = {number(value)}")
    return ", ".join(pairs) or "no parameters"


def _describe(entry: dict, number, target: ExportTarget, brief: bool = False) -> str:
    what = "torque term" if entry.get("kind") == "torque" else "measurement correction"
    return f"{entry.get('label', '?')} ({what}, NOT in the {target.name}): {_values_text(entry, number, brief)}"


def findings_left_out(calibrated, target: ExportTarget = URDF) -> tuple:
    """(per joint (0-based) the comment texts of its findings ``target`` cannot hold, the texts of those on no joint).

    Parameters
    ----------
    calibrated : CalibratedModel
    target : ExportTarget
        :data:`URDF` or :data:`MJCF` (which holds linear springs).

    Returns
    -------
    tuple of (dict, list)
        ``{joint: [text, ...]}`` and ``[text, ...]`` (a delay); both empty for a model without such findings.
    """
    per_joint, general = {}, []
    for entry in _left_out_entries(calibrated, target):
        text = _describe(entry, exact_text, target)
        joints = [int(j) - 1 for j in entry.get("joints") or () if isinstance(j, int) and 1 <= j <= calibrated.n_dof]
        for j in joints:
            per_joint.setdefault(j, []).append(text)
        if not joints:
            general.append(text)
    return per_joint, general


def findings_not_representable(calibrated, target: ExportTarget = URDF) -> str | None:
    """The warning for a model with findings ``target`` cannot hold (module docstring), naming each; else None."""
    entries = _left_out_entries(calibrated, target)
    if not entries:
        return None
    named = "; ".join(_describe(entry, lambda v: f"{float(v):.4g}", target, brief=True) for entry in entries)
    return (
        f"the model has {len(entries)} finding(s) {target.article} {target.name} cannot hold, left out of it (their "
        f"parameters are in the {target.name}'s comments): {named}. The {target.name}'s torque therefore differs from "
        "'psdm validate' and 'psdm codegen' of this model"
    )
