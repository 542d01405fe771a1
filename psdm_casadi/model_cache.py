"""A folder of derived models, so that a robot is derived once, not by every command (derive_psdm → cache).

Deriving a model takes 1-20 s (the Panda about 20 s); every ``psdm`` command needs one. The cache keeps
each derived model as a ``psdm-model`` ``.npz`` file (:meth:`PSDMModel.save`, the file ``psdm derive -o``
writes; no pickle) named by a key: the sha256 of

- the robot description as loaded (every compared field, after ``--lock``; a URDF by its bytes),
- the derivation options (seed, tolerances),
- the software: the package version, the model-file version, Pinocchio's and NumPy's versions and the
  source of the ``psdm_casadi`` modules the derivation runs (an edited checkout is a new key).

The folder is ``$PSDM_CACHE_DIR`` when set, else the user's cache folder (``platformdirs.user_cache_dir``,
``~/.cache/psdm-casadi/models`` on Linux). Writing is atomic (a temporary file in the same folder renamed
over the entry), so two commands deriving the same robot at once both leave a whole file. An entry that
does not read (truncated, edited, another format) is logged and derived again; a folder that cannot be
written is logged and the model derived without caching. The folder keeps the :data:`MAX_ENTRIES` most
recently used entries (a read touches its entry; a write removes the oldest beyond that), so that entries of
older versions or edited robots do not pile up.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import logging
import math
import os
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np

from psdm_casadi.derive import DeriveOptions, derive_psdm
from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import ParameterError, PSDMError
from psdm_casadi.model import MODEL_VERSION, PSDMModel, load_model

__all__ = ["CACHE_ENV", "ModelCache", "default_cache_folder", "model_key", "robot_cache_folder"]

logger = logging.getLogger(__name__)

#: Environment variable naming the cache folder (overrides the user's cache folder).
CACHE_ENV = "PSDM_CACHE_DIR"
#: Errors of reading an entry that mean "derive again" (a truncated zip, bad JSON, missing arrays ...).
UNREADABLE = (PSDMError, OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile)
#: Entries kept in the cache folder (the least recently used beyond it are removed after a write).
MAX_ENTRIES = 64


def default_cache_folder() -> Path:
    """``$PSDM_CACHE_DIR`` when set, else ``<user cache dir>/psdm-casadi/models``."""
    override = os.environ.get(CACHE_ENV)
    if override:
        return Path(override).expanduser()
    import platformdirs

    return Path(platformdirs.user_cache_dir("psdm-casadi")) / "models"


def robot_cache_folder() -> Path:
    """Where a calibrated-model file's robot texts are written back: ``robots`` beside the models.

    ``$PSDM_CACHE_DIR/robots`` when the variable is set (the model entries are the ``*.npz`` files of that
    folder, so the subfolder is never pruned), else ``<user cache dir>/psdm-casadi/robots``: one setting moves
    every cache psdm keeps.
    """
    override = os.environ.get(CACHE_ENV)
    if override:
        return Path(override).expanduser() / "robots"
    import platformdirs

    return Path(platformdirs.user_cache_dir("psdm-casadi")) / "robots"


def _canonical(value):
    """A JSON-able form of a description value: dataclasses by compared fields, arrays as lists, floats exactly."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _canonical(getattr(value, f.name)) for f in dataclasses.fields(value) if f.compare}
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in sorted(value.items(), key=lambda item: str(item[0]))}
    if isinstance(value, np.ndarray):
        return {"shape": list(value.shape), "values": [_canonical(x) for x in value.ravel().tolist()]}
    if isinstance(value, (list, tuple)):
        return [_canonical(x) for x in value]
    if isinstance(value, (bool, np.bool_)) or value is None or isinstance(value, str):
        return value if not isinstance(value, np.bool_) else bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value).hex() if math.isfinite(value) else repr(float(value))
    return repr(value)


