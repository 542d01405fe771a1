"""Atomic file and folder writing shared by every package: write beside the target, then rename over it.

Also the checks every writer runs before any work (:func:`check_output_file`, :func:`check_writable`,
``OutputFolder.check``) and :func:`markdown_escape` for names written into Markdown reports.
"""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
from pathlib import Path

__all__ = [
    "OutputFile",
    "OutputFolder",
    "atomic_write",
    "check_output_file",
    "check_writable",
    "default_mode",
    "markdown_escape",
]

#: Characters that change the meaning of Markdown text (emphasis, code, tables, HTML, links).
MARKDOWN_SPECIAL = "\\`*_|<>[]~#"


def default_mode(executable: bool = False) -> int:
    """The permission bits ``open`` gives a new file: 0o666 (0o777 for folders and programs) less the umask."""
    mask = os.umask(0)
    os.umask(mask)
    return (0o777 if executable else 0o666) & ~mask


def normalise_modes(path) -> None:
    """Give a staged file or folder tree the permissions of files made by ``open`` (temporary files are 0600).

    Folders and files with an execute bit (compiled libraries) get 0o777 less the umask, other files 0o666.
    """
    path = Path(path)
    if path.is_symlink():
        return
    if path.is_dir():
        os.chmod(path, default_mode(executable=True))
        for child in path.iterdir():
            normalise_modes(child)
    elif path.is_file():
        os.chmod(path, default_mode(executable=bool(path.stat().st_mode & 0o111)))


