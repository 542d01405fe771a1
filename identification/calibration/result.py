"""IdentifiedModel: the outcome of the identification pipeline (PSDM model, base parameters, Kt, LuGre, report).

Saved as a directory: ``identified.json`` (versioned header, Kt, LuGre, validation report,
consistency check, provenance), ``parameters.npz`` (theta and Kt) and ``model.npz`` (the PSDM
model, ``PSDMModel.save``). Files are written atomically and never overwritten unless asked.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from identification.calibration.consistency import ConsistencyReport
from identification.calibration.report import ValidationReport
from identification.friction.models import LuGreParameters
from psdm_casadi.errors import ModelFileError, ShapeError
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
    """

    robot_name: str
    model: PSDMModel
    theta: np.ndarray
    kt: np.ndarray
    lugre: tuple
    report: ValidationReport
    consistency: ConsistencyReport | None = None
    metadata: dict = field(default_factory=dict)

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

    @property
    def n_dof(self) -> int:
        return self.model.n_dof

    def predict_torque(self, t, q, qd, qdd) -> np.ndarray:
        """Joint torques [N m]: ``Y theta`` plus LuGre friction simulated along ``qd``; shape (n_samples, n_dof)."""
        from identification.calibration.friction_step import friction_torque
        from identification.calibration.steps import regressor_chunked

        q, qd, qdd = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
        return regressor_chunked(self.model, q, qd, qdd) @ self.theta + friction_torque(self.lugre, t, qd)

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
    )


# ``IdentifiedModel.load(directory)``: the documented alias of load_identified
IdentifiedModel.load = staticmethod(load_identified)
