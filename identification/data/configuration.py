"""Payload configurations: which load each recording carries at the flange (none, a known one, an unknown one).

A robot is often recorded empty, with a calibration mass and with its tool. The identification
(``identification.calibration.payload_fit``) shares the arm's parameters across these
configurations: a known payload's torques are subtracted, each unknown one is identified as a body
fixed to the flange, the same in every recording that names it.

The user states a recording's payload in one of two ways:

- a sidecar file beside the recording, ``A.payload.json`` for ``A.csv`` (the payload.json of the
  four-step route): ``{"mass": 2.8, "com": [0, 0, 0.05]}`` (known, optional ``"inertia"`` about the
  centre of mass), ``{"unknown": "gripper"}`` (unknown, the same in every file that says
  ``gripper``) or ``{"mass": 0}`` (none);
- a configuration manifest ``--data configurations.toml`` listing the recordings of each
  configuration (paths relative to the manifest), for recordings one may not write beside::

      [[configuration]]
      name = "empty"
      recordings = ["empty_1.csv", "empty_2.csv"]

      [[configuration]]
      name = "calibration mass"
      payload = {mass = 2.8, com = [0.0, 0.0, 0.05]}   # or "mass.payload.json"
      recordings = ["mass_1.csv"]

      [[configuration]]
      name = "gripper"
      payload = "unknown"
      recordings = ["gripper_1.csv", "gripper_2.csv"]

A recording that states nothing carries no payload (and the fit checks that it does not look loaded).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import tomllib

from identification.data.payload import Payload, payload_from_mapping, read_payload
from psdm_casadi.errors import ParameterError
from psdm_casadi.text_file import read_text_file
from psdm_casadi.values import format_value

__all__ = [
    "NO_PAYLOAD",
    "PayloadConfiguration",
    "recordings_with_configurations",
    "sidecar_path",
    "stated_configuration",
]

MANIFEST_EXAMPLE = '[[configuration]]\nname = "gripper"\npayload = "unknown"\nrecordings = ["a.csv", "b.csv"]'
SIDECAR_EXAMPLE = '{"mass": 2.8, "com": [0, 0, 0.05]} (known), {"unknown": "gripper"} or {"mass": 0} (none)'


@dataclass(frozen=True)
class PayloadConfiguration:
    """The load a recording carries at the flange (last link frame).

    Parameters
    ----------
    name : str
        The configuration's label; the recordings of one unknown payload share it.
    payload : Payload or None
        The known load (its torques are subtracted); None for no load or an unknown one.
    unknown : bool
        An unknown load, identified as a body fixed to the flange (the same in every recording named ``name``).
    stated : bool
        Whether the user said it (a sidecar or a manifest); False for the default, no payload.
    """

    name: str = "none"
    payload: Payload | None = None
    unknown: bool = False
    stated: bool = False

    def __post_init__(self):
        if self.unknown and self.payload is not None:
            raise ParameterError(
                f"PayloadConfiguration {self.name!r} is unknown and known at once; give payload= or unknown=True."
            )

    @property
    def kind(self) -> str:
        """``"none"``, ``"known"`` or ``"unknown"``."""
        if self.unknown:
            return "unknown"
        return "known" if self.payload is not None and self.payload.mass > 0 else "none"


NO_PAYLOAD = PayloadConfiguration()


def sidecar_path(recording_path) -> Path:
    """``A.payload.json`` for ``A.csv`` (a bag folder ``run/`` has ``run.payload.json`` beside it)."""
    path = Path(recording_path)
    stem = path.name[: -len(path.suffix)] if path.suffix else path.name
    return path.with_name(f"{stem}.payload.json")


def stated_configuration(recording_path) -> PayloadConfiguration:
    """The configuration the sidecar of a recording states (``A.payload.json``, or ``A.csv.payload.json`` named
    after the whole file), or no payload without one.

    Raises
    ------
    ParameterError
        For a sidecar under a near-miss name (``A_payload.json``, ``A-payload.json``, ``A.Payload.json``): read
        silently as none, its load would go into the arm's links.
    """
    sidecar = sidecar_path(recording_path)
    whole = Path(recording_path).with_name(f"{Path(recording_path).name}.payload.json")
    for candidate in (sidecar, whole):
        if candidate.is_file():
            return _sidecar(candidate)
    _refuse_near_miss(sidecar)
    return NO_PAYLOAD


def _refuse_near_miss(sidecar: Path) -> None:
    stem = sidecar.name[: -len(".payload.json")]
    for name in (f"{stem}_payload.json", f"{stem}-payload.json", f"{stem}.Payload.json", f"{stem}.payload.JSON"):
        if (sidecar.parent / name).is_file() and name != sidecar.name:
            raise ParameterError(
                f"{name} beside recording {stem} is not read: a recording's payload is stated in {sidecar.name} "
                f"(without it the load goes into the arm's links). Rename {name} to {sidecar.name}."
            )


def _sidecar(path: Path) -> PayloadConfiguration:
    """The configuration a sidecar file states (module docstring)."""
    text = read_text_file(path, what="payload file", error=ParameterError)
    try:
        data = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise ParameterError(f"{path.name} must be JSON such as {SIDECAR_EXAMPLE}; got {exc}. Fix it.") from None
    if isinstance(data, dict) and "unknown" in data:
        label = data["unknown"]
        if set(data) != {"unknown"} or not isinstance(label, str) or not label.strip():
            raise ParameterError(
                f'{path.name}: an unknown payload is {{"unknown": "LABEL"}} alone (the label names the payload '
                f'the recordings share); got {format_value(data)}. Write e.g. {{"unknown": "gripper"}}.'
            )
        return PayloadConfiguration(name=label.strip(), unknown=True, stated=True)
    if not isinstance(data, dict):
        raise ParameterError(
            f"{path.name} must hold a JSON object such as {SIDECAR_EXAMPLE}; got {format_value(data)}."
        )
    payload = read_payload(path)
    return _known(payload, f"{payload.mass:g} kg ({path.name})")


def _known(payload: Payload, name: str) -> PayloadConfiguration:
    if payload.mass == 0:
        return PayloadConfiguration(name="none", stated=True)
    return PayloadConfiguration(name=name, payload=payload, stated=True)


def _manifest_payload(value, name: str, where: str, folder: Path) -> PayloadConfiguration:
    """The ``payload`` of one manifest entry: absent/"none", "unknown", a table, or a payload.json path."""
    if value is None or value == "none":
        return PayloadConfiguration(name=name, stated=True)
    if value == "unknown":
        return PayloadConfiguration(name=name, unknown=True, stated=True)
    if isinstance(value, dict):
        return _known(payload_from_mapping(value, f"{where} payload"), name)
    if isinstance(value, str) and value.endswith(".json"):
        return _known(read_payload(folder / value), name)
    raise ParameterError(
        f'{where}: payload must be "none", "unknown", a table {{mass = 2.8, com = [0, 0, 0.05]}} or a '
        f'payload.json path; got {format_value(value)}. Write e.g. payload = "unknown".'
    )


def _read_manifest(path: Path) -> list:
    """[(recording path, PayloadConfiguration)] of a configuration manifest (module docstring)."""
    text = read_text_file(path, what="configuration manifest", error=ParameterError)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{path.name} is not TOML ({exc}); write it as\n{MANIFEST_EXAMPLE}") from None
    entries = data.get("configuration")
    extra = sorted(set(data) - {"configuration"})
    if extra or not isinstance(entries, list) or not entries:
        raise ParameterError(
            f"{path.name} must hold [[configuration]] tables only; got {sorted(data)}. Write\n{MANIFEST_EXAMPLE}"
        )
    out, seen = [], set()
    for k, entry in enumerate(entries):
        where = f"{path.name} configuration {k + 1}"
        if not isinstance(entry, dict):
            raise ParameterError(f"{where} must be a [[configuration]] table; got {format_value(entry)}. Write\n"
                                 f"{MANIFEST_EXAMPLE}")  # fmt: skip
        unknown = sorted(set(entry) - {"name", "payload", "recordings"})
        name, files = entry.get("name"), entry.get("recordings")
        if unknown:
            raise ParameterError(f"{where} has unknown key(s) {unknown}; allowed: name, payload, recordings.")
        if not isinstance(name, str) or not name.strip() or name in seen:
            raise ParameterError(f"{where}: name must be a new, non-empty text; got {format_value(name)}. "
                                 'Write name = "gripper".')  # fmt: skip
        if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
            raise ParameterError(f"{where}: recordings must be a list of file names; got {format_value(files)}. "
                                 'Write recordings = ["a.csv", "b.csv"].')  # fmt: skip
        seen.add(name)
        configuration = _manifest_payload(entry.get("payload"), name, where, path.parent)
        out += [(path.parent / f, configuration) for f in files]
    return out


def recordings_with_configurations(paths, option: str = "--data") -> tuple[list, list]:
    """(recording paths, one PayloadConfiguration each) of ``--data``: manifests expanded, sidecars read.

    A ``.toml`` entry is a configuration manifest; any other path is a recording, whose configuration
    is its sidecar ``A.payload.json`` when there is one, else no payload (not stated).

    Raises
    ------
    ParameterError
        Naming the file, the field and the fix: a manifest or sidecar that does not parse, a payload out of
        range, a recording listed twice, a recording with both a manifest entry and a sidecar that disagree.
    """
    recordings, configurations = [], []
    for item in paths:
        item = Path(item)
        if item.suffix.lower() == ".toml":
            for path, configuration in _read_manifest(item):
                recordings.append(path)
                configurations.append(configuration)
            continue
        recordings.append(item)
        configurations.append(stated_configuration(item))
    resolved = [p.resolve() for p in recordings]
    twice = sorted({str(p) for p, r in zip(recordings, resolved) if resolved.count(r) > 1})
    if twice:
        raise ParameterError(f"{option} lists {twice} more than once; give each recording once (in one configuration).")
    _check_unknown_labels(configurations)
    return recordings, configurations


def _check_unknown_labels(configurations) -> None:
    """A label names one payload: it must not be both unknown and something else."""
    kinds = {}
    for configuration in configurations:
        kinds.setdefault(configuration.name, set()).add(configuration.kind)
    for name, found in kinds.items():
        if "unknown" in found and len(found) > 1:
            raise ParameterError(
                f"payload {name!r} is unknown in some recordings and {sorted(found - {'unknown'})} in others; "
                "give every configuration its own name."
            )
