"""Output folders that remember what ``psdm`` wrote in them: a ``.psdm-manifest.json`` beside the outputs.

``--overwrite`` / ``--force`` on a folder output replaces a file only when an earlier ``psdm`` run wrote
it there, as recorded in the folder's manifest. A user's own ``main.c``, ``Makefile``,
``reference.csv`` or ``report.md`` that happens to carry the name of an output is refused, never
replaced, even with the option: the name alone does not tell whose file it is. Folders that earlier
versions wrote hold no manifest; their files are refused the same way (delete them, or name a new
folder).
"""

from __future__ import annotations

import json
import os
from contextlib import contextmanager
from pathlib import Path

from psdm_casadi.fileio import OutputFolder, atomic_write

__all__ = ["MANIFEST_NAME", "ManifestFolder", "read_manifest"]

#: The file in an output folder that lists the entries ``psdm`` wrote there.
MANIFEST_NAME = ".psdm-manifest.json"


def read_manifest(folder) -> frozenset:
    """The entry names the manifest of ``folder`` lists (empty when it has none or it cannot be read)."""
    path = Path(folder) / MANIFEST_NAME
    try:
        document = json.loads(path.read_text())
        files = document["files"]
    except (OSError, ValueError, TypeError, KeyError):
        return frozenset()
    return frozenset(str(name) for name in files) if isinstance(files, list) else frozenset()


class ManifestFolder:
    """An ``OutputFolder`` whose replacements are limited to the entries its manifest lists.

    Parameters
    ----------
    target : str or Path
        The output folder.
    names : iterable of str
        Every entry the command may write there (the manifest is added).
    command : str
        The ``psdm`` subcommand, recorded in the manifest.
    force_option : str
        The option that allows replacing (``--overwrite`` or ``--force``), named in messages.
    shared : bool
        A folder several runs fill (recordings): other entries are kept (see ``OutputFolder``).
    label : str
        The option that names the folder (``--out``, ``--plots``), named in messages.
    """

    def __init__(self, target, names, command: str, force_option="--overwrite", shared=False, label="--out"):
        self.names = frozenset(names)
        self.command = command
        self.folder = OutputFolder(target, (*self.names, MANIFEST_NAME), force_option, shared, label)
        # a shared folder's manifest is not an output of this run that an earlier one left (it is merged)
        self._checked = OutputFolder(target, self.names, force_option, shared, label) if shared else self.folder

    @property
    def target(self) -> Path:
        return self.folder.target

    def check(self, force: bool) -> None:
        """Refuse, before any work, a target this run may not write (``OutputFolder.check``), and with ``force``
        a target holding an output name that no earlier ``psdm`` run wrote (not in its manifest)."""
        self._checked.check(force)
        target = self.target
        if not (force and target.is_dir()):
            return
        listed = read_manifest(target)
        unlisted = sorted(name for name in os.listdir(target) if name in self.names and name not in listed)
        if unlisted:
            folder = self.folder
            raise FileExistsError(
                f"{folder.label} {str(target)!r} holds {', '.join(unlisted)}, which psdm did not write there (not "
                f"listed in its {MANIFEST_NAME}); {folder.option} replaces only files a psdm run wrote. Move them "
                f"away, or name a new folder, e.g. {folder.label} {target.name}_new."
            )

    @contextmanager
    def staging(self):
        """A fresh staging folder (see ``OutputFolder.staging``); on success the manifest is written with it,
        listing the staged entries and the earlier listed ones still in the target."""
        with self.folder.staging() as stage:
            yield stage
            kept = {name for name in read_manifest(self.target) if os.path.lexists(self.target / name)}
            staged = {p.name for p in stage.iterdir()} - {MANIFEST_NAME}
            document = {"tool": "psdm", "command": self.command, "files": sorted(kept | staged)}
            atomic_write(stage / MANIFEST_NAME, lambda handle: json.dump(document, handle, indent=1))
