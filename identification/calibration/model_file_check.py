"""The checks a calibrated-model file passes when it is read (``calibrated_model.load_calibrated_model``).

Every command that reads a model (validate, codegen, export-urdf, diagnose, simulate) must compute from the
same numbers, and those numbers must be what the file claims. A file edited by hand or truncated is refused
with the file, the field (``base.values[3]``) and the fix, never used:

- :func:`check_document` (no model needed): every numeric field parses as finite numbers of the right length
  (standard deviations may be null), the flags are JSON booleans, the drive names and values match one to
  one, the robot texts match ``robot.sha256``, and the held-out parts (``identification.holdout``) parse;
- :func:`check_against_model` (the model derived from the file's robot): the base parameters are the model's
  base parameters of the standard block (relative to the largest, within :data:`BASE_TOLERANCE`), and a file
  that claims ``consistent`` passes the consistency check again on its standard block (every link the data
  sees has a positive-definite pseudo-inertia, every drive inertia is >= 0).

A file that says it is not consistent is taken at its word (it is then refused or marked by each command).
"""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np

from identification.calibration.coulomb_width import file_coulomb_widths
from identification.calibration.merged_rotors import merged_rotor_map
from identification.calibration.model_preparation import PREPARATION_VERSION
from identification.calibration.parameter_covariance import check_covariance_block
from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT, pseudo_inertia_eigenvalues
from identification.calibration.trajectory_data import drive_column_names
from identification.data.holdout import stored_parts
from psdm_casadi.errors import ModelFileError
from psdm_casadi.oracle import LINK_PARAMETER_NAMES

__all__ = ["BASE_TOLERANCE", "FIX", "check_against_model", "check_document", "free_links", "robot_digest"]

#: Largest difference between the file's base parameters and those of its standard block, relative to the
#: largest of them: the writer stores one as the image of the other, so only an edit exceeds it.
BASE_TOLERANCE = 1e-9
FIX = "Re-identify, or restore the file"
FRICTION_TERMS = ("fc", "fs", "fv", "offset", "Ia")
OPTIONAL_NUMBERS = ("ols", "std", "relative_sigma_percent")  # may be null where the estimate has no value


def _refuse(name: str, field: str, constraint: str, got) -> ModelFileError:
    return ModelFileError(f"{name}: {field} must be {constraint}; got {got}. {FIX} ('psdm identify' writes it).")


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _check_preparation(name: str, preparation) -> None:
    """``identification.preparation`` (absent from older files: their cutoff is used): positive cutoff and grid rate,
    a version this reader knows and, from version 2, the filter periods trimmed at each end (``edge_periods``)."""
    if preparation is None:
        return
    rates = [preparation.get(k) if isinstance(preparation, dict) else None for k in ("cutoff_hz", "grid_rate_hz")]
    if not all(_is_number(v) and v > 0 for v in rates):
        raise _refuse(name, "identification.preparation", "an object with positive cutoff_hz and grid_rate_hz [Hz]",
                      repr(preparation)[:80])  # fmt: skip
    version = preparation.get("version", 1)
    if not (isinstance(version, int) and not isinstance(version, bool) and 1 <= version <= PREPARATION_VERSION):
        raise ModelFileError(
            f"{name}: identification.preparation.version must be 1..{PREPARATION_VERSION}; got {version!r}. Re-run "
            "'psdm identify' with this version of psdm-casadi, or use the version that wrote the file."
        )
    edge = preparation.get("edge_periods")
    if version >= 2 and not (_is_number(edge) and math.isfinite(edge) and edge >= 0):
        raise _refuse(name, "identification.preparation.edge_periods", "a number >= 0 (filter periods)", repr(edge))


def _numbers(name: str, block: dict, key: str, path: str, length=None, *, nullable=False) -> list:
    """The list ``block[key]`` as floats: finite numbers (or null when ``nullable``) of ``length`` entries."""
    values = block.get(key)
    if not isinstance(values, list):
        raise _refuse(name, f"{path}.{key}", "a list of numbers", repr(values)[:80])
    if length is not None and len(values) != length:
        raise _refuse(name, f"{path}.{key}", f"{length} numbers", f"{len(values)}")
    for k, value in enumerate(values):
        if value is None and nullable:
            continue
        if not _is_number(value) or not math.isfinite(value):
            wanted = "a finite number" + (" or null" if nullable else "")
            raise _refuse(name, f"{path}.{key}[{k}]", wanted, repr(value))
    return [None if v is None else float(v) for v in values]


