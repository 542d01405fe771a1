"""The calibrated-model file: one versioned JSON document that every command can read.

It holds everything needed to use an identification without the recordings or the checkout:

- ``robot``: the robot file's text (and, for a URDF robot, the URDF's text) with the locked joints,
  so the kinematics are rebuilt exactly (:meth:`CalibratedModel.load_robot`);
- ``standard``: labelled standard parameters per link (``m1, mx1, ..., Izz1, Ia1``), whether they are
  physically consistent and the smallest pseudo-inertia eigenvalue;
- ``base``: the base parameters with their least-squares estimate, standard deviations and relative
  sigma in percent;
- ``drive``: the labelled drive parameters (``fc1, fv1, offset1, ..., Ia<j>``) with their standard
  deviations and the friction model's shape;
- ``identification``: filter, decimation, samples, weights, condition number, solver status, ``preparation``
  (``model_preparation``): how every command prepares a recording, ``column_choice`` (optional): the columns chosen,
  ``holdout`` (optional, any version; older readers ignore it and ask for recordings): the part of each training
  recording ``--holdout`` kept out of the fit (``data.holdout``: path, content hash, cut sample and time);
- ``provenance``: when, which version, which recordings (``recording_provenance``; optional ``columns`` read);
- ``validation``: the report the command printed (per-joint RMSE and R^2 on held-out data);
- ``findings``: the terms diagnosis added (empty until a diagnosis is applied with
  ``psdm diagnose MODEL --apply NEW``): per finding its effect, label, kind (``findings.FINDING_KINDS``),
  joints, the term that rebuilds its columns, feature names, coefficients and standard deviations from the
  joint recalibration, physical parameters and the diagnosis' own numbers;
- ``corrections`` (version 2): the measurement corrections of the ``signal`` findings (a torque delay),
  applied by ``psdm validate`` as by the recalibration (``findings.correct_recording``);
- ``recalibration`` (version 2): the calibration before and after the findings (validation RMSE,
  consistency, the parameters that moved);
- ``configurations`` (optional, any version; absent in older files, read as none): the load each
  recording carried at the flange (``payload_fit.configurations_block``): none, a known payload as
  given, or an unknown one as identified (mass and centre of mass with standard deviations). The
  arm's parameters above are the unloaded arm's; older readers ignore the block and predict the arm;
- ``drive.lugre`` (version 3, ``friction_shape`` ``"lugre"``): the seven LuGre parameters per joint with their
  standard deviations and whether ``sigma0`` was identifiable (``lugre_recordings``); the drive columns then
  hold only the drive inertias and offsets, and the friction is the LuGre model carried along the series
  (``predict`` needs the sample times);
- ``covariance`` (optional, any version; older files: ``std`` alone): the base then drive parameters' covariance;
- ``drive.temperature`` (optional, any version, its own ``version``): the friction's slopes in the joints' logged
  temperature about a reference (``temperature_friction``); older readers predict the friction at the reference.

Version 1 files (no findings) are read as they were. A model without LuGre friction is still written as
version 2 (older readers read it); one with LuGre friction is version 3, which older readers refuse rather
than predict it without its friction. ``drive.coulomb_velocity`` is the Coulomb sign's smoothing width: one number
for every joint, or (version 4, written only when the joints' widths differ; older readers refuse it rather than
misread it) one per joint (``coulomb_width``).

A model whose standard parameters are not consistent is written only when the caller says so
(``allow_inconsistent``), and then says so in ``standard.consistent``.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import tomllib

from identification.calibration.coulomb_width import file_coulomb_widths, file_width
from identification.calibration.findings import FindingTerm, correct_recording, term_values
from identification.calibration.held_friction import drive_inertia_split
from identification.calibration.mixed_friction import file_lugre_joints, friction_drives
from identification.calibration.model_file_check import robot_digest
from identification.calibration.model_preparation import model_preparation, preparation_block
from identification.calibration.parameter_covariance import covariance_block
from identification.calibration.payload_fit import configurations_block
from identification.calibration.temperature_friction import TemperatureFriction
from identification.calibration.trajectory_data import drive_columns, file_shape, friction_shapes, prepare_recording
from identification.calibration.trajectory_fit import TrajectoryFit
from identification.data.temperature import temperatures_at
from psdm_casadi.errors import ModelFileError, ParameterError
from psdm_casadi.fileio import atomic_write
from psdm_casadi.model_cache import robot_cache_folder
from psdm_casadi.near_names import did_you_mean
from psdm_casadi.oracle import LINK_PARAMETER_NAMES

__all__ = ["CALIBRATED_FORMAT", "CALIBRATED_VERSION", "CalibratedModel", "calibrated_robot", "friction_drives",
           "LoadedModel", "load_calibrated_model", "read_calibrated_model", "standard_parameter_labels"]  # fmt: skip

CALIBRATED_FORMAT = "psdm-calibrated-model"
CALIBRATED_VERSION = 2
LUGRE_VERSION = 3  # the version of a file whose friction is LuGre (drive.lugre)
WIDTH_VERSION = 4  # the version of a file whose drive.coulomb_velocity is one width per joint (coulomb_width)
READABLE_VERSIONS = (1, 2, 3, 4, 5)  # 5: a counterbalance finding (``counterbalance_finding.COUNTERBALANCE_VERSION``)


def standard_parameter_labels(n_dof: int) -> list:
    """``m1, mx1, my1, mz1, Ixx1, Ixy1, Iyy1, Ixz1, Iyz1, Izz1, Ia1, m2, ...``."""
    return [f"{name}{j + 1}" for j in range(n_dof) for name in (*LINK_PARAMETER_NAMES, "Ia")]


def _floats(values) -> list:
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(values, dtype=float).reshape(-1)]


def _array(values) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=float)


@dataclass(frozen=True)
class CalibratedModel:
    """A calibrated model as read from (or about to be written to) its file; see the module docstring."""

    document: dict = field(repr=False)

    # --- building and writing --------------------------------------------------------------------
    @classmethod
    def from_fit(cls, robot, model, fit: TrajectoryFit, *, robot_source, recordings=(), validation=None, lugre=None,
                 configurations=None):  # fmt: skip
        """The document of a :class:`TrajectoryFit` of ``robot`` (``robot_source`` is its file or built-in name).

        With ``lugre`` (a ``lugre_recordings.LuGreFit``) of every joint, ``fit``'s friction columns are replaced by
        the LuGre block (version 3); of some joints (``mixed_friction``), ``fit`` keeps them (0 on the LuGre joints).
        With ``configurations`` (one ``PayloadConfiguration`` per recording of ``recordings``), the
        ``configurations`` block says which load each recording carried.
        """
        if lugre is not None and len(lugre.joints) == robot.n_dof:  # a mixed model keeps its steady-state columns
            from identification.calibration.lugre_recordings import without_friction

            fit = without_friction(fit)
        n = robot.n_dof
        relative = fit.relative_sigma_percent
        document = {
            "format": CALIBRATED_FORMAT,
            "version": CALIBRATED_VERSION,
            "robot": _robot_block(robot, robot_source),
            "standard": {"names": standard_parameter_labels(n), "values": _floats(fit.standard),
                         "consistent": bool(fit.consistent), "checked": bool(fit.checked),
                         "min_pseudo_inertia_eigenvalue": _floats([fit.min_pseudo_inertia_eigenvalue])[0],
                         "envelope": dict(fit.envelope_bounds),
                         "envelope_findings": [finding.to_dict() for finding in fit.envelope]},
            "base": {"names": [f"theta{k + 1}" for k in range(model.n_base)], "values": _floats(fit.theta),
                     "ols": _floats(fit.theta_ols), "std": _floats(fit.theta_std),
                     "relative_sigma_percent": _floats(relative[: model.n_base]),
                     "equations": model.equations().splitlines()},
            "drive": {"names": list(fit.drive_names), "values": _floats(fit.drive), "ols": _floats(fit.drive_ols),
                      "std": _floats(fit.drive_std), "relative_sigma_percent": _floats(relative[model.n_base :]),
                      "friction_terms": list(fit.friction_terms), "coulomb_velocity": file_width(fit.coulomb_velocity),
                      "friction_shape": "stribeck" if "fs" in fit.friction_terms else "coulomb-viscous",
                      "friction_shapes": friction_shapes(fit.friction_terms, fit.stribeck_velocity, n),
                      "stribeck_velocity": list(fit.stribeck_velocity),
                      "stribeck_velocity_std": _floats(fit.stribeck_velocity_std),
                      **({"viscous_exponent": list(fit.viscous_exponent)} if fit.viscous_exponent else {}),
                      "inertia_joints": [j + 1 for j in fit.inertia_joints]},
            "identification": {"cutoff_hz": list(fit.cutoff_hz), "decimation": list(fit.decimation),
                               "n_samples": fit.n_samples, "joint_samples": list(fit.joint_samples),
                               "sigma": _floats(fit.sigma),
                               "condition_number": float(fit.condition_number), "solver_status": fit.solver_status,
                               "seconds": round(fit.seconds, 3),
                               "preparation": preparation_block(fit.cutoff_hz, fit.decimation, fit.edge_periods)},
            "provenance": {"created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                           "psdm_casadi_version": _version(), "recordings": list(recordings)},
            "validation": validation or {},
            "findings": [], **covariance_block(fit),
        }  # fmt: skip
        if configurations is not None and any(c.stated for c in configurations):
            names = [e["name"] for e in recordings] or [f"recording {k + 1}" for k in range(len(configurations))]
            document["configurations"] = configurations_block(configurations, names, fit.payloads)
        if lugre is not None:  # LuGre on its joints, each other joint the fit's steady-state shape (mixed_friction)
            from identification.calibration.lugre_recordings import lugre_block

            shapes = document["drive"]["friction_shapes"]
            document["version"], document["drive"]["friction_shape"] = LUGRE_VERSION, "lugre"
            document["drive"]["friction_shapes"] = ["lugre" if j in lugre.joints else shapes[j] for j in range(n)]
            document["drive"]["lugre"] = lugre_block(lugre)
        if isinstance(document["drive"]["coulomb_velocity"], list):  # one width per joint: older readers refuse it
            document["version"] = WIDTH_VERSION
        return cls(document)

    def save(self, path, *, overwrite: bool = False, allow_inconsistent: bool = False) -> Path:
        """Write the file atomically; an inconsistent model needs ``allow_inconsistent`` (and says so)."""
        if not self.consistent and not allow_inconsistent:
            raise ModelFileError(
                f"the calibrated model is not physically consistent (smallest pseudo-inertia eigenvalue "
                f"{self.document['standard']['min_pseudo_inertia_eigenvalue']}); it was not written to {path}. "
                "Pass --allow-inconsistent to write it marked as such."
            )
        text = json.dumps(self.document, indent=1, allow_nan=False)
        return atomic_write(path, lambda handle: handle.write(text + "\n"), overwrite)

    # --- reading -----------------------------------------------------------------------------------
    @property
    def consistent(self) -> bool:
        return bool(self.document["standard"]["consistent"])

    @property
    def configurations(self) -> list:
        """The ``configurations`` block (module docstring): a list of dicts, empty for a file without one."""
        return list(self.document.get("configurations") or [])

    @property
    def n_dof(self) -> int:
        return len(self.document["robot"]["joint_names"])

    @property
    def standard(self) -> np.ndarray:
        """Standard parameters, shape (n_dof, 11): the 10 of each link, then its drive inertia."""
        return _array(self.document["standard"]["values"]).reshape(self.n_dof, -1)

    @property
    def theta(self) -> np.ndarray:
        return _array(self.document["base"]["values"])

    @property
    def drive(self) -> np.ndarray:
        return _array(self.document["drive"]["values"])

    def robot_file(self, cache_dir=None) -> Path:
        """The robot file's text written into the robot cache (with its URDF), as a path to load or copy."""
        block = self.document["robot"]
        folder = Path(cache_dir or robot_cache_folder()) / block["sha256"][:16]
        # a URDF outside the robot file's folder is stored by its relative path ("../data/robot.urdf"): the robot
        # file goes as many folders deep as the paths climb, so that each lands inside ``folder``
        depth = max(os.path.normpath(name).split(os.sep).count("..") for name in block["files"])
        base = folder.joinpath(*["up"] * depth)
        for name, text in block["files"].items():
            target = Path(os.path.normpath(base / name))
            if folder.resolve() not in target.resolve().parents:
                raise ModelFileError(f"robot.files name {name!r} must lie beside the robot file or below it.")
            target.parent.mkdir(parents=True, exist_ok=True)
            if not target.exists() or target.read_text() != text:
                atomic_write(target, lambda handle, text=text: handle.write(text), overwrite=True)
        return base / block["main_file"]

    def load_robot(self, cache_dir=None):
        """The robot description the model was identified for, rebuilt from the texts in the file."""
        from psdm_casadi.robot import load_robot

        block = self.document["robot"]
        main = self.robot_file(cache_dir)
        robot = load_robot(main)
        stored = [_lock(entry) for entry in block["locked_joints"]]
        extra = [lock for lock in stored if lock not in robot.locked_joints]  # the command line's, not the file's
        return load_robot(main, locked_joints=tuple(extra)) if extra else robot

    @property
    def corrections(self) -> dict:
        """Measurement corrections of the signal-type findings (``{"delay": {"delay_s": d}}``), empty if none."""
        return dict(self.document.get("corrections") or {})

    @property
    def torque_findings(self) -> list:
        """``(FindingTerm, coefficients)`` of every torque-type finding; a feature left out of the fit counts 0."""
        out = []
        for entry in self.document.get("findings") or []:
            if entry.get("kind") == "torque":
                term = FindingTerm.from_dict(entry.get("term") or {})
                values = np.array([0.0 if v is None else v for v in entry.get("coefficients") or ()], dtype=float)
                if values.size != len(term.feature_names()) or not np.all(np.isfinite(values)):
                    raise ModelFileError(
                        f"calibrated model findings[{entry.get('label')!r}].coefficients must be "
                        f"{len(term.feature_names())} finite numbers (or null for an absorbed feature), one per "
                        f"feature {term.feature_names()}; got {entry.get('coefficients')!r}. Re-run "
                        "'psdm diagnose MODEL --apply'."
                    )
                out.append((term, values))
        return out

    @property
    def coulomb_widths(self) -> np.ndarray:
        """[rad/s] the Coulomb sign's smoothing width per joint, shape (n_dof,) (``coulomb_width``)."""
        return file_coulomb_widths(self.document["drive"], self.n_dof)

    @property
    def temperature_friction(self):
        """The friction's law in the joints' temperature (``temperature_friction.TemperatureFriction``), or None."""
        return TemperatureFriction.from_document(self.document)

    @property
    def lugre_parameters(self) -> tuple | None:
        """The LuGre parameters of each joint (``LuGreParameters``; None on a joint of a steady-state shape,
        ``mixed_friction``) of a LuGre model, else None."""
        block = self.document["drive"].get("lugre")
        if not block:
            return None
        from identification.friction.models import LUGRE_PARAMETER_NAMES, LuGreParameters

        joints = file_lugre_joints(self.document, self.n_dof)
        try:
            return tuple(LuGreParameters(**{name: block[name][j] for name in LUGRE_PARAMETER_NAMES})
                         if j in joints else None for j in range(self.n_dof))  # fmt: skip
        except (KeyError, IndexError, TypeError, ParameterError) as exc:
            raise ModelFileError(
                f"calibrated model drive.lugre must hold {self.n_dof} valid values for each of "
                f"{list(LUGRE_PARAMETER_NAMES)}; got an error ({exc}). Re-run 'psdm identify --friction lugre'."
            ) from None

    def predict_recording(self, model, recording, kt=None) -> tuple:
        """(prepared recording, predicted joint torques [N m]) of the model on a raw recording, as ``psdm validate``.

        The one path from a raw recording to the model's torque: the model's measurement corrections first
        (``findings.correct_recording``), then the identification's preparation (``model_preparation``). A LuGre
        model's bristle state starts relaxed at the raw start and is carried over the samples the filter trims along
        the corrected recording (``lugre_recordings.bristle_force_at``): the friction sees the corrected velocity, as
        in the fit.
        ``kt`` [N m/A], shape (n_dof,), converts a recording of currents.
        """
        own = model_preparation(self.document)  # its cutoff and edge trim (one filter period in older files)
        corrected = correct_recording(recording, self.corrections, kt)
        prepared, _, _ = prepare_recording(corrected, kt, own.cutoff_hz, own.edge_periods)
        bristle = None
        if self.lugre_parameters is not None:
            from identification.calibration.lugre_recordings import bristle_force_at

            bristle = bristle_force_at(self.lugre_parameters, corrected, own.cutoff_hz, prepared.t[0])
        temperature = temperatures_at(recording, prepared.t) if self.temperature_friction is not None else None
        predicted = self.predict(model, prepared.q, prepared.qd, prepared.qdd, t=prepared.t, bristle=bristle,
                                 temperature=temperature)  # fmt: skip
        return prepared, predicted

    def predict(self, model, q, qd, qdd, t=None, bristle=None, temperature=None, lugre=True) -> np.ndarray:
        """Joint torques [N m] of the calibrated model: rigid body of ``theta``, drive terms and findings.

        The load-dependent friction of a finding is proportional to the model's own torque without it. The
        friction of a LuGre model carries its bristle state along the series (``lugre_recordings.lugre_friction``):
        it needs the sample times ``t`` [s], shape (n_samples,), and the rows in time order; ``bristle`` [N m],
        shape (n_dof,), is its bristle force ``sigma0 z`` at ``t[0]`` (default relaxed, 0). ``temperature`` [°C],
        shape (n_samples, n_dof) (NaN: not logged), moves a file's friction along its law (``temperature_friction``;
        None: the reference temperature). ``lugre=False`` leaves the LuGre friction out (no ``t`` needed): the torque
        the exported ``psdm_inverse_dynamics`` computes at a state (its ``lugre_step`` carries the bristles beside).
        """
        lugre = self.lugre_parameters if lugre else None
        if lugre is not None and t is None:
            raise ParameterError(
                "CalibratedModel.predict t must be the sample times [s] for a LuGre model (its friction carries "
                "the bristle state along the series); got None. Pass t=recording.t."
            )
        drive = self.document["drive"]
        q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
        inertia_joints = tuple(j - 1 for j in drive["inertia_joints"])
        columns = drive_columns(qd, qdd, tuple(drive["friction_terms"]), inertia_joints, self.coulomb_widths,
                                *file_shape(drive))  # the Stribeck velocities and viscous exponents  # fmt: skip
        tau = model.inverse_dynamics(q, qd, qdd, self.theta) + columns @ self.drive
        if lugre is not None:
            from identification.calibration.lugre_recordings import lugre_friction

            tau = tau + lugre_friction(lugre, np.asarray(t, dtype=float), qd, bristle)
        findings = self.torque_findings
        for term, values in findings:
            if not term.load_dependent:
                tau[:, term.joint] += sum(c * v for c, v in zip(values, term_values(term, q, qd, qdd)))
        base = tau.copy()
        for term, values in findings:
            if term.load_dependent:
                tau[:, term.joint] += values[0] * term_values(term, q, qd, qdd, base)[0]
        laws = self.temperature_friction
        return tau if laws is None else tau + laws.torque(columns, drive["names"], temperature)


