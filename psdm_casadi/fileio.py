"""Atomic file and folder writing shared by every package: write beside the target, then rename over it."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path


def atomic_write(path, write, overwrite: bool = False, mode: str = "w") -> Path:
    """Write a file through ``write(handle)`` into a temporary file of the same folder, then rename it.

    Raises ``FileExistsError`` when ``path`` exists and ``overwrite`` is false.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{str(path)!r} exists; pass overwrite=True (or --overwrite) to replace it.")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, mode) as handle:
            write(handle)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


class OutputFolder:
    """A folder of outputs built beside its target and moved into place only when complete.

    The rules, checked by :meth:`check` before any work:

    - the target must not be a file, the working folder or the home folder;
    - an existing non-empty target is refused unless ``force``; with ``force`` it may hold only
      entries this tool writes (``names``): a folder that holds anything else is refused whole;
    - nothing is deleted but the entries this run replaces.

    The outputs are written into a fresh staging folder next to the target (hidden, unique, never an
    existing one); :meth:`commit` moves its entries into the target, and an interrupted or failed run
    leaves the target as it was and removes only its own staging folder.

    Examples
    --------
    >>> folder = OutputFolder("report", names=("report.md",), option="--force")  # doctest: +SKIP
    >>> folder.check(force=False)  # doctest: +SKIP
    >>> with folder.staging() as stage:  # doctest: +SKIP
    ...     (stage / "report.md").write_text("...")
    """

    def __init__(self, target, names, option: str = "--force"):
        self.target = Path(target)
        self.names = frozenset(names)
        self.option = option

    def check(self, force: bool) -> None:
        """Refuse a target this run may not write, before any work (FileExistsError, naming the fix)."""
        target = self.target
        resolved = target.expanduser().resolve()
        if resolved in (Path.cwd().resolve(), Path.home().resolve()) or resolved == Path(resolved.anchor):
            raise FileExistsError(
                f"--out {str(target)!r} is the working, home or root folder; name a new folder, e.g. --out report."
            )
        if target.exists() and not target.is_dir():
            raise FileExistsError(f"--out {str(target)!r} is a file; name a folder (new, or one this tool wrote).")
        existing = sorted(p.name for p in target.iterdir()) if target.is_dir() else []
        if not existing:
            return
        if not force:
            raise FileExistsError(
                f"--out {str(target)!r} exists and is not empty; pass {self.option} to replace "
                "the files this tool wrote there, or name a new folder."
            )
        foreign = [name for name in existing if name not in self.names]
        if foreign:
            shown = ", ".join(foreign[:5]) + (" ..." if len(foreign) > 5 else "")
            raise FileExistsError(
                f"--out {str(target)!r} holds files this tool did not write ({shown}); "
                f"{self.option} replaces only its own outputs. Name a new folder."
            )

    def staging(self):
        """Context manager: a fresh staging folder; removed on error or interrupt, committed on success."""
        return _Staging(self)

    def commit(self, stage: Path) -> Path:
        """Move the staged entries into the target, replacing only the entries of the same names."""
        unknown = sorted(p.name for p in stage.iterdir() if p.name not in self.names)
        if unknown:  # a programming error: every output must be declared, or --force could not replace it
            raise RuntimeError(f"OutputFolder.names must list every output; {unknown} are missing.")
        if not self.target.exists():
            os.replace(stage, self.target)
            return self.target
        for entry in sorted(stage.iterdir()):
            destination = self.target / entry.name
            if destination.is_dir() and not destination.is_symlink():
                shutil.rmtree(destination)
            elif destination.exists() or destination.is_symlink():
                destination.unlink()
            os.replace(entry, destination)
        stage.rmdir()
        return self.target


class _Staging:
    def __init__(self, folder: OutputFolder):
        self.folder = folder
        self.path: Path | None = None

    def __enter__(self) -> Path:
        parent = self.folder.target.parent
        parent.mkdir(parents=True, exist_ok=True)
        self.path = Path(tempfile.mkdtemp(prefix=f".{self.folder.target.name}.partial-", dir=parent))
        return self.path

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            self.folder.commit(self.path)
        elif self.path.exists():
            shutil.rmtree(self.path)
        return False