def _strings(name: str, block: dict, key: str, path: str) -> list:
    values = block.get(key)
    if not isinstance(values, list) or not all(isinstance(v, str) for v in values):
        raise _refuse(name, f"{path}.{key}", "a list of strings", repr(values)[:80])
    return values


def _flag(name: str, block: dict, key: str, path: str, default=None) -> bool:
    value = block.get(key, default)
    if not isinstance(value, bool):
        raise _refuse(name, f"{path}.{key}", "true or false (a JSON boolean)", repr(value))
    return value


def robot_digest(files: dict) -> str:
    """The SHA-256 the writer stores for the robot texts (``robot.sha256``)."""
    return hashlib.sha256(json.dumps(files, sort_keys=True).encode()).hexdigest()


def _check_robot(name: str, block: dict) -> int:
    """The robot block (texts, hash, joints); returns n_dof."""
    if not isinstance(block, dict):
        raise _refuse(name, "robot", "an object", type(block).__name__)
    joints = _strings(name, block, "joint_names", "robot")
    if not joints:
        raise _refuse(name, "robot.joint_names", "at least one joint name", "[]")
    files = block.get("files")
    if not isinstance(files, dict) or not all(isinstance(v, str) for v in files.values()):
        raise _refuse(name, "robot.files", "an object of file name -> text", repr(files)[:80])
    if block.get("main_file") not in files:
        raise _refuse(name, "robot.main_file", f"one of robot.files {list(files)}", repr(block.get("main_file")))
    digest = robot_digest(files)
    if block.get("sha256") != digest:
        raise ModelFileError(
            f"{name}: robot.sha256 must be the SHA-256 of the robot texts in robot.files ({digest}); got "
            f"{block.get('sha256')!r}: the robot text or its hash was edited, and the kinematics would not be the "
            f"ones the model was identified for. {FIX}."
        )
    return len(joints)


def _check_standard(name: str, block: dict, n_dof: int) -> None:
    """The standard block: 11 numbers per link (all null for a base-parameters-only model) and its flags."""
    consistent = _flag(name, block, "consistent", "standard")
    checked = _flag(name, block, "checked", "standard", default=True)
    values = block.get("values")
    count = n_dof * (LINK_PARAMETER_COUNT + 1)
    if not checked and isinstance(values, list) and len(values) == count and all(v is None for v in values):
        if consistent:
            raise _refuse(name, "standard.consistent", "false for a model not checked (standard.checked false)",
                          "true")  # fmt: skip
        return
    _numbers(name, block, "values", "standard", count)
    eigenvalue = block.get("min_pseudo_inertia_eigenvalue")
    if eigenvalue is not None and not _is_number(eigenvalue):
        raise _refuse(name, "standard.min_pseudo_inertia_eigenvalue", "a number or null", repr(eigenvalue))


def _check_base(name: str, block: dict) -> None:
    names = _strings(name, block, "names", "base")
    _numbers(name, block, "values", "base", len(names))
    for key in OPTIONAL_NUMBERS:
        if key in block:
            _numbers(name, block, key, "base", len(names), nullable=True)


def _check_column_choice(name, choice, n_dof) -> None:
    """``identification.column_choice`` (optional; ``column_choice.ColumnChoice.to_dict``): its joints are 1..n."""
    if choice is None:
        return
    joints = [choice.get(key) for key in ("offset_joints", "inertia_joints")] if isinstance(choice, dict) else [None]
    if not all(isinstance(j, list) and all(isinstance(k, int) and 1 <= k <= n_dof for k in j) for j in joints):
        expected = f"offset_joints and inertia_joints: joint numbers 1..{n_dof}"
        raise _refuse(name, "identification.column_choice", expected, repr(choice)[:80])