def calibrated_robot(calibrated: CalibratedModel, robot):
    """``robot`` with the calibrated standard parameters as its nominal inertia: the nominal model a diagnosis of a
    calibrated model starts from (``psdm diagnose MODEL``). Links the data cannot see keep the robot file's values; a
    drive inertia below 0 is held beside it (``held_friction.drive_inertia_split``). Raises ``ParameterError`` for a
    model identified with --no-consistency (it holds base parameters only)."""
    import pinocchio as pin

    from psdm_casadi.description import LinkInertia

    standard = calibrated.standard
    if not calibrated.document["standard"].get("checked", True) or not np.all(np.isfinite(standard)):
        raise ParameterError(
            "diagnose MODEL needs the standard parameters of a consistent fit; the file holds base parameters only "
            "(identified with --no-consistency). Identify it again without --no-consistency."
        )
    prior = robot.links
    links = []
    for i in range(robot.n_dof):
        if standard[i, 0] > 1e-9:
            inertia = pin.Inertia.FromDynamicParameters(standard[i, :10])
            links.append(
                LinkInertia(mass=float(inertia.mass), com=np.array(inertia.lever), inertia=np.array(inertia.inertia))
            )
        else:
            links.append(prior[i] if prior is not None else LinkInertia())
    out = robot.with_links(links, rotor_inertia=drive_inertia_split(standard[:, 10])[0])
    drives = friction_drives(calibrated, robot)
    return out if drives is None else dataclasses.replace(out, drives=drives)


