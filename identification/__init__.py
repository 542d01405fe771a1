"""identification: from recordings to a calibrated model, and what that model still misses.

The flow reads off the subpackages:

- ``data``: a :class:`Recording` (time, joint positions, torques or currents), the readers and
  writers of every file format, filtering and differentiation, the calibration data folder;
- ``friction``: LuGre and simpler friction models (numeric and CasADi), their start values, the
  multiple-shooting fit and the model of what a friction experiment measures;
- ``calibration``: the paper's four identification steps (torque constants, gravity, friction,
  inertial), the joint refinement, the consistency check and the :class:`IdentifiedModel`;
- ``diagnosis``: where a model misses the recordings, which physics explains it, the augmented model;
- ``virtual``: the virtual robot that simulates recordings with known truth and hidden effects.

The names below are the everyday entry points.
"""

import importlib

#: each entry point's module: imported on first use (PEP 562), so that importing one subpackage (a Dask worker's
#: robot-day task imports the readers and the fleet's refit) does not load the pipeline and the diagnosis
_ENTRY_POINTS = {
    "DiagnosisOptions": "identification.diagnosis",
    "DiagnosisReport": "identification.diagnosis",
    "IdentificationPipeline": "identification.calibration.pipeline",
    "IdentifiedModel": "identification.calibration.result",
    "PipelineOptions": "identification.calibration.pipeline",
    "Recording": "identification.data.recording",
    "diagnose": "identification.diagnosis",
    "load_identified": "identification.calibration.result",
    "load_recording": "identification.data.io",
    "save_recording": "identification.data.io",
}

__all__ = [
    "DiagnosisOptions",
    "DiagnosisReport",
    "IdentificationPipeline",
    "IdentifiedModel",
    "PipelineOptions",
    "Recording",
    "diagnose",
    "load_identified",
    "load_recording",
    "save_recording",
]


def __getattr__(name: str):
    if name in _ENTRY_POINTS:
        return getattr(importlib.import_module(_ENTRY_POINTS[name]), name)
    raise AttributeError(f"module 'identification' has no attribute {name!r}")


def __dir__() -> list:
    return sorted(list(globals()) + __all__)
