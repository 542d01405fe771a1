"""build_calibrated_functions(): a calibrated model's full torque as CasADi Functions (calibrated model -> export_c).

A calibrated-model file (``psdm identify --out model.json``) reports the torque
``CalibratedModel.predict``: the rigid body of its base parameters plus the drive terms of each joint j

    tau_j = [D(q) qdd + h(q, qd)]_j + fc_j tanh(qd_j / v) + fv_j qd_j + offset_j + Ia_j qdd_j

(only the terms the file lists; ``Ia_j`` for the joints whose rigid-body model has no drive inertia).
The Functions built here compute exactly that, so the exported C equals what the report shows:

- ``inverse_dynamics`` is the rigid body (recursive or sum form, theta baked in) plus the drive terms;
- ``mass_matrix`` is ``D(q) + diag(Ia)``: the drive inertias multiply qdd, so they belong to the mass matrix;
- ``bias`` is ``h(q, qd)`` plus friction and offsets (everything that does not multiply qdd), and
  ``gravity`` is the torque that holds the robot still at q (``bias(q, 0)``: gravity plus the offsets);
- ``forward_dynamics`` solves ``mass_matrix qdd = tau - bias``, the inverse of ``inverse_dynamics``;
- ``regressor`` and ``gravity_regressor`` stay the rigid body's base-parameter regressor
  (``Y theta`` omits the drive terms);
- ``inverse_dynamics_at_temperature`` (only for a file whose friction has a law in the joints' temperature):
  ``inverse_dynamics`` with a temperature input per joint (``codegen.temperature_friction``).

Every parameter is compiled in: the Functions have no ``theta`` input.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from codegen.calibrated_lugre import lugre_note
from codegen.export import CExport
from codegen.temperature_friction import add_temperature_friction, temperature_note
from identification.calibration.findings import term_values
from identification.calibration.trajectory_data import drive_column_names, friction_term
from psdm_casadi.errors import ModelFileError, ParameterError, ShapeError
from psdm_casadi.symbolic import DynamicsFunctions, assemble_functions

__all__ = [
    "FORMS",
    "add_drive_terms",
    "add_finding_terms",
    "add_header_note",
    "build_calibrated_functions",
    "consistency_problem",
    "corrections_note",
    "drive_bias",
    "drive_inertia",
    "header_note",
    "stribeck_velocity",
    "viscous_exponent",
]

#: The forms of the rigid body: Newton-Euler on the base parameters (fastest) or the paper's sum.
FORMS = ("recursive", "sum")


def consistency_problem(calibrated) -> str | None:
    """None for a physically consistent calibrated model, else one sentence naming the failed check.

    Parameters
    ----------
    calibrated : identification.calibration.calibrated_model.CalibratedModel

    Returns
    -------
    str or None
        Names the smallest pseudo-inertia eigenvalue [kg m^2] (and the smallest mass-matrix
        eigenvalue when the file's validation block holds one), or says that the model was not checked.
    """
    if calibrated.consistent:
        return None
    standard = calibrated.document["standard"]
    if not standard.get("checked", True):
        return (
            "the calibrated model was not checked for physical consistency (identified with --no-consistency: "
            "unconstrained base parameters, its mass matrix may be indefinite)"
        )
    sentence = (
        "the calibrated model is not physically consistent (smallest pseudo-inertia eigenvalue "
        f"{_number(standard.get('min_pseudo_inertia_eigenvalue'))}"
    )
    mass = (calibrated.document.get("validation") or {}).get("min_mass_eigenvalue")
    if mass is not None:
        sentence += f", smallest mass-matrix eigenvalue {_number(mass)}"
    return sentence + ")"


def _number(value) -> str:
    return "unknown" if value is None else f"{float(value):.3g}"


def _drive_block(calibrated) -> tuple[dict, tuple, tuple, np.ndarray]:
    """({name: value}, friction terms, 0-based inertia joints, Coulomb widths per joint) of the file's drive block,
    checked (``coulomb_width.file_coulomb_widths``)."""
    drive = calibrated.document["drive"]
    terms = tuple(drive["friction_terms"])
    inertia_joints = tuple(int(j) - 1 for j in drive["inertia_joints"])
    names = list(drive["names"])
    values = calibrated.drive
    expected = drive_column_names(calibrated.n_dof, terms, inertia_joints)
    if names != expected or values.size != len(names):
        raise ModelFileError(
            f"calibrated model drive.names must be {expected} with one value each (from friction_terms {list(terms)} "
            f"and inertia_joints {list(drive['inertia_joints'])}); got {names} with {values.size} values. "
            "Re-run 'psdm identify'."
        )
    if not np.all(np.isfinite(values)):
        raise ModelFileError(
            f"calibrated model drive.values must be finite; got {dict(zip(names, values.tolist()))}. "
            "Re-run 'psdm identify'."
        )
    return dict(zip(names, values.tolist())), terms, inertia_joints, calibrated.coulomb_widths


def drive_bias(calibrated, qd):
    """Friction and offsets of the calibrated model's drives, ``fc tanh(qd / v) + fv qd + offset``, per joint.

    Parameters
    ----------
    calibrated : CalibratedModel
    qd : casadi.SX, shape (n_dof, 1)
        Joint velocities [rad/s or m/s].

    Returns
    -------
    casadi.SX, shape (n_dof, 1)
        [N m or N]; the same terms as ``identification.calibration.trajectory_data.drive_columns``.
    """
    values, terms, _, widths = _drive_block(calibrated)
    stribeck, exponent = stribeck_velocity(calibrated), viscous_exponent(calibrated)
    entries = []
    for j in range(calibrated.n_dof):
        entry = ca.SX(0)
        vs, dv = None if stribeck is None else float(stribeck[j]), None if exponent is None else float(exponent[j])
        for term in terms:
            if term != "Ia":
                entry = entry + values[f"{term}{j + 1}"] * friction_term(term, qd[j], float(widths[j]), vs, dv)
        entries.append(entry)
    return ca.vertcat(*entries)


def viscous_exponent(calibrated) -> np.ndarray | None:
    """The viscous exponents per joint of a model with a viscous power law (``drive.viscous_exponent``), else None."""
    dv = calibrated.document["drive"].get("viscous_exponent")
    if not dv:
        return None
    out = np.array([np.nan if v is None else v for v in dv], dtype=float)
    if out.shape != (calibrated.n_dof,) or not np.all(np.isfinite(out) & (out > 0)):
        raise ModelFileError(f"calibrated model drive.viscous_exponent must be {calibrated.n_dof} numbers > 0 (1: "
                             f"linear viscous friction); got {dv!r}. Re-run 'psdm identify'.")  # fmt: skip
    return out


def stribeck_velocity(calibrated) -> np.ndarray | None:
    """The Stribeck velocities [rad/s] per joint of a Stribeck-shaped model (``fs`` terms), else None."""
    drive = calibrated.document["drive"]
    if "fs" not in drive["friction_terms"]:
        return None
    vs = np.array([np.nan if v is None else v for v in drive.get("stribeck_velocity") or []], dtype=float)
    if vs.shape != (calibrated.n_dof,) or not np.all(np.isfinite(vs) & (vs >= 0)):
        raise ModelFileError(
            f"calibrated model drive.stribeck_velocity must be {calibrated.n_dof} numbers >= 0 [rad/s] (the "
            f"friction terms hold 'fs'); got {drive.get('stribeck_velocity')!r}. Re-run 'psdm identify'."
        )
    return vs


def drive_inertia(calibrated) -> np.ndarray:
    """Drive inertias ``Ia_j`` [kg m^2] the file lists outside the base parameters, per joint (0 elsewhere)."""
    values, _, inertia_joints, _ = _drive_block(calibrated)
    inertia = np.zeros(calibrated.n_dof)
    for j in inertia_joints:
        inertia[j] = values[f"Ia{j + 1}"]
    return inertia


def add_drive_terms(rigid: DynamicsFunctions, calibrated) -> DynamicsFunctions:
    """The Functions of ``rigid`` (theta baked in) with the calibrated model's drive terms added (module docstring).

    Raises
    ------
    ParameterError
        When ``rigid`` still has a ``theta`` input (build it with numeric theta).
    ShapeError
        When ``rigid`` and ``calibrated`` have different numbers of joints.
    """
    if rigid.theta is None:
        raise ParameterError(
            "add_drive_terms rigid must have its base parameters compiled in; got Functions with a theta input. "
            "Build them with theta=calibrated.theta."
        )
    if rigid.n_dof != calibrated.n_dof:
        raise ShapeError(
            f"add_drive_terms rigid.n_dof must be the calibrated model's n_dof={calibrated.n_dof}; got {rigid.n_dof}. "
            "Build the Functions of the robot in the file (calibrated.load_robot())."
        )
    n = rigid.n_dof
    q, qd, qdd, tau_in = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd", "tau"))
    friction = drive_bias(calibrated, qd)
    offsets = drive_bias(calibrated, ca.SX.zeros(n, 1))
    inertia = drive_inertia(calibrated)
    rigid_mass = rigid.mass_matrix(q)
    columns = [rigid_mass[:, k] + (ca.DM(np.eye(n)[k] * inertia[k]) if inertia[k] else 0) for k in range(n)]
    inertia_torque = ca.vertcat(*[inertia[j] * qdd[j] if inertia[j] else ca.SX(0) for j in range(n)])
    functions = assemble_functions(
        (q, qd, qdd, tau_in),
        [],
        [],
        regressor=rigid.regressor(q, qd, qdd),
        gravity_regressor=rigid.gravity_regressor(q),
        tau=rigid.inverse_dynamics(q, qd, qdd) + friction + inertia_torque,
        bias=rigid.bias(q, qd) + friction,
        gravity=rigid.gravity(q) + offsets,
        mass_columns=columns,
        theta=rigid.theta,
    )
    return dataclasses.replace(functions, regressor_structure=rigid.regressor_structure)


def build_calibrated_functions(
    calibrated, model, robot, *, form: str = "recursive", allow_inconsistent: bool = False
) -> DynamicsFunctions:
    """The CasADi Functions of a calibrated model's full torque: rigid body plus drive terms, all compiled in.

    Parameters
    ----------
    calibrated : identification.calibration.calibrated_model.CalibratedModel
        From ``load_calibrated_model("model.json")``.
    model : PSDMModel
        The model of the file's robot (``derive_psdm(calibrated.load_robot())``).
    robot : RobotDescription
        ``calibrated.load_robot()``; the recursive form needs its kinematics.
    form : {"recursive", "sum"}
        The rigid body by Newton-Euler on the base parameters (fastest) or as the paper's sum.
    allow_inconsistent : bool
        Build the Functions of a model that is not physically consistent (or was not checked).

    Returns
    -------
    DynamicsFunctions
        Without ``theta`` input; ``theta`` holds the compiled-in base parameters. ``regressor`` is the
        rigid body's.

    Raises
    ------
    ParameterError
        For an inconsistent model without ``allow_inconsistent`` (the message names the eigenvalue),
        or an unknown ``form``.
    ShapeError
        When the file's base parameters do not match the model's n_base.
    ModelFileError
        When the file's drive block is malformed.

    Examples
    --------
    >>> calibrated = load_calibrated_model("model.json")                      # doctest: +SKIP
    >>> robot = calibrated.load_robot(); model = derive_psdm(robot)           # doctest: +SKIP
    >>> fns = build_calibrated_functions(calibrated, model, robot)            # doctest: +SKIP
    >>> fns.inverse_dynamics(q, qd, qdd)   # == calibrated.predict(model, q, qd, qdd)  # doctest: +SKIP
    """
    from psdm_casadi.recursive import build_recursive_functions
    from psdm_casadi.symbolic import build_functions

    if form not in FORMS:
        raise ParameterError(f"build_calibrated_functions form must be one of {FORMS}; got {form!r}.")
    problem = consistency_problem(calibrated)
    if problem is not None and not allow_inconsistent:
        raise ParameterError(f"build_calibrated_functions: {problem}. Pass allow_inconsistent=True to build it anyway.")
    theta = calibrated.theta
    if theta.size != model.n_base or not np.all(np.isfinite(theta)):
        raise ShapeError(
            f"calibrated model base.values must be {model.n_base} finite numbers (the model's n_base); got "
            f"{theta.size} values. Pass the model derived from the file's robot (derive_psdm(calibrated.load_robot()))."
        )
    rigid = build_recursive_functions(model, robot, theta) if form == "recursive" else build_functions(model, theta)
    functions = add_finding_terms(add_drive_terms(rigid, calibrated), calibrated)
    return add_temperature_friction(functions, calibrated, stribeck_velocity(calibrated), viscous_exponent(calibrated))


def _finding_torques(calibrated, q, qd, qdd):
    """(torque of the findings without load dependence, [(joint, mu, smooth sign)] of the load-dependent ones)."""
    n = calibrated.n_dof
    extra, load = ca.SX.zeros(n, 1), []
    for term, values in calibrated.torque_findings:
        if term.load_dependent:
            load.append((term.joint, float(values[0]), ca.tanh(qd[term.joint] / term.velocity)))
            continue
        torque = sum(float(c) * v for c, v in zip(values, term_values(term, q, qd, qdd)) if c != 0.0)
        extra[term.joint] = extra[term.joint] + torque
    return extra, load


def add_finding_terms(functions: DynamicsFunctions, calibrated) -> DynamicsFunctions:
    """The Functions with the calibrated model's torque-type findings added (``CalibratedModel.predict``).

    The findings' torque joins ``inverse_dynamics``; its acceleration part (a rotor inertia, a coupling's
    ``qdd_k``) joins ``mass_matrix`` (which a coupling makes non-symmetric); ``bias`` is
    ``inverse_dynamics(q, qd, 0)`` and ``gravity`` ``inverse_dynamics(q, 0, 0)``. A load-dependent friction
    ``mu |tau_b| tanh(qd / v)`` is inverted exactly in ``forward_dynamics``: ``tau = tau_b (1 + mu s sign(tau_b))``
    with ``|mu s| < 1`` gives ``tau_b = tau / (1 + mu s sign(tau))``, then ``mass_matrix qdd = tau_b - bias_b``.
    Without torque findings the Functions are returned unchanged.
    """
    if not calibrated.torque_findings:
        return functions
    n = functions.n_dof
    q, qd, qdd, tau_in = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd", "tau"))
    extra, load = _finding_torques(calibrated, q, qd, qdd)
    tau_b = functions.inverse_dynamics(q, qd, qdd) + extra
    factor = ca.SX.ones(n, 1)  # tau = tau_b * factor(sign tau_b), per joint
    factor_tau = ca.SX.ones(n, 1)
    for j, mu, sign in load:
        factor[j] += mu * sign * ca.sign(tau_b[j])
        factor_tau[j] += mu * sign * ca.sign(tau_in[j])
    tau = tau_b * factor
    zero = ca.SX.zeros(n, 1)
    mass = functions.mass_matrix(q) + ca.jacobian(extra, qdd)
    bias_b = ca.substitute(tau_b, qdd, zero)
    bias = ca.substitute(tau, qdd, zero)
    gravity = ca.substitute(bias, qd, zero)
    forward = ca.solve(mass, tau_in / factor_tau - bias_b)

    def function(name, inputs, names, output, output_name):
        return ca.Function(name, inputs, [output], names, [output_name], {"cse": True})

    return dataclasses.replace(
        functions,
        inverse_dynamics=function("inverse_dynamics", [q, qd, qdd], ["q", "qd", "qdd"], tau, "tau"),
        mass_matrix=function("mass_matrix", [q], ["q"], mass, "D"),
        bias=function("bias", [q, qd], ["q", "qd"], bias, "h"),
        gravity=function("gravity", [q], ["q"], gravity, "G"),
        forward_dynamics=function("forward_dynamics", [q, qd, tau_in], ["q", "qd", "tau"], forward, "qdd"),
    )


def header_note(calibrated, *, prefix: str = "psdm_", source_name: str | None = None) -> str:
    """The C comment that says what an export of a calibrated model computes (see ``add_header_note``)."""
    document = calibrated.document
    values, terms, inertia_joints, widths = _drive_block(calibrated)
    velocity = repr(float(widths[0])) if np.all(widths == widths[0]) else "v_j"  # v_j: listed under the parameters
    per_joint = " + ".join(_term_text(term, velocity) for term in terms) or "none"
    stribeck, exponent = stribeck_velocity(calibrated), viscous_exponent(calibrated)
    if exponent is not None:
        per_joint = per_joint.replace("fv_j qd_j", f"fv_j qd_j (qd_j^2 + {velocity}^2)^((dv_j - 1) / 2)")
    inertia = f" + Ia_j qdd_j (joints {', '.join(str(j + 1) for j in inertia_joints)})" if inertia_joints else ""
    problem = consistency_problem(calibrated)
    state = "physically consistent" if problem is None else f"WARNING: {problem}; exported with --allow-inconsistent"
    origin = f" from {source_name}" if source_name else ""
    lines = [
        f"Calibrated model of {document['robot']['name']}{origin} "
        f"(created {document.get('provenance', {}).get('created', 'unknown')}).",
        f"{state}.",
        f"{prefix}inverse_dynamics(q, qd, qdd) is the full feed-forward torque the calibration reports",
        "(CalibratedModel.predict, 'psdm validate'): the rigid body of the identified base parameters (compiled in)",
        f"plus the drive terms of each joint j: {per_joint}{inertia}.",
        f"{prefix}mass_matrix is D(q){' + diag(Ia)' if inertia else ''}; {prefix}forward_dynamics solves "
        "mass_matrix(q) qdd = tau - h(q, qd) - friction - offsets, the inverse of inverse_dynamics.",
        f"{prefix}regressor is the RIGID BODY's base-parameter regressor only: Y theta omits the drive terms.",
        "Drive parameters:",
    ]
    for j in range(calibrated.n_dof):
        names = [f"{term}{j + 1}" for term in terms] + ([f"Ia{j + 1}"] if j in inertia_joints else [])
        if names:
            vs = [] if stribeck is None else [f"vs{j + 1} = {stribeck[j]:.17g}"]
            if stribeck is not None and stribeck[j] == 0:
                vs = [f"vs{j + 1} = 0 (Coulomb-viscous joint: no Stribeck term)"]
            dv = [] if exponent is None else [f"dv{j + 1} = {exponent[j]:.17g}"]
            v = [] if velocity != "v_j" else [f"v{j + 1} = {widths[j]:.17g}"]
            lines.append("  " + ", ".join([f"{name} = {values[name]:.17g}" for name in names] + vs + dv + v))
    lines += lugre_note(calibrated, prefix) + _findings_lines(calibrated) + corrections_note(calibrated, prefix)
    lines += temperature_note(calibrated, prefix)
    lines = [line.replace("*/", "* /") for line in _warning_lines(calibrated) + lines]  # free text: no comment end
    return "/* " + "\n * ".join(_wrap(lines)) + "\n */\n"


def _warning_lines(calibrated) -> list:
    """The warnings of the fit stored in the model file (``trajectory_checks.fit_warnings``), first."""
    warnings = calibrated.document.get("warnings") or []
    if not warnings:
        return []
    return [
        "WARNINGS of the identification (stored in the model file; check the recordings before using this code):"
    ] + [f"  - {w}" for w in warnings]


def _correction_text(entry: dict) -> str:
    """One correction in the words of ``findings.correct_recording`` (numbers as the file holds them)."""
    effect, j = entry.get("effect"), entry.get("joint")
    if effect == "delay":
        return f"torque delay d = delay_s = {float(entry['delay_s'])!r} s: the recorded torque lags the positions by d"
    if effect == "joint_elasticity":
        c = float(entry["compliance_rad_per_Nm"])
        return f"joint {j} elasticity: q{j} = q_rec{j} - c tau_rec{j}, c = compliance_rad_per_Nm = {c!r} rad/(N m)"
    if effect == "backlash":
        b, scale = float(entry["backlash_rad"]), float(entry["torque_scale_Nm"])
        return (
            f"joint {j} backlash: q{j} = q_rec{j} - (b / 2) tanh(tau_rec{j} / s), b = backlash_rad = {b!r} rad, "
            f"s = torque_scale_Nm = {scale!r} N m"
        )
    return f"{effect}: {entry}"


def corrections_note(calibrated, prefix: str = "psdm_") -> list:
    """Header lines for a model with measurement corrections (empty without): what to feed the compiled functions.

    The model was fitted on corrected signals (``findings.correct_recording``): link-side positions, and the
    torque advanced by the delay. No exported function applies the corrections, so the header says which
    signals the functions expect, the way ``CalibratedModel.predict_recording`` feeds them.
    """
    corrections = calibrated.corrections
    if not corrections:
        return []
    entries = [dict(v, effect=v.get("effect", k)) for k, v in corrections.items()]
    step = f" and {prefix}lugre_step (its qd_prev and qd)" if calibrated.lugre_parameters is not None else ""
    lines = [
        "MEASUREMENT CORRECTIONS (signal findings; tau_rec is the recorded joint torque, or kt times the current):"
    ]
    lines += [f"  {_correction_text(e)}" for e in entries]
    text = "No function of this code applies them; the model was fitted on the corrected signals."
    if any(e["effect"] != "delay" for e in entries):
        text += (
            f" Feed {prefix}inverse_dynamics{step} the corrected positions q above and their velocities and "
            "accelerations (the derivatives of the corrected q), not the raw encoder values."
        )
    if any(e["effect"] == "delay" for e in entries):
        text += " Compare its torque with the recorded torque advanced by d, tau_rec(t + d)."
    text += (
        " CalibratedModel.predict_recording does so (identification.calibration.findings.correct_recording corrects "
        "a recording in Python)."
    )
    return lines + [text]


def _findings_lines(calibrated) -> list:
    """Header lines naming the findings: the torque terms compiled in, the others and why they are not."""
    entries = calibrated.document.get("findings") or []
    if not entries:
        return []
    lines = ["Findings of the diagnosis (psdm diagnose MODEL --apply), part of inverse_dynamics when torque-type:"]
    for entry in entries:
        if entry["kind"] == "torque":
            pairs = zip(entry["feature_names"], entry["coefficients"])
            text = ", ".join(f"{n} = {'absorbed' if c is None else format(c, '.17g')}" for n, c in pairs)
            lines.append(f"  {entry['label']}: {text}")
        else:
            lines.append(f"  {entry['label']} ({entry['kind']}): not in this code; {entry.get('applied', '')}")
    return lines


def _term_text(term: str, velocity: str) -> str:
    stribeck = f"exp(-(qd_j / vs_j)^2) tanh(qd_j / {velocity})"
    return {"fc": f"fc_j tanh(qd_j / {velocity})", "fv": "fv_j qd_j", "offset": "offset_j",
            "fs": f"(fs_j - fc_j) {stribeck}"}[term]  # fmt: skip


def _wrap(lines: list, width: int = 110) -> list:
    out = []
    for line in lines:
        words, current = line.split(" "), ""
        for word in words:
            if current and len(current) + 1 + len(word) > width:
                out.append(current)
                current = "  " + word
            else:
                current = f"{current} {word}" if current else word
        out.append(current)
    return out


def add_header_note(export: CExport, note: str) -> None:
    """Put ``note`` (a C comment) at the top of an export's ``.h`` and ``.c`` files."""
    for path in (export.header, export.source):
        path.write_text(note + path.read_text())