def _robot_block(robot, robot_source) -> dict:
    from psdm_casadi.robot import resolve_robot_path

    if robot_source is None:
        raise ParameterError(
            f"robot_source is None for robot {robot.name!r}: the calibrated-model file stores the robot file's text "
            "so every command can rebuild the kinematics; pass the robot file's path (or a built-in name), or write "
            "a robot built in Python to a robot file first."
        )
    main = resolve_robot_path(robot_source)
    files = {main.name: main.read_text()}
    if robot.urdf_path is not None and Path(robot.urdf_path).name != main.name:
        # by its path relative to the robot file (its name when beside it), as the robot file's [urdf].path reads
        relative = Path(robot.urdf_path).name if main.suffix.lower() == ".urdf" else _relative(robot.urdf_path, main)
        files[relative] = Path(robot.urdf_path).read_text()
    digest = robot_digest(files)  # the same digest the reader checks
    locked = [list(_lock(entry)) for entry in robot.locked_joints] if robot.urdf_path is not None else []
    return {"name": robot.name, "joint_names": list(robot.joint_names), "main_file": main.name, "files": files,
            "locked_joints": locked, "sha256": digest}  # fmt: skip


def _relative(urdf_path, main: Path) -> str:
    """The URDF's path relative to the robot file's folder (/ separators): its [urdf].path as written, not from the
    resolved ``urdf_path``, which through a symlinked folder differs and would not reach the stored URDF."""
    written = tomllib.loads(main.read_text()).get("urdf", {}).get("path")
    if isinstance(written, str) and not Path(written).is_absolute():
        return Path(written).as_posix()
    return Path(os.path.relpath(os.path.abspath(urdf_path), os.path.abspath(main.parent))).as_posix()