def _file_digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@functools.lru_cache(maxsize=1)
def _software() -> dict:
    """The versions and derivation sources that a cached model depends on (read once per process: a fleet run
    asks for a model key per robot and day, and the installed sources do not change under a running process)."""
    import pinocchio

    try:
        version = metadata.version("psdm-casadi")
    except metadata.PackageNotFoundError:  # run from a checkout without installing
        version = "unknown"
    package = Path(__file__).resolve().parent
    sources = {p.name: _file_digest(p) for p in sorted(package.glob("*.py"))}
    return {
        "psdm_casadi": version,
        "model_file": MODEL_VERSION,
        "pinocchio": pinocchio.__version__,
        "numpy": np.__version__,
        "sources": sources,
    }


def _touch(path: Path) -> None:
    """Mark an entry used now (a read-only folder keeps its old time)."""
    try:
        os.utime(path)
    except OSError:
        pass


def model_key(robot: RobotDescription, options: DeriveOptions | None = None) -> str:
    """The sha256 (hex) naming the derived model of ``robot`` with ``options`` (see the module docstring)."""
    description = _canonical(robot)
    if robot.urdf_path is not None:  # the kinematics are the URDF's: key on its content, not its name
        description["urdf_path"] = {"sha256": _file_digest(robot.urdf_path)}
    document = {
        "robot": description,
        "options": _canonical(options if options is not None else DeriveOptions()),
        "software": _software(),
    }
    text = json.dumps(document, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class ModelCache:
    """Derived models in ``folder`` by :func:`model_key`; ``enabled=False`` always derives.

    Examples
    --------
    >>> from psdm_casadi import load_robot
    >>> model = ModelCache().derive(load_robot("denso_vs6556g"))   # doctest: +SKIP
    """

    folder: Path | None = None
    enabled: bool = True
    max_entries: int = MAX_ENTRIES

    def __post_init__(self):
        object.__setattr__(self, "folder", default_cache_folder() if self.folder is None else Path(self.folder))
        if not (isinstance(self.max_entries, int) and self.max_entries >= 1):
            raise ParameterError(f"ModelCache.max_entries must be an integer >= 1; got {self.max_entries!r}.")

    def path(self, key: str) -> Path:
        """The entry of ``key``."""
        return self.folder / f"{key}.npz"

    def derive(self, robot: RobotDescription, options: DeriveOptions | None = None) -> PSDMModel:
        """The model of ``robot``: read from the cache when its entry reads, else derived and stored."""
        if not self.enabled:
            return derive_psdm(robot, options)
        key = model_key(robot, options)
        path = self.path(key)
        model = self._read(path, robot)
        if model is not None:
            logger.info("model of %s read from the cache (%s)", robot.name, path)
            _touch(path)
            return model
        model = derive_psdm(robot, options)
        try:
            model.save(path, overwrite=True)
        except OSError as exc:  # a read-only or full cache folder: the command goes on without it
            logger.warning("could not write the model cache %s (%s); the model will be derived again", path, exc)
        else:
            logger.debug("model of %s stored in the cache (%s)", robot.name, path)
            self.prune()
        return model

    def prune(self) -> None:
        """Remove the least recently used entries beyond ``max_entries`` (another command's removal is no error)."""
        entries = []
        for entry in self.folder.glob("*.npz"):
            try:
                entries.append((entry.stat().st_mtime, entry))
            except OSError:  # removed meanwhile
                continue
        for _, entry in sorted(entries, reverse=True)[self.max_entries :]:
            try:
                entry.unlink()
                logger.debug("removed the least recently used model cache entry %s", entry)
            except OSError:
                pass

    def _read(self, path: Path, robot: RobotDescription) -> PSDMModel | None:
        if not path.is_file():
            return None
        try:
            model = load_model(path)
        except UNREADABLE as exc:
            logger.warning("ignoring the unreadable model cache entry %s (%s); deriving again", path, exc)
            return None
        if model.n_dof != robot.n_dof or model.robot_name != robot.name:
            logger.warning("ignoring the model cache entry %s: it holds another robot; deriving again", path)
            return None
        return model