def _check_drive(name: str, block: dict, n_dof: int) -> None:
    """The drive block: names and values one to one, as the friction terms and drive-inertia joints say."""
    names = _strings(name, block, "names", "drive")
    values = _numbers(name, block, "values", "drive")
    if len(values) != len(names):
        raise _refuse(name, "drive.values", f"{len(names)} numbers, one per drive.names {names}", len(values))
    for key in OPTIONAL_NUMBERS:
        if key in block:
            _numbers(name, block, key, "drive", len(names), nullable=True)
    terms = _strings(name, block, "friction_terms", "drive")
    unknown = [t for t in terms if t not in FRICTION_TERMS]
    if unknown:
        raise _refuse(name, "drive.friction_terms", f"terms of {list(FRICTION_TERMS)}", unknown)
    joints = block.get("inertia_joints", [])
    if not isinstance(joints, list) or not all(type(j) is int and 1 <= j <= n_dof for j in joints):
        raise _refuse(name, "drive.inertia_joints", f"a list of joint numbers 1..{n_dof}", repr(joints))
    expected = drive_column_names(n_dof, tuple(terms), [j - 1 for j in joints])
    if names != expected:
        raise _refuse(name, "drive.names", f"{expected} (from friction_terms and inertia_joints)", names)
    if "fc" in terms and block.get("coulomb_velocity") is None:
        raise _refuse(name, "drive.coulomb_velocity", "a positive number [rad/s] or one per joint", "none")
    file_coulomb_widths(block, n_dof, name)  # one positive width, or one per joint
    if "fs" in terms:
        vs = _numbers(name, block, "stribeck_velocity", "drive", n_dof)
        if min(vs) < 0 or max(vs) <= 0:
            raise _refuse(name, "drive.stribeck_velocity", f"{n_dof} numbers >= 0 [rad/s], one positive (0: a "
                          "Coulomb-viscous joint, no Stribeck hump)", vs)  # fmt: skip
    if block.get("viscous_exponent"):
        dv = _numbers(name, block, "viscous_exponent", "drive", n_dof)
        if min(dv) <= 0:
            raise _refuse(name, "drive.viscous_exponent", f"{n_dof} numbers > 0 (1: linear viscous friction)", dv)
    lugre = block.get("lugre")
    if lugre:
        from identification.friction.models import LUGRE_PARAMETER_NAMES

        shapes = block.get("friction_shapes") or ["lugre"] * n_dof  # a mixed model: null on a steady-state joint
        joints = [j for j in range(n_dof) if j >= len(shapes) or shapes[j] == "lugre"]
        for key in LUGRE_PARAMETER_NAMES:
            values = _numbers(name, lugre, key, "drive.lugre", n_dof, nullable=True)
            if [j for j, v in enumerate(values) if v is not None] != joints:
                raise _refuse(name, f"drive.lugre.{key}", f"a number on each joint drive.friction_shapes names "
                              f"'lugre' ({[j + 1 for j in joints]}) and null on the others", values)  # fmt: skip


def check_document(document: dict, name: str) -> None:
    """Refuse a calibrated-model document whose fields do not parse (module docstring, first list).

    Parameters
    ----------
    document : dict
        The parsed JSON of a file of format ``psdm-calibrated-model`` with its five blocks.
    name : str
        The file's name, for the messages.
    robot : RobotDescription, optional
        ``calibrated.load_robot()`` (loaded here when a drive inertia outside the model's map needs it).

    Raises
    ------
    ModelFileError
        Naming the file, the field (``base.values[3]``) and the fix.
    """
    n_dof = _check_robot(name, document["robot"])
    for key in ("standard", "base", "drive", "identification"):
        if not isinstance(document[key], dict):
            raise _refuse(name, key, "an object", type(document[key]).__name__)
    _check_standard(name, document["standard"], n_dof)
    _check_base(name, document["base"])
    _check_drive(name, document["drive"], n_dof)
    cutoff = _numbers(name, document["identification"], "cutoff_hz", "identification")
    if not cutoff or min(cutoff) <= 0:
        raise _refuse(name, "identification.cutoff_hz", "positive numbers [Hz]", cutoff)
    _check_preparation(name, document["identification"].get("preparation"))
    _check_column_choice(name, document["identification"].get("column_choice"), n_dof)
    stored_parts(document, name)  # identification.holdout (optional): every held-out part parses
    findings = document.get("findings", [])
    if not isinstance(findings, list) or not all(isinstance(e, dict) for e in findings):
        raise _refuse(name, "findings", "a list of objects", repr(findings)[:80])
    _check_configurations(name, document.get("configurations"))
    check_covariance_block(name, document)
    warnings = document.get("warnings") if document.get("warnings") is not None else []  # null: none stored
    if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
        raise _refuse(name, "warnings", "a list of strings (the warnings of 'psdm identify')", repr(warnings)[:80])


def free_links(model) -> list:
    """The links (0-based) whose inertial parameters enter the base parameters: the links the data sees."""
    width = LINK_PARAMETER_COUNT + 1
    return [
        i for i in range(model.n_dof) if np.any(model.parameter_map[:, i * width : i * width + LINK_PARAMETER_COUNT])
    ]