def _lock(entry) -> tuple:
    """A locked joint as ``(name, value)``; a bare name (older files) is locked at 0."""
    if isinstance(entry, str):
        return (entry, 0.0)
    name, value = entry
    return (str(name), float(value))


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("psdm-casadi")
    except Exception:  # not installed (a plain checkout): say so rather than guess
        return "unknown"


@dataclass(frozen=True, eq=False)
class LoadedModel:
    """A checked calibrated-model file with the robot it was identified for and that robot's PSDM model (the
    check derives them; :func:`read_calibrated_model` hands them on so that a command does not derive again)."""

    calibrated: CalibratedModel
    robot: object
    model: object


def load_calibrated_model(path) -> CalibratedModel:
    """The checked calibrated model of ``path`` (:func:`read_calibrated_model` without the robot and its model)."""
    return read_calibrated_model(path).calibrated


def read_calibrated_model(path, derive=None) -> LoadedModel:
    """Read a calibrated-model file, checking its format, version and contents (``model_file_check``).

    Every field must parse (finite numbers of the right length, booleans, drive names and values one to one),
    the robot texts must match ``robot.sha256``, the base parameters must be those of the standard block under
    the model derived from the file's robot, and a file that claims ``consistent`` must pass the check again.
    ``derive(robot) -> PSDMModel`` derives that model (default ``derive_psdm``; the CLI passes its model cache).

    Raises
    ------
    ModelFileError
        Naming the file, the field and the fix (not JSON, another format, a newer version, missing blocks, a
        field that does not parse, an edited robot text, base and standard parameters that disagree, a false
        consistency claim).
    """
    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except FileNotFoundError:
        raise ModelFileError(f"model file {str(path)!r} does not exist. Check the path.{did_you_mean(path)}") from None
    except IsADirectoryError:
        inside = ", ".join(sorted(p.name for p in path.glob("*.json"))[:5]) or "none"
        raise ModelFileError(f"model file {str(path)!r} is a folder. Pass the .json file that 'psdm identify' wrote "
                             f"(.json files in it: {inside}).") from None  # fmt: skip
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(f"{path.name}: not a calibrated-model file ({exc}). Pass the .json that "
                             "'psdm identify' wrote.") from None  # fmt: skip
    if not isinstance(document, dict) or document.get("format") != CALIBRATED_FORMAT:
        raise ModelFileError(f"{path.name}: format must be {CALIBRATED_FORMAT!r}; got "
                             f"{document.get('format') if isinstance(document, dict) else type(document).__name__!r}. "
                             "Pass the .json that 'psdm identify' wrote.")  # fmt: skip
    if document.get("version") not in READABLE_VERSIONS:
        raise ModelFileError(f"{path.name}: version must be one of {READABLE_VERSIONS}; got "
                             f"{document.get('version')!r}. Re-run 'psdm identify' with this version of "
                             "psdm-casadi.")  # fmt: skip
    missing = [k for k in ("robot", "standard", "base", "drive", "identification") if k not in document]
    if missing:
        raise ModelFileError(f"{path.name}: the blocks {missing} are missing. Re-run 'psdm identify'.")
    from identification.calibration.model_file_check import check_against_model, check_document
    from psdm_casadi.derive import derive_psdm

    check_document(document, path.name)  # every field parses, the robot text matches its hash
    calibrated = CalibratedModel(document)
    calibrated.lugre_parameters, calibrated.torque_findings, calibrated.temperature_friction  # noqa: B018
    robot = calibrated.load_robot()
    model = (derive or derive_psdm)(robot)
    check_against_model(calibrated, model, path.name, robot)  # base == standard's, and what the file claims
    return LoadedModel(calibrated, robot, model)
