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

from identification.calibration.pipeline import IdentificationPipeline, PipelineOptions
from identification.calibration.result import IdentifiedModel, load_identified
from identification.data.io import load_recording, save_recording
from identification.data.recording import Recording
from identification.diagnosis import DiagnosisOptions, DiagnosisReport, diagnose

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