def atomic_write(path, write, overwrite: bool = False, mode: str = "w") -> Path:
    """Write a file through ``write(handle)`` into a temporary file of the same folder, then rename it.

    The file gets the permissions ``open`` would give it: those of the file it replaces, else 0o666
    less the umask. An error or interrupt leaves the target as it was and no temporary file.

    Raises ``FileExistsError`` when ``path`` exists and ``overwrite`` is false.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{str(path)!r} exists; pass overwrite=True (or --overwrite) to replace it.")
    path.parent.mkdir(parents=True, exist_ok=True)
    permissions = stat.S_IMODE(path.stat().st_mode) if path.is_file() else default_mode()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, mode) as handle:
            write(handle)
        os.chmod(tmp, permissions)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def markdown_escape(text) -> str:
    """``text`` (a robot or joint name) safe inside Markdown prose and table cells: one line, special characters
    backslash-escaped (``|``, ``*``, ``_``, backticks, ``<`` ...).

    Examples
    --------
    >>> markdown_escape("arm|v2 <b>")
    'arm\\\\|v2 \\\\<b\\\\>'
    """
    text = " ".join(str(text).splitlines())
    return "".join("\\" + c if c in MARKDOWN_SPECIAL else c for c in text)


def _existing_ancestor(path: Path) -> Path:
    current = Path(os.path.abspath(path))
    while not os.path.lexists(current) and current != current.parent:
        current = current.parent
    return current


def check_writable(folder, option: str, shown=None) -> None:
    """Refuse, before any work, an output whose ``folder`` cannot be created or written.

    The nearest existing ancestor of ``folder`` must be a folder in which a file can be created (tried
    with an empty temporary folder, removed at once: the permission bits do not tell for root).

    Raises
    ------
    FileExistsError
        When a file stands where a folder of the path must be.
    PermissionError
        When nothing can be created there; the message names ``option`` and the fix.
    """
    shown = str(folder if shown is None else shown)
    ancestor = _existing_ancestor(Path(folder))
    if not ancestor.is_dir():
        raise FileExistsError(
            f"{option} {shown!r} needs a folder where the file {str(ancestor)!r} is; name a path in a folder."
        )
    try:
        probe = tempfile.mkdtemp(prefix=".psdm-write-check-", dir=ancestor)
    except OSError as exc:
        raise PermissionError(
            f"{option} {shown!r} is not writable: cannot create files in {str(ancestor)!r} ({exc.strerror}). "
            f"Name a folder you can write, e.g. {option} {Path.home() / Path(shown).name}."
        ) from None
    os.rmdir(probe)


def check_output_file(path, option: str, overwrite: bool, overwrite_option: str = "--overwrite") -> Path:
    """Refuse, before any work, an output file that may not be written; return it as a Path.

    Raises
    ------
    FileExistsError
        ``path`` is a folder, or exists and ``overwrite`` is false (the message names both options).
    PermissionError
        Its folder cannot be created or written.
    """
    path = Path(path).expanduser()
    if path.is_dir():
        raise FileExistsError(f"{option} {str(path)!r} is a folder; name a file, e.g. {option} {path / 'out'}.")
    if os.path.lexists(path) and not overwrite:
        raise FileExistsError(
            f"{option} {str(path)!r} exists; pass {overwrite_option} to replace it, or name a new file."
        )
    check_writable(path.parent, option, path)
    return path


def _make_parents(folder: Path) -> list:
    """Create ``folder`` and its missing parents; return the ones created, deepest first (to undo them)."""
    missing = []
    current = Path(os.path.abspath(folder))
    while not os.path.lexists(current):
        missing.append(current)
        current = current.parent
    folder.mkdir(parents=True, exist_ok=True)
    return missing


def _remove_empty(folders) -> None:
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            return


class OutputFile:
    """One output file, written into a temporary file beside it and renamed over it only at the end.

    Examples
    --------
    >>> output = OutputFile("traj.csv", option="--out")  # doctest: +SKIP
    >>> output.check(force=False)  # doctest: +SKIP
    >>> with output.staging() as path:  # doctest: +SKIP
    ...     path.write_text("t,q1\\n")
    """

    def __init__(self, target, option: str = "--out", force_option: str = "--overwrite"):
        self.target = Path(target).expanduser()
        self.option = option
        self.force_option = force_option

    def check(self, force: bool) -> None:
        """Refuse a target this run may not write, before any work (see :func:`check_output_file`)."""
        check_output_file(self.target, self.option, force, self.force_option)

    def staging(self):
        """Context manager: an empty temporary file beside the target (same suffix), renamed over it on success."""
        return _StagedFile(self.target)


class _StagedFile:
    def __init__(self, target: Path):
        self.target = target
        self.path: Path | None = None
        self.created: list = []

    def __enter__(self) -> Path:
        self.created = _make_parents(self.target.parent)
        fd, tmp = tempfile.mkstemp(
            prefix=f".{self.target.name}.partial-", suffix=self.target.suffix, dir=self.target.parent
        )
        os.close(fd)
        self.path = Path(tmp)
        return self.path

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            normalise_modes(self.path)
            os.replace(self.path, self.target)
            return False
        if os.path.lexists(self.path):
            self.path.unlink()
        _remove_empty(self.created)
        return False


class OutputFolder:
    """A folder of outputs built beside its target and moved into place only when complete.

    The rules, checked by :meth:`check` before any work:

    - the target must not be a file, the working folder or the home folder, and must be writable;
    - an existing non-empty target is refused unless ``force``; with ``force`` it may hold only
      entries this tool writes (``names``): a folder that holds anything else is refused whole;
    - with ``shared=True`` (a folder of recordings that several runs fill) other entries are kept and
      only the entries of this run are checked: existing ones are refused unless ``force``;
    - nothing is deleted but the entries this run replaces.

    The outputs are written into a fresh staging folder next to the target (hidden, unique, never an
    existing one; inside an existing shared target); :meth:`commit` moves its entries into the target,
    and an interrupted or failed run leaves the target as it was and removes only its own staging folder.

    Examples
    --------
    >>> folder = OutputFolder("report", names=("report.md",), option="--force")  # doctest: +SKIP
    >>> folder.check(force=False)  # doctest: +SKIP
    >>> with folder.staging() as stage:  # doctest: +SKIP
    ...     (stage / "report.md").write_text("...")
    """

    def __init__(self, target, names, option: str = "--force", shared: bool = False, label: str = "--out"):
        self.target = Path(target).expanduser()
        self.names = frozenset(names)
        self.option = option
        self.shared = shared
        self.label = label  # the option that names the folder, in messages

    def check(self, force: bool) -> None:
        """Refuse a target this run may not write, before any work (FileExistsError, naming the fix)."""
        target = self.target
        resolved = target.resolve()
        if not self.shared and (
            resolved in (Path.cwd().resolve(), Path.home().resolve()) or resolved == Path(resolved.anchor)
        ):
            raise FileExistsError(
                f"{self.label} {str(target)!r} is the working, home or root folder; name a new folder, "
                f"e.g. {self.label} report."
            )
        if os.path.lexists(target) and not target.is_dir():
            raise FileExistsError(
                f"{self.label} {str(target)!r} is a file; name a folder (new, or one this tool wrote)."
            )
        existing = sorted(p.name for p in target.iterdir()) if target.is_dir() else []
        if self.shared:
            self._check_shared(existing, force)
        elif existing:
            self._check_exclusive(existing, force)
        check_writable(self._staging_parent(), self.label, target)
        if target.is_dir():
            check_writable(target, self.label, target)

    def _check_exclusive(self, existing: list, force: bool) -> None:
        if not force:
            raise FileExistsError(
                f"{self.label} {str(self.target)!r} exists and is not empty; pass {self.option} to replace "
                "the files this tool wrote there, or name a new folder."
            )
        foreign = [name for name in existing if name not in self.names]
        if foreign:
            raise FileExistsError(
                f"{self.label} {str(self.target)!r} holds files this tool did not write ({_shown(foreign)}); "
                f"{self.option} replaces only its own outputs. Name a new folder."
            )

    def _check_shared(self, existing: list, force: bool) -> None:
        ours = [name for name in existing if name in self.names]
        if ours and not force:
            raise FileExistsError(
                f"{self.label} {str(self.target)!r} already holds {_shown(ours)}; pass {self.option} to replace "
                "them, or name another folder."
            )

    def _staging_parent(self) -> Path:
        if self.shared and self.target.is_dir():
            return self.target
        return Path(os.path.abspath(self.target)).parent

    def staging(self):
        """Context manager: a fresh staging folder; removed on error or interrupt, committed on success."""
        return _Staging(self)

    def commit(self, stage: Path) -> Path:
        """Move the staged entries into the target, replacing only the entries of the same names."""
        unknown = sorted(p.name for p in stage.iterdir() if p.name not in self.names)
        if unknown:  # a programming error: every output must be declared, or --force could not replace it
            raise RuntimeError(f"OutputFolder.names must list every output; {unknown} are missing.")
        normalise_modes(stage)
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


def _shown(names: list) -> str:
    return ", ".join(names[:5]) + (" ..." if len(names) > 5 else "")


class _Staging:
    def __init__(self, folder: OutputFolder):
        self.folder = folder
        self.path: Path | None = None
        self.created: list = []

    def __enter__(self) -> Path:
        parent = self.folder._staging_parent()
        self.created = _make_parents(parent)
        name = self.folder.target.name or "out"
        self.path = Path(tempfile.mkdtemp(prefix=f".{name}.partial-", dir=parent))
        return self.path

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            self.folder.commit(self.path)
        else:
            if self.path.exists():
                shutil.rmtree(self.path)
            _remove_empty(self.created)
        return False
