"""Which recordings a model was identified on: the model file's ``provenance.recordings`` entries.

Each entry names the recording, its samples and duration, and (for a recording on disk: a file, or the folder of a
split recording or a ROS 2 bag) its absolute path and its content hash (``holdout.recording_digest``), so a reader can
tell whether a file is still the one the model was fitted to, and a refit of the model (``refit_training``) can find
it again.
"""

from __future__ import annotations

import os
from pathlib import Path

from identification.data.holdout import recording_digest

__all__ = ["recording_provenance"]


def recording_provenance(recording, source=None) -> dict:
    """Name, samples, duration and (for a recording on disk) the path and SHA-256 of a recording, for the provenance
    block."""
    entry = {"name": recording.name, "n_samples": int(recording.n_samples), "duration_s": float(recording.duration)}
    if source is not None and Path(source).exists():
        entry["path"] = os.path.abspath(source)
        entry["sha256"] = recording_digest(source)
    return entry