def check_against_model(calibrated, model, name: str, robot=None) -> None:
    """Refuse a model whose base and standard blocks disagree, or that claims a consistency it lacks.

    Parameters
    ----------
    calibrated : CalibratedModel
        A document that passed :func:`check_document`.
    model : PSDMModel
        ``derive_psdm(calibrated.load_robot())``.
    name : str
        The file's name, for the messages.

    Raises
    ------
    ModelFileError
        Naming the file, the field and the fix.
    """
    theta = calibrated.theta
    if theta.size != model.n_base:
        raise _refuse(name, "base.values", f"{model.n_base} numbers (the base parameters of the model of "
                      f"{calibrated.document['robot'].get('name')!r})", theta.size)  # fmt: skip
    standard = calibrated.standard
    if not np.all(np.isfinite(standard)):
        return  # a base-parameters-only model (identified with --no-consistency): nothing to compare
    if calibrated.document["standard"]["consistent"]:
        _check_consistency_claim(name, standard, model)
    expected = model.base_parameters(standard) + _merged_rotor_share(calibrated, model, standard, robot)
    error = np.abs(theta - expected)
    scale = max(float(np.max(np.abs(expected))), np.finfo(float).tiny)
    if float(np.max(error)) > BASE_TOLERANCE * scale:
        k = int(np.argmax(error))
        raise ModelFileError(
            f"{name}: base.values[{k}] (theta{k + 1}) must be the base parameter of the standard block "
            f"(standard.values), {float(expected[k])!r}; got {float(theta[k])!r} (base and standard parameters "
            f"disagree by {error[k] / scale:.3g} of the largest base parameter: one of them was edited, or the file "
            f"was written for another model of its robot). {FIX}."
        )


def _merged_rotor_share(calibrated, model, standard, robot):
    """The base parameters' share of the drive inertias outside both the model's map and the drive columns: those
    the fit held inside the base parameters (``merged_rotors``, motor currents)."""
    names = set(calibrated.document["drive"]["names"])
    columns = model.parameter_map[:, LINK_PARAMETER_COUNT :: LINK_PARAMETER_COUNT + 1]
    joints = [j for j in range(model.n_dof) if standard[j, LINK_PARAMETER_COUNT] != 0 and f"Ia{j + 1}" not in names
              and not np.any(columns[:, j])]  # fmt: skip
    if not joints:
        return 0.0
    merged = merged_rotor_map(model, calibrated.load_robot() if robot is None else robot, joints)
    return sum(coefficients * standard[j, LINK_PARAMETER_COUNT] for j, coefficients in merged.items())


def _check_consistency_claim(name: str, standard, model) -> None:
    """``consistent: true`` must survive the check again: positive pseudo-inertias, drive inertias >= 0."""
    links = free_links(model)
    eigen = pseudo_inertia_eigenvalues(standard[links]) if links else np.zeros(0)
    bad = [(links[k], float(e)) for k, e in enumerate(eigen) if not e > 0]
    if bad:
        blamed = "; ".join(
            f"link {i + 1} ({', '.join(f'{n}{i + 1}={standard[i, c]:.6g}' for c, n in enumerate(LINK_PARAMETER_NAMES))}"
            f", smallest pseudo-inertia eigenvalue {e:.3g})"
            for i, e in bad
        )
        raise ModelFileError(
            f"{name}: standard.consistent is true, but the standard parameters are not physically consistent: "
            f"{blamed}. {FIX} (a model written with --allow-inconsistent says consistent: false)."
        )
    negative = [j for j in range(standard.shape[0]) if standard[j, LINK_PARAMETER_COUNT] < 0]
    if negative:
        listed = ", ".join(f"Ia{j + 1}={standard[j, LINK_PARAMETER_COUNT]:.6g}" for j in negative)
        raise ModelFileError(
            f"{name}: standard.consistent is true, but drive inertias must be >= 0; got {listed} "
            f"(standard.values). {FIX}."
        )


def _check_configurations(name: str, configurations) -> None:
    """The optional ``configurations`` block: a list of objects with a text name, a kind and their recordings."""
    configurations = [] if configurations is None else configurations
    if not isinstance(configurations, list) or not all(isinstance(e, dict) for e in configurations):
        got = repr(configurations)[:80]
        raise _refuse(name, "configurations", "a list of objects (the payload configurations)", got)
    for k, entry in enumerate(configurations):
        if not isinstance(entry.get("name"), str) or entry.get("kind") not in ("none", "known", "unknown"):
            got = f"name {entry.get('name')!r}, kind {entry.get('kind')!r}"
            raise _refuse(name, f"configurations[{k}]", "a name and a kind among none, known, unknown", got)
        if not isinstance(entry.get("recordings"), list):
            raise _refuse(name, f"configurations[{k}].recordings", "a list of recording names", entry.get("recordings"))
