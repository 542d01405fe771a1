"""The recordings a refit of a model file trains on: the file's own training recordings, found again, and ``--train``.

model file (its ``provenance.recordings``, ``configurations`` and ``identification.holdout``) + the diagnosis's training
recording -> ``RefitTraining`` (the raw recordings, each one's load taken off, the ``--train`` first; the ones not
found, why, and the fix).

``diagnose MODEL --apply`` identifies the model again with its findings (``applied_model``), and the diagnosis reports
that model as its "after". Trained on ``--train`` alone, that refit forgot what the model's other training recordings
taught it (a parameter only another recording excites, a payload recording that separates a link's mass from the load)
and wrote a model worse than the file on the joints they had fixed. So the refit trains on every recording the file was
identified on, found again on disk: under the name its ``provenance.recordings`` entry gives, at the path identify read
it from, beside the model file or in the working folder, and recognised by its content (``holdout.recording_digest``,
the entry's ``sha256``). Each is read as identify read it (the file's column layout; the part identify trained on where
it held one out, ``data.holdout``), its dead torque channels marked (``missing_torque``), and the load the file's
``configurations`` block lists for it (else its sidecar) taken off its torque (``payload_check.without_load``, as the
diagnosis takes the ``--train``'s off). The ``--train`` recording is one of them when its content (or, for an entry
without a content hash, its name) is the entry's, or when the two read as the same samples (the part identify trained
on, cut into a file of its own): counted once. A recording that is gone, changed since identify, or reads otherwise is
left out and named with the fix; the refit goes on with the others. A user whose recordings moved hands them back as
further ``--train`` recordings (``diagnose MODEL --train A B``): each that is one of the file's (by content, or the same
samples) stands for it wherever it lies now; one the file does not list is added, read as the diagnosis reads
``--train``. Each recording is read once and held once (the report keeps references, not copies). Where identify moved
the training torques of joints whose friction drifted between the recordings to the friction it kept (``drift_choice``),
the files do not hold what it trained on: the refit repeats that correction on each of them from what the model file
records (``drift_correction``, ``identification.friction_drift.correction``) and says so. A recording the file does not
list has no recorded friction of its own: it is fitted beside the model on the drifting joints (``new_recording_drift``)
and moved likewise, and the written model's correction lists it. A file written before the correction was recorded
cannot repeat it, and its refit trains on ``--train`` alone and says why.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from identification.calibration.drift_correction import DriftCorrection
from identification.calibration.new_recording_drift import new_recording_friction
from identification.calibration.payload_check import without_load
from identification.calibration.payload_fit import stated_payload
from identification.calibration.recording_provenance import recording_provenance
from identification.data.configuration import NO_PAYLOAD, PayloadConfiguration, stated_configuration
from identification.data.holdout import matching_part, recording_digest, reload_part, stored_parts
from identification.data.missing_torque import find_missing_torque
from identification.data.payload import Payload
from identification.data.torque_constants import recording_kt
from psdm_casadi.errors import PSDMError

__all__ = ["MissingRecording", "RefitTraining", "listed_configuration", "refit_training", "training_alone"]

#: How the report names the recording given to the diagnosis.
GIVEN = "--train"


@dataclass(frozen=True)
class MissingRecording:
    """A training recording of the model file the refit could not use: its name, the paths looked at, and why."""

    name: str
    looked: tuple
    reason: str

    def sentence(self) -> str:
        where = ", ".join(self.looked) if self.looked else "no file (identified from a recording in memory)"
        return (
            f"{self.name}: {self.reason} (looked at {where}); the refit trained without it. Put it back "
            "beside the model file (it is recognised by its content, whatever its name) or give it as --train"
        )

    def to_dict(self) -> dict:
        return {"name": self.name, "looked": list(self.looked), "reason": self.reason, "sentence": self.sentence()}


@dataclass(frozen=True, eq=False)
class RefitTraining:
    """The recordings a refit trains on (module docstring).

    Attributes
    ----------
    recordings : tuple of Recording
        Raw, each one's load taken off its torque; the diagnosis's ``--train`` first.
    sources : tuple of str
        How the report names each (its path; the ``--train``'s marked).
    entries : tuple of dict
        Each one's ``provenance.recordings`` entry (the file's own, or a new one for a ``--train`` it did not hold):
        the written model's training recordings.
    missing : tuple of MissingRecording
        The file's training recordings left out.
    note : str
        How the refit handled a friction drift identify corrected (``drift_correction``).
    friction_drift : dict or None
        The model file's ``identification.friction_drift`` where the refit repeated its correction: the written
        model, trained on the same corrected torques, carries it, so that its own refit repeats it too.
    """

    recordings: tuple
    sources: tuple
    entries: tuple
    missing: tuple = ()
    note: str = ""
    friction_drift: dict | None = None

    def sentence(self) -> str:
        """What the refit trained on, and what it could not find (or why it left the file's recordings out)."""
        names = ", ".join(_with_samples(source, recording) for source, recording in zip(self.sources, self.recordings))
        text = f"the refit with the findings trained on {len(self.recordings)} recording(s): {names}"
        if self.missing:
            text += "; not found: " + "; ".join(m.sentence() for m in self.missing)
        return text + (f"; {self.note}" if self.note else "")

    def short(self) -> str:
        """What the refit trained on, in a few words: ``--train alone``, or the file's recordings with it."""
        given = max(1, sum(source.endswith(f"({GIVEN})") for source in self.sources))
        others = len(self.recordings) - given
        named = GIVEN if given == 1 else f"the {given} {GIVEN} recordings"
        return f"{named} alone" if not others else f"{named} and {others} training recording(s) of the model file"

    def given(self) -> tuple:
        """Whether each recording is a ``--train`` one (the diagnosis's), not only one of the model file's own."""
        return tuple(source.endswith(f"({GIVEN})") for source in self.sources)

    def to_dict(self) -> dict:
        return {"recordings": list(self.sources), "not_found": [m.to_dict() for m in self.missing],
                "note": self.note or None}  # fmt: skip


def _with_samples(source: str, recording) -> str:
    """``source`` with the samples the refit trains on (a recording identify cut with --holdout was named as if whole:
    TX40 'staubli_tx40_figaroh (--train)' beside 'training: the first 31499 samples'), unless it says them already."""
    if "samples" in source:
        return source
    count = f"{int(recording.n_samples)} samples"
    return f"{source[:-1]}; {count})" if source.endswith(f"({GIVEN})") else f"{source} ({count})"


def training_alone(train, source=None) -> RefitTraining:
    """The ``RefitTraining`` of the recording ``train`` alone, or of each of a sequence of them (a model file without
    training recordings of its own, or a caller that gives the recordings itself); ``source`` the one's path, if
    any."""
    if isinstance(train, (list, tuple)):
        parts = [training_alone(recording) for recording in train]
        return RefitTraining(*(tuple(x for p in parts for x in getattr(p, f)) for f in ("recordings", "sources",
                                                                                        "entries")))  # fmt: skip
    name = f"{source if source is not None else train.name} ({GIVEN})"
    return RefitTraining((train,), (name,), (recording_provenance(train, source),))


def refit_training(document, model_path, train, train_path, load, robot, cutoff_hz, more=(), predict=None):
    """The ``RefitTraining`` of the model file ``document`` read from ``model_path`` and the diagnosis's training
    recording ``train`` (raw, its load already taken off) read from ``train_path`` (module docstring).

    ``load(path) -> Recording`` reads a recording as identify read the file's (joint side, timed, its column layout);
    ``robot`` (the model's) and ``cutoff_hz`` (its preparation's) take a load off (``without_load``). ``more``: the
    other ``--train`` recordings as ``(path, raw recording read with load)`` (``diagnose MODEL --train A B``), or
    ``(path, its training part, HeldOutPart)`` where ``diagnose --holdout`` cut it (``holdout.other_training_parts``):
    one that is a training recording of the file (by content, or the same samples) is used in its place, read as
    identify read it (or as the diagnosis cut it), wherever it lies now; another is added, read as the diagnosis reads
    ``--train`` (its dead channels marked, the load its sidecar states taken off), and where identify corrected a
    friction drift its friction is fitted beside the model (``predict(recording) -> (prepared, predicted)``,
    ``CalibratedModel.predict_recording``; ``new_recording_drift``) and moved to the kept friction as the file's
    recordings are. A recording given twice counts once. Never raises for a recording it cannot use: that one is in
    ``RefitTraining.missing``.
    """
    entries = [e for e in ((document.get("provenance") or {}).get("recordings")) or [] if isinstance(e, dict)]
    own = _digest(train_path)
    out = training_alone(train, train_path)
    correction, moved = _drift_correction(document)
    if moved:  # identify trained on torques the files do not hold, and the file does not say how to repeat it
        extra = f"; the other {GIVEN} recording(s) are left out as well" if more else ""
        return RefitTraining(out.recordings, out.sources, out.entries, note=moved + extra)
    given, twice = _given(more, train, own)
    recordings, sources, kept, missing, added = [train], list(out.sources), list(out.entries), [], [True]
    for entry in entries:
        if _is_given(entry, train, own):  # the file's own entry: the written model names it as identify did
            where = {"path": os.path.abspath(train_path)} if own else {}
            kept[0], added[0] = dict(_trained(entry, train), **where), False
            continue
        handed = next((g for g in given if _is_given(entry, g[1], g[2])), None)
        recording, path, looked = None, None, ()
        try:
            if handed is not None and handed[3] is not None:  # diagnose --holdout cut it: its training part as cut
                given.remove(handed)
                path, looked = handed[0], (os.path.abspath(handed[0]),)
                configuration = _configuration(document, str(entry.get("name")), path)
                recording = _without_stated_load(find_missing_torque(handed[1]), configuration, document, robot,
                                                 cutoff_hz)  # fmt: skip
            elif handed is not None:  # a --train that is this recording: read as identify read it, wherever it is
                given.remove(handed)
                path, looked = handed[0], (os.path.abspath(handed[0]),)
                recording, reason = _read(path, entry, document, lambda _, r=handed[1]: r, robot, cutoff_hz)
            else:
                path, reason, looked = _find(entry, document, model_path)
                if path is not None:
                    recording, reason = _read(path, entry, document, load, robot, cutoff_hz)
        except (PSDMError, OSError, ValueError) as exc:  # unreadable, a folder in its place, a malformed entry
            reason = f"could not be read again ({(str(exc).splitlines() or [type(exc).__name__])[0]})"
        if recording is None:
            missing.append(MissingRecording(str(entry.get("name")), looked, reason))
            continue
        if _same_motion(recording, train):  # the --train under another file (a part identify trained on, cut out)
            kept[0], added[0] = entry, False
            continue
        same = next((g for g in given if _same_motion(recording, g[1])), None)
        if same is not None:  # another --train is this recording's training part, cut into a file of its own
            given.remove(same)
        recordings.append(recording)
        sources.append(path if handed is None and same is None else _source(handed or same))
        kept.append(dict(_trained(entry, recording), path=os.path.abspath(path)))  # a later refit looks there
        added.append(False)
    for path, recording, _, cut in given:  # --train recordings the model file does not list: read as --train is
        recordings.append(_read_new(path, recording, document, robot, cutoff_hz))
        sources.append(_source((path, recording, None, cut)))
        kept.append(recording_provenance(recording, path))
        added.append(True)
    note, drift = twice, None
    if correction is not None:
        recordings, corrected, drift = _corrected(correction, recordings, kept, robot, added, predict, document)
        note = "; ".join(filter(None, (corrected, twice)))
    return RefitTraining(tuple(recordings), tuple(sources), tuple(kept), tuple(missing), note, drift)


def _trained(entry, recording) -> dict:
    """The provenance ``entry`` with the samples the refit trains on (``recording``: a ``--holdout`` cut of one the
    model trained on whole holds fewer, and the written model's own refit reads it so)."""
    return dict(entry, n_samples=int(recording.n_samples), duration_s=float(recording.duration))


def _source(given) -> str:
    """How the report names a ``--train`` recording (``[path, recording, digest, HeldOutPart or None]``): its path, and
    the samples it trained on where ``diagnose --holdout`` cut it."""
    path, _, _, cut = given
    return f"{path} ({GIVEN})" if cut is None else f"{path}, its first {cut.cut_sample} samples ({GIVEN})"


def _given(more, train, digest) -> tuple:
    """``([path, recording, digest, HeldOutPart or None] of each other --train, a note on those given twice)``: one
    whose content or samples are the first's or an earlier one's counts once."""
    out, twice = [], []
    for path, recording, *cut in more:
        own = _digest(path)
        earlier = [(None, train, digest), *out]
        same = next((g for g in earlier if (own is not None and own == g[2]) or _same_motion(recording, g[1])), None)
        if same is not None:
            twice.append(f"{path} is the same recording as {GIVEN} {same[0] or 'the first'}: counted once")
            continue
        out.append([path, recording, own, cut[0] if cut else None])
    return out, "; ".join(twice)


def _read_new(path, recording, document, robot, cutoff_hz):
    """A ``--train`` recording the model file does not list, read as the diagnosis reads ``--train``: its dead torque
    channels marked, the load its sidecar states (a known one, or an unknown one the file identified by name) taken
    off."""
    return _without_stated_load(find_missing_torque(recording), stated_configuration(path), document, robot, cutoff_hz)


def _drift_correction(document) -> tuple:
    """``(DriftCorrection or None, why the file's other recordings are left out)`` where identify moved the drifting
    joints' training torques to the friction it kept (``identification.friction_drift.corrected``): the correction the
    file records, which the refit repeats; a file that records none (written before it was recorded) cannot, and read
    again raw its recordings would bring the drift back into the refit. ``(None, "")`` without a corrected drift."""
    drift = (document.get("identification") or {}).get("friction_drift") or {}
    named = drift.get("named") or []
    if not (drift.get("corrected") and named):
        return None, ""
    correction = DriftCorrection.from_dict(drift.get("correction"))
    if correction is not None:
        return correction, ""
    return None, (f"the model file's other training recordings are left out: identify moved their torques on the "
                  f"joint(s) with friction drift ({', '.join(map(str, named))}) to the friction it kept, and this file "
                  "(written before identify recorded that correction) does not say how to repeat it, so the refit "
                  "trains on --train alone; identify again to record it")  # fmt: skip


def _corrected(correction: DriftCorrection, recordings, entries, robot, added, predict, document) -> tuple:
    """``(recordings, note, friction_drift)``: each of the model file's training recordings (``entries`` their
    provenance entries) with identify's drift correction repeated (``drift_correction``); each one the file does not
    list (``added``) with its friction fitted beside the model (``predict``, ``new_recording_drift``) and moved
    likewise, or kept as it is where that cannot be done (the note says why). ``friction_drift`` is the file's block
    for the written model, its correction extended by the added recordings so that its own refit repeats it."""
    drift = dict(document["identification"]["friction_drift"])
    out, own, fitted, raw, extended = [], [], [], [], correction
    for recording, entry, new in zip(recordings, entries, added):
        kt = recording_kt(robot, recording)
        use, index, why = correction, correction.index(entry.get("name")), ""
        if new:
            rows, why = (None, "no model to fit it beside") if predict is None else new_recording_friction(
                correction, document.get("drive") or {}, *predict(recording))  # fmt: skip
            if rows is not None:
                use = correction.with_recording(str(entry.get("name")), rows)
                index, extended = len(use.recordings) - 1, extended.with_recording(str(entry.get("name")), rows)
        if index is None:
            out.append(recording)
            raw.append(f"{entry.get('name')}" + (f" ({why})" if why else ""))
            continue
        out.append(use.moved(recording, index, kt))
        (fitted if new else own).append(str(entry.get("name")))
    if extended is not correction and len(set(extended.recordings)) == len(extended.recordings):  # told apart
        drift["correction"] = extended.to_dict()
    joints = ", ".join(str(s.joint + 1) for s in correction.joints)
    note = (f"identify's friction drift correction repeated on {len(own) + len(fitted)} recording(s): their torques "
            f"on joint(s) {joints} moved to the friction the model keeps, as identify trained on them")  # fmt: skip
    if fitted:
        note += (f"; the friction of {', '.join(fitted)} (not one of the model file's training recordings) fitted "
                 "beside the model on those joints first")  # fmt: skip
    if raw:
        note += f"; {', '.join(raw)} keep(s) its own friction there (not one of identify's training recordings)"
    return out, note, drift


def _digest(path) -> str | None:
    try:
        return recording_digest(path) if path is not None and Path(path).exists() else None
    except OSError:  # unreadable: matched by name or samples only
        return None


def _is_given(entry, train, digest) -> bool:
    """Whether the entry is the ``--train`` recording: the same content, or (an entry without a content hash, from a
    recording in memory) the same name."""
    stored = entry.get("sha256")
    return stored == digest if stored else entry.get("name") == train.name


def _same_motion(recording, train) -> bool:
    """Whether two recordings hold the same samples of time and position (one recording under two files)."""
    return (
        recording.n_samples == train.n_samples
        and np.array_equal(recording.t, train.t)
        and (np.array_equal(recording.q, train.q))
    )


def _find(entry, document, model_path) -> tuple:
    """(path or None, why not, the paths looked at) of the file of a ``provenance.recordings`` entry."""
    name, stored = str(entry.get("name")), entry.get("sha256")
    if not stored:
        return None, "the model file holds no content hash of it, so it cannot be recognised on disk", ()
    parts = [p.path for p in stored_parts(document) if Path(p.path).name == name]
    folder = Path(model_path).parent if model_path is not None else None
    candidates = [entry.get("path"), *parts, folder / name if folder is not None else None, name]
    looked = tuple(dict.fromkeys(os.path.abspath(c) for c in candidates if c))
    changed = [path for path in looked if Path(path).exists()]
    for path in changed:
        if recording_digest(path) == stored:
            return path, "", looked
    if changed:
        return None, f"changed since the model was identified (its content hash is not {stored[:12]}...)", looked
    return None, "not there (moved or renamed since identify?)", looked


def _read(path, entry, document, load, robot, cutoff_hz) -> tuple:
    """(the recording at ``path`` as the model trained on it, its load taken off; or None and why not)."""
    recording = load(path)
    part = matching_part(stored_parts(document), path)
    if part is not None:  # identify trained on its first part only
        recording, _ = reload_part(part, lambda _: recording, path, "diagnose")
    expected = entry.get("n_samples")
    if expected is not None and recording.n_samples != int(expected):
        return None, (f"reads as {recording.n_samples} samples, but the model was identified on {int(expected)} "
                      "(read with other options? the same --columns, --rate and --topic as identify)")  # fmt: skip
    configuration = _configuration(document, str(entry.get("name")), path)
    return _without_stated_load(find_missing_torque(recording), configuration, document, robot, cutoff_hz), ""


def _without_stated_load(recording, configuration, document, robot, cutoff_hz):
    """``recording`` with the load ``configuration`` states taken off its torque (``without_load``), if any."""
    body, _ = stated_payload(configuration, document.get("configurations") or [], "the model file")
    if body is None:
        return recording
    kt = recording_kt(robot, recording)
    return without_load(robot, recording, body, kt, cutoff_hz)


def listed_configuration(document, path) -> PayloadConfiguration:
    """The load the recording file at ``path`` carries: its sidecar's, as the user states it now; without one, where
    its content is one of the model file ``document``'s training recordings (a ``provenance.recordings`` entry's
    ``sha256``), the configuration identify read for it (its ``configurations`` block: from a sidecar or a manifest).
    ``psdm diagnose MODEL`` reads its ``--train`` and ``--validate`` so: a recording a manifest stated has no sidecar,
    and read as unloaded its load went into the diagnosis and into the refit ``--apply`` judges."""
    own = stated_configuration(path)
    if own.stated:
        return own
    digest = _digest(path)
    entries = ((document or {}).get("provenance") or {}).get("recordings") or []
    for entry in entries:
        if digest is not None and isinstance(entry, dict) and entry.get("sha256") == digest:
            return _configuration(document, str(entry.get("name")), path)
    return own


def _configuration(document, name: str, path) -> PayloadConfiguration:
    """The load the model file's ``configurations`` block lists for the recording ``name`` (as identify read it,
    from a sidecar or a manifest); a recording it does not list: its sidecar beside ``path``."""
    for block in document.get("configurations") or []:
        if name not in (block.get("recordings") or []):
            continue
        if block.get("kind") == "unknown":
            return PayloadConfiguration(name=block["name"], unknown=True, stated=True)
        load = block.get("payload") if block.get("kind") == "known" else None
        if load is None:
            return NO_PAYLOAD
        inertia = None if load.get("inertia") is None else tuple(map(tuple, load["inertia"]))
        return PayloadConfiguration(name=block["name"], payload=Payload(float(load["mass"]), tuple(load["com"]),
                                                                        inertia), stated=True)  # fmt: skip
    return stated_configuration(path)
