"""Reading an input file's text (robot file, URDF, payload.json): one clear error per way a file can be unreadable.

The robot-file reader (``robot_file``), the URDF reader (``urdf``) and the payload reader of
``identification.data.payload`` call :func:`read_text_file` before they parse anything, so that a
directory, an unreadable file, compressed or binary data or a non-UTF-8 byte is reported naming the
file and the fix instead of as a traceback.
"""

from __future__ import annotations

import codecs
from pathlib import Path

from psdm_casadi.errors import ParameterError, RobotFileError

__all__ = ["read_text_file"]

# Magic numbers of the compressed and archive formats a text file is most often confused with.
_COMPRESSED = {
    b"\x1f\x8b": ("gzip-compressed data", "Decompress it first (gunzip)"),
    b"PK\x03\x04": ("a ZIP archive", "Unpack it first and give the text file it holds"),
    b"BZh": ("bzip2-compressed data", "Decompress it first (bunzip2)"),
    b"\xfd7zXZ\x00": ("xz-compressed data", "Decompress it first (unxz)"),
    b"\x28\xb5\x2f\xfd": ("zstd-compressed data", "Decompress it first (unzstd)"),
}


def read_text_file(path, *, what: str = "robot file", error: type = RobotFileError, decode: bool = True) -> str:
    """The text of ``path``, or ``error`` naming the file and the fix.

    Parameters
    ----------
    path : str or Path
    what : str
        What the file should be, for the message ("robot file", "URDF", "payload file").
    error : type
        The ParameterError subclass to raise (RobotFileError for robot files).
    decode : bool
        Decode as UTF-8 (a byte-order mark is dropped). ``False`` only checks that the file is a
        readable, uncompressed, non-binary file and returns ``""`` (an XML file may declare
        another encoding).

    Returns
    -------
    str

    Raises
    ------
    ParameterError
        (of class ``error``) for a directory, a missing or unreadable file, compressed or binary
        data, or bytes that are not UTF-8.
    """
    if not issubclass(error, ParameterError):
        raise TypeError(f"read_text_file error must be a ParameterError subclass; got {error!r}.")
    path = Path(path)
    name = path.name or str(path)
    if path.is_dir():
        raise error(f"{what} {name!r} must be a file; got a directory. Give the path of the {what} inside it.")
    try:
        data = path.read_bytes()
    except PermissionError:
        raise error(f"{what} {name!r} must be readable; got permission denied. Check the file's permissions.") from None
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise error(f"{what} {name!r} must be a readable file; got {reason!r}. Check the path.") from None
    for magic, (kind, fix) in _COMPRESSED.items():
        if data.startswith(magic):
            raise error(f"{what} {name!r} must be plain text; got {kind}. {fix}.")
    if b"\x00" in data[:8192]:
        raise error(f"{what} {name!r} must be plain text; got a binary file (it holds NUL bytes). Give the text file.")
    if not decode:
        return ""
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8) :]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        before = data[: exc.start]
        line = before.count(b"\n") + 1
        column = exc.start - (before.rfind(b"\n") + 1) + 1
        raise error(
            f"{what} {name!r} must be UTF-8 text; got byte 0x{data[exc.start]:02x} at line {line}, column {column} "
            "(a Latin-1 or Windows-1252 character?). Save the file as UTF-8."
        ) from None
