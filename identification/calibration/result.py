"""IdentifiedModel: the outcome of the identification pipeline (PSDM model, base parameters, Kt, LuGre, report).

Saved as a directory: ``identified.json`` (versioned header, Kt, LuGre, validation report,
consistency check, provenance), ``parameters.npz`` (theta and Kt) and ``model.npz`` (the PSDM
model, ``PSDMModel.save``). Files are written atomically and never overwritten unless asked.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from identification.calibration.consistency import ConsistencyReport
from identification.calibration.extra_terms import ExtraTerms, TermContext, extra_torque
from identification.calibration.report import ValidationReport
from identification.friction.models import LuGreParameters
from psdm_casadi.errors import ModelFileError, ParameterError, ShapeError
from psdm_casadi.fileio import OutputFolder, atomic_write
from psdm_casadi.model import PSDMModel, load_model

__all__ = ["IdentifiedModel", "load_identified", "RESULT_FORMAT", "RESULT_VERSION", "RESULT_FILES"]

RESULT_FORMAT = "psdm-identified"
RESULT_VERSION = 1
#: The files of a saved IdentifiedModel, inside its directory.
RESULT_FILES = ("identified.json", "parameters.npz", "model.npz")


@dataclass(frozen=True, eq=False)
class IdentifiedModel:
    """An identified robot model.

    Parameters
    ----------
    robot_name : str
    model : PSDMModel
    theta : array, shape (n_base,)
        Base parameters.
    kt : array, shape (n_dof,)
        Motor torque constants [N m/A].
    lugre : tuple of LuGreParameters, length n_dof
    report : ValidationReport
    consistency : ConsistencyReport or None
    metadata : dict
        Provenance only (timings, solver statuses); never read by algorithms.
    extra_terms : ExtraTerms or None
        Known additive torques fitted with the model (a diagnosis finding such as a spring), with their
        coefficients and standard errors; part of every prediction.
    """

    robot_name: str
    model: PSDMModel
    theta: np.ndarray
    kt: np.ndarray
    lugre: tuple
    report: ValidationReport
    consistency: ConsistencyReport | None = None
    metadata: dict = field(default_factory=dict)
    extra_terms: ExtraTerms | None = None

    def __post_init__(self):
        n, l = self.model.n_dof, self.model.n_base
        theta = np.array(self.theta, dtype=float).reshape(-1)
        kt = np.array(self.kt, dtype=float).reshape(-1)
        if theta.shape != (l,):
            raise ShapeError(f"IdentifiedModel.theta must have {l} base parameters; got {theta.shape}.")
        if kt.shape != (n,):
            raise ShapeError(f"IdentifiedModel.kt must have {n} values [N m/A]; got {kt.shape}.")
        if len(self.lugre) != n or not all(isinstance(p, LuGreParameters) for p in self.lugre):
            raise ShapeError(f"IdentifiedModel.lugre must hold {n} LuGreParameters; got {len(self.lugre)} items.")
        for name, value in (("theta", theta), ("kt", kt)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "lugre", tuple(self.lugre))
        if self.extra_terms is not None and not (isinstance(self.extra_terms, ExtraTerms) and self.extra_terms.fitted):
            raise ParameterError(
                f"IdentifiedModel.extra_terms must be a fitted ExtraTerms or None; got {self.extra_terms!r}."
            )

    @property
    def n_dof(self) -> int:
        return self.model.n_dof

    def predict_torque(self, t, q, qd, qdd) -> np.ndarray:
        """Joint torques [N m]: ``Y theta`` plus LuGre friction simulated along ``qd`` plus the extra terms;
        shape (n_samples, n_dof)."""
        from identification.calibration.friction_step import friction_torque
        from identification.calibration.steps import regressor_chunked

        q, qd, qdd = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
        t = np.asarray(t, dtype=float).reshape(-1)
        tau = regressor_chunked(self.model, q, qd, qdd) @ self.theta + friction_torque(self.lugre, t, qd)
        return tau + extra_torque(self.extra_terms, TermContext(t, q, qd, qdd))

    def build_feedforward(self, robot) -> ca.Function:
        """The model's whole feed-forward torque as a CasADi Function ``feedforward_torque(q, qd, qdd) -> tau``.

        Rigid body (Newton-Euler on the base parameters, ``build_recursive_functions`` with ``theta``
        baked in), the steady-state (Stribeck) curve of each joint's LuGre friction, and the extra terms.
        The LuGre bristle dynamics have a state and are left out: at constant velocity the two agree.
        Export it with ``codegen.export.export_c``.

        Parameters
        ----------
        robot : RobotDescription
            The robot the model was derived from (its kinematics).

        Raises
        ------
        ParameterError
            When an extra term depends on time (a drift is no feed-forward of the joint state).
        """
        from psdm_casadi.recursive import build_recursive_functions

        n = self.n_dof
        q, qd, qdd = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd"))
        tau = build_recursive_functions(self.model, robot, self.theta).inverse_dynamics(q, qd, qdd)
        friction = []
        for j, p in enumerate(self.lugre):
            breakaway = p.fc + (p.fs - p.fc) * ca.exp(-((qd[j] / p.vs) ** 2))
            friction.append((breakaway + p.fv * ca.fabs(qd[j]) ** p.dv) * ca.sign(qd[j]))
        tau = tau + ca.vertcat(*friction)
        if self.extra_terms is not None:
            t = ca.SX.sym("t")
            extra = self.extra_terms.casadi_torque(q, qd, qdd, t, tau)
            if ca.depends_on(extra, t):
                raise ParameterError(
                    f"IdentifiedModel.extra_terms {list(self.extra_terms.labels)} depend on time; a feed-forward "
                    "torque of (q, qd, qdd) cannot hold them. Drop the time-dependent term."
                )
            tau = tau + extra
        return ca.Function("feedforward_torque", [q, qd, qdd], [tau], ["q", "qd", "qdd"], ["tau"], {"cse": True})

    # --- files ------------------------------------------------------------------------------------
    def save(self, directory, overwrite: bool = False) -> Path:
        """Write the model into ``directory`` (created); refuse existing files unless ``overwrite``.

        The three files are written into a staging folder and moved into ``directory`` together: an
        error or an interrupt leaves the directory as it was. Other files of the directory are kept.

        Raises
        ------
        FileExistsError
            When a file of the result exists and ``overwrite`` is false (nothing is written).
        """
        directory = Path(directory)
        if not overwrite:
            for name in RESULT_FILES:
                if (directory / name).exists():
                    raise FileExistsError(
                        f"{str(directory / name)!r} exists; pass overwrite=True (or --overwrite) to replace it."
                    )
        header = {
            "format": RESULT_FORMAT,
            "version": RESULT_VERSION,
            "robot_name": self.robot_name,
            "consistent": None if self.consistency is None else self.consistency.consistent,
            "base_names": list(self.model.base_names),
            "theta": self.theta.tolist(),
            "kt": self.kt.tolist(),
            "lugre": [p.as_dict() for p in self.lugre],
            "report": self.report.to_dict(),
            "consistency": None if self.consistency is None else self.consistency.to_dict(),
            "metadata": self.metadata,
            "extra_terms": None if self.extra_terms is None else self.extra_terms.to_dict(),
        }
        text = json.dumps(header, indent=2, default=_json_default)
        arrays = {"theta": self.theta, "kt": self.kt, "lugre": np.array([p.as_array() for p in self.lugre])}
        with OutputFolder(directory, RESULT_FILES, shared=True).staging() as stage:
            self.model.save(stage / "model.npz")
            atomic_write(stage / "parameters.npz", lambda h: np.savez(h, **arrays), mode="wb")
            atomic_write(stage / "identified.json", lambda h: h.write(text + "\n"))
        return directory


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return str(value)


def load_identified(directory) -> IdentifiedModel:
    """Read an :class:`IdentifiedModel` written by ``IdentifiedModel.save``.

    Raises
    ------
    ModelFileError
        Missing files, another format or an unsupported version.
    """
    directory = Path(directory)
    for name in RESULT_FILES:
        if not (directory / name).exists():
            raise ModelFileError(
                f"{str(directory / name)!r} is missing; is {str(directory)!r} an identified model "
                "written by IdentifiedModel.save / psdm identify?"
            )
    try:
        header = json.loads((directory / "identified.json").read_text())
    except ValueError as exc:
        raise ModelFileError(f"identified.json is not valid JSON ({exc}). Identify again.") from None
    if header.get("format") != RESULT_FORMAT:
        raise ModelFileError(f"identified.json format must be {RESULT_FORMAT!r}; got {header.get('format')!r}.")
    if header.get("version") != RESULT_VERSION:
        raise ModelFileError(
            f"identified.json version {header.get('version')} is not supported (this release reads "
            f"version {RESULT_VERSION}). Identify again with this release."
        )
    with np.load(directory / "parameters.npz", allow_pickle=False) as arrays:
        theta, kt = arrays["theta"], arrays["kt"]
    consistency = header.get("consistency")
    return IdentifiedModel(
        robot_name=header["robot_name"],
        model=load_model(directory / "model.npz"),
        theta=theta,
        kt=kt,
        lugre=tuple(LuGreParameters(**p) for p in header["lugre"]),
        report=ValidationReport.from_dict(header["report"]),
        consistency=None if consistency is None else ConsistencyReport.from_dict(consistency),
        metadata=header.get("metadata", {}),
        extra_terms=_extra_terms_from(header.get("extra_terms"), len(kt)),
    )


def _extra_terms_from(entries, n_dof: int):
    """The saved extra terms (``ExtraTerms.to_dict``) rebuilt from their spec (``CandidateTerm.spec``), or for files
    written before specs from the candidate library by their labels."""
    if not entries:
        return None
    from identification.diagnosis.candidates import default_library
    from identification.diagnosis.term_spec import term_from_spec
    from psdm_casadi.errors import ParameterError

    by_label = {term.label: term for term in default_library().expand(n_dof)}
    terms, coefficients, std = [], [], []
    for entry in entries:
        try:
            term = term_from_spec(entry["spec"]) if "spec" in entry else by_label.get(entry.get("label"))
        except ParameterError as exc:
            raise ModelFileError(f"identified.json extra_terms: {exc} Identify again with this release.") from None
        if term is None or list(term.feature_names()) != entry.get("feature_names"):
            raise ModelFileError(
                f"identified.json extra_terms: {entry.get('label')!r} with features {entry.get('feature_names')} "
                "is not a term of this release's candidate library. Identify again with this release."
            )
        terms.append(term)
        coefficients.extend(entry["coefficients"])
        std.extend(entry.get("std", [np.nan] * len(entry["coefficients"])))
    return ExtraTerms(tuple(terms), np.array(coefficients), np.array(std))


# ``IdentifiedModel.load(directory)``: the documented alias of load_identified
IdentifiedModel.load = staticmethod(load_identified)
