"""The held-out part of a recording: ``--holdout FRACTION`` cuts the last part of a one-log recording off.

A shared real dataset is often one recording. Validation needs motion the model was not fitted to, so the last
``FRACTION`` of each training recording is held out: the first ``n_train = int(round(1 - FRACTION, 12) * n)`` samples
train, the rest validate (in time order; at a steady sample rate the last ``FRACTION`` of the time, the cut the
benchmarks and the documentation's hand-cut files make). The cut is made on the raw, joint-side recording, before any
preparation: each part is filtered and differentiated on its own (each with the edges its preparation trims), so no
held-out sample reaches a training sample through the low-pass filter or the differences, and both parts are prepared
as the model file says.

A :class:`HeldOutPart` records which recording was cut where: its path, the content hash of the whole recording (its
bytes; a folder's files by relative name, then contents), its samples and the cut's sample and time. The model file
stores them (``identification.holdout``, :func:`holdout_block`), so ``psdm validate MODEL`` and ``psdm diagnose MODEL
--train REC`` reuse the same held-out part (:func:`reload_part`), and a recording changed since (another hash) is
refused rather than judged on other samples. ``psdm diagnose MODEL --train REC`` and the Python
``diagnosis.model_file.diagnose_model(MODEL, REC)`` find the parts through the one :func:`diagnose_parts`.

``psdm diagnose MODEL --train A B ... --holdout F`` cuts every training recording as it cuts the first
(:func:`other_training_parts`): a user who asks for the last ``F`` of the data held out means every recording's, not
the first's only (before, the others trained whole in the refit and none of their motion was judged). Each held-out
part is a validation recording of its own, so a finding must hold on each (the findings-that-hold rule of several
``--validate`` recordings): the parts are different motions, and a gain pooled over them would let one outvote another.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass
from pathlib import Path

from identification.data.filter_choice import EDGE_PERIODS, choose_filter, edge_samples
from identification.data.recording import MIN_SAMPLES
from psdm_casadi.errors import ModelFileError, ParameterError, RecordingError

__all__ = ["HOLDOUT_MAX", "HeldOutPart", "check_holdout_fraction", "check_parts_long_enough", "cut_recording",
           "diagnose_parts", "held_out_sentences", "holdout_block", "matching_part", "other_part",
           "other_training_parts", "recording_digest", "reload_part", "shortest_part", "stored_parts",
           "train_samples", "training_part"]  # fmt: skip

#: The largest held-out fraction: at least a tenth of a recording trains.
HOLDOUT_MAX = 0.9
BLOCK = 1 << 20


def check_holdout_fraction(fraction, option: str = "--holdout") -> float:
    """``fraction`` as a float in (0, :data:`HOLDOUT_MAX`), else a ``ParameterError`` naming ``option`` and the fix."""
    try:
        value = float(fraction)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and 0.0 < value < HOLDOUT_MAX):
        raise ParameterError(
            f"{option} must be the share of each recording held out for validation, between 0 and {HOLDOUT_MAX:g} "
            f"(exclusive); got {fraction!r}. Use e.g. {option} 0.3: the last 30 % validates, the first 70 % trains."
        )
    return value


def train_samples(n_samples: int, fraction: float) -> int:
    """The training samples of a recording of ``n_samples`` with ``fraction`` held out (module docstring)."""
    return int(round(1.0 - fraction, 12) * n_samples)


def recording_digest(path) -> str:
    """SHA-256 (hex) of a recording file, or of a folder's files (a split recording, a ROS 2 bag): names relative to
    it, then contents."""
    path = Path(path)
    digest = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for member in files:
        if path.is_dir():
            digest.update(member.relative_to(path).as_posix().encode() + b"\0")
        with open(member, "rb") as handle:
            while block := handle.read(BLOCK):
                digest.update(block)
    return digest.hexdigest()


@dataclass(frozen=True)
class HeldOutPart:
    """Where a recording was cut: samples ``cut_sample`` .. ``n_samples - 1`` (from ``cut_time_s``) are held out.

    ``path`` is the recording's absolute path, ``sha256`` the digest of the whole recording
    (:func:`recording_digest`), ``fraction`` the share asked for."""

    path: str
    sha256: str
    fraction: float
    n_samples: int
    cut_sample: int
    cut_time_s: float

    @property
    def name(self) -> str:
        return Path(self.path).name

    def describe(self) -> str:
        """``"the last 30 % of run.csv (samples 700-999 of 1000, t >= 7 s), held out"``."""
        return (f"the last {100 * self.fraction:g} % of {self.name} (samples {self.cut_sample}-{self.n_samples - 1} "
                f"of {self.n_samples}, t >= {self.cut_time_s:.6g} s), held out")  # fmt: skip

    def to_dict(self) -> dict:
        return {"path": self.path, "name": self.name, "sha256": self.sha256, "fraction": self.fraction,
                "n_samples": self.n_samples, "cut_sample": self.cut_sample, "cut_time_s": self.cut_time_s}  # fmt: skip

    @classmethod
    def from_dict(cls, entry, where: str = "identification.holdout.recordings") -> HeldOutPart:
        """The part of a model file's entry; a malformed one raises ``ModelFileError`` naming ``where``."""
        try:
            part = cls(str(entry["path"]), str(entry["sha256"]), float(entry["fraction"]), int(entry["n_samples"]),
                       int(entry["cut_sample"]), float(entry["cut_time_s"]))  # fmt: skip
        except (KeyError, TypeError, ValueError):
            part = None
        if part is None or not (MIN_SAMPLES <= part.cut_sample <= part.n_samples - MIN_SAMPLES):
            raise ModelFileError(
                f"{where} must hold path, sha256, fraction, n_samples and cut_sample (at least {MIN_SAMPLES} samples "
                f"on each side) and cut_time_s; got {str(entry)[:120]}. Re-run 'psdm identify --holdout'."
            )
        return part

    def matches(self, path) -> bool:
        """Whether ``path`` holds this recording: the same content hash."""
        return Path(path).exists() and recording_digest(path) == self.sha256


def shortest_part(recording, cutoff_hz: float | None = None) -> int:
    """The fewest samples a part of ``recording`` may hold and still be prepared: filtered at ``cutoff_hz`` (default
    identify's choice for its rate), ``EDGE_PERIODS`` filter periods trimmed at each end, three samples left."""
    rate = (recording.n_samples - 1) / max(float(recording.t[-1] - recording.t[0]), 1e-12)
    cutoff, step = choose_filter(rate, cutoff_hz)
    edge = edge_samples(rate, cutoff, EDGE_PERIODS) + 1  # a part's rate may round its trim up by one sample
    return max(MIN_SAMPLES, 2 * edge + 2 * step + 1)


def check_parts_long_enough(recording, fraction: float, path, cutoff_hz: float | None = None) -> None:
    """Refuse a cut that leaves a part too short to prepare, before any work: a ``RecordingError`` naming the part,
    its length, the recording and the fractions that would do (or, for a recording too short to cut at all, the
    routes that use it whole)."""
    n = recording.n_samples
    cut = train_samples(n, fraction)
    shortest = shortest_part(recording, cutoff_hz)
    if min(cut, n - cut) >= shortest:
        return
    name, seconds = Path(path).name, n / max(n - 1, 1) * float(recording.t[-1] - recording.t[0])
    short, length = ("held-out", n - cut) if n - cut < cut else ("training", cut)
    need = shortest * seconds / n
    if n >= 2 * shortest + 2:
        low, high = math.ceil(100 * shortest / n) / 100, math.floor(100 * (1 - (shortest + 1) / n)) / 100
        fix = (f"Use --holdout between {low:g} and {high:g} for it, or pass it with --validate instead of --data "
               "(it then validates whole)")  # fmt: skip
    else:
        fix = (f"No --holdout leaves two such parts of its {seconds:.3g} s: pass it with --validate instead of "
               "--data (it then validates whole), or leave it out")  # fmt: skip
    raise RecordingError(
        f"--holdout {fraction:g} leaves {length * seconds / n:.3g} s of {name} ({seconds:.3g} s) as its {short} part "
        f"({length} of {n} samples), too short to prepare: each part needs at least {need:.3g} s ({shortest} samples) "
        f"to be low-pass filtered and have its first and last {EDGE_PERIODS} filter periods trimmed. {fix}; "
        "--holdout cuts every --data recording."
    )


def cut_recording(recording, fraction: float, path, cutoff_hz: float | None = None) -> tuple:
    """``(training part, held-out part, HeldOutPart)`` of a raw recording read from ``path`` (module docstring).

    Raises
    ------
    RecordingError
        When a part would be too short to prepare at ``cutoff_hz`` (``check_parts_long_enough``).
    """
    check_parts_long_enough(recording, fraction, path, cutoff_hz)
    n = recording.n_samples
    cut = train_samples(n, fraction)
    part = HeldOutPart(os.path.abspath(path), recording_digest(path), float(fraction), n, cut, float(recording.t[cut]))
    return recording.slice(0, cut), recording.slice(cut, None), part


def holdout_block(parts) -> dict:
    """The model file's ``identification.holdout`` block of the held-out parts (one per training recording cut)."""
    parts = list(parts)
    return {"fraction": parts[0].fraction if parts else None, "recordings": [p.to_dict() for p in parts]}


def stored_parts(document, name: str = "model file") -> tuple:
    """The :class:`HeldOutPart` of each recording a model file's identification held out (empty: none, or a file
    written without ``--holdout``)."""
    block = (document.get("identification") or {}).get("holdout")
    if block is None:
        return ()
    entries = block.get("recordings") if isinstance(block, dict) else None
    if not isinstance(entries, list):
        raise ModelFileError(f"{name}: identification.holdout must be an object with a list 'recordings'; got "
                             f"{str(block)[:80]}. Re-run 'psdm identify --holdout'.")  # fmt: skip
    return tuple(HeldOutPart.from_dict(e, f"{name}: identification.holdout.recordings[{k}]")
                 for k, e in enumerate(entries))  # fmt: skip


#: How each command is given a moved recording again, and other recordings to validate on.
PASS_AGAIN = {
    "validate": ("psdm validate MODEL NEW/PATH/{name}", "psdm validate MODEL B.csv"),
    "diagnose": ("psdm diagnose MODEL --train NEW/PATH/{name}", "--validate B.csv"),
}


def reload_part(part: HeldOutPart, load, path=None, command: str = "validate") -> tuple:
    """``(training part, held-out part)`` of the recording a model file cut, read again with ``load(path)`` from
    ``path`` (default the stored one), after checking that its content is the one the model was identified on.
    ``command`` (``validate`` or ``diagnose``) words the fix for a recording that is gone.

    Raises
    ------
    RecordingError
        When the recording is gone, or changed since (another content hash, or another sample count).
    """
    path = part.path if path is None else str(path)
    if not Path(path).exists():
        again, other = (form.format(name=part.name) for form in PASS_AGAIN[command])
        raise RecordingError(
            f"{path}: the recording whose last {100 * part.fraction:g} % the model held out is not there any more "
            f"(moved or renamed since identify?). Pass it from where it is now ({again}; it is recognised by its "
            f"content, whatever its name), or validate on other recordings ({other})."
        )
    digest = recording_digest(path)
    if digest != part.sha256:
        raise RecordingError(
            f"{path} changed since the model was identified (its content hash is {digest[:12]}..., the model file "
            f"holds {part.sha256[:12]}...): its held-out part ({part.describe()}) is not the data the model was judged "
            "on. Restore the recording, or identify again on it (psdm identify ... --holdout), or validate on it "
            "as a new recording under another name."
        )
    recording = load(path)
    if recording.n_samples != part.n_samples:
        raise RecordingError(
            f"{path} reads as {recording.n_samples} samples, but the model cut it at {part.n_samples} (same content, "
            "read with other options?). Read it as identify did (the same --columns, --rate, --topic)."
        )
    return recording.slice(0, part.cut_sample), recording.slice(part.cut_sample, None)


def matching_part(parts, path):
    """The stored part of the recording at ``path`` (the same path, or the same content under another), else None.
    The same path with other content is returned too: ``reload_part`` then refuses it as changed since identify."""
    where = os.path.abspath(path)
    return next((p for p in parts if p.path == where), None) or next((p for p in parts if p.matches(path)), None)


def diagnose_parts(train_path, train, document, fraction, load, explicit: bool, name: str) -> tuple:
    """``(training recording, [(path, held-out recording, HeldOutPart)])`` of a diagnosis (``psdm diagnose``, and
    ``diagnose_model`` from Python): the training recording ``train`` read from ``train_path``, cut where the model
    file ``document`` cut it (or at ``fraction``, ``--holdout``), and, without validation recordings given
    (``explicit`` False), the other held-out parts the model stores, each read with ``load(path)``."""
    parts = stored_parts(document, name) if document is not None else ()
    own = matching_part(parts, train_path)
    held = []
    if own is not None:
        _check_same_cut(fraction, own, train_path, name)
        train, part = reload_part(own, lambda _: train, train_path, "diagnose")
        held.append((train_path, part, own))
    elif fraction is not None:
        train, part, cut = cut_recording(train, fraction, train_path)
        held.append((train_path, part, cut))
    if not explicit:
        held += [(p.path, other_part(p, load, train_path, name), p) for p in parts if p is not own]
    return train, held


def other_training_parts(more, document, fraction, explicit: bool, name: str) -> tuple:
    """``(the other --train recordings for the refit, [(path, held-out recording, HeldOutPart)])`` of ``psdm diagnose
    MODEL --train A B ... [--holdout F]`` (``more``: ``(path, raw recording)`` of B ...), each cut as
    :func:`diagnose_parts` cuts the first (module docstring): where the model file cut it, its held-out part validates
    and it is given raw (the refit cuts it as identify did, ``refit_training``); else at ``fraction`` its first part
    trains, given as ``(path, training part, HeldOutPart)``, and its last validates; else it trains whole. A part the
    model stores is listed once: without ``explicit`` validation recordings :func:`diagnose_parts` lists it."""
    parts = stored_parts(document, name) if document is not None else ()
    training, held = [], []
    for path, recording in more:
        own = matching_part(parts, path)
        if own is not None:
            _check_same_cut(fraction, own, path, name)
            training.append((path, recording))
            if explicit:
                held.append((path, reload_part(own, lambda _, r=recording: r, path, "diagnose")[1], own))
        elif fraction is not None:
            train, part, cut = cut_recording(recording, fraction, path)
            training.append((path, train, cut))
            held.append((path, part, cut))
        else:
            training.append((path, recording))
    return training, held


def training_part(entry, document, name: str):
    """The part of an entry of :func:`other_training_parts`'s training list the diagnosis trains on: a part cut at
    ``--holdout`` as it is; a recording the model file ``document`` cut, its training part (:func:`reload_part`); else
    the whole recording."""
    if len(entry) == 3:
        return entry[1]
    path, recording = entry
    own = matching_part(stored_parts(document, name) if document is not None else (), path)
    return recording if own is None else reload_part(own, lambda _: recording, path, "diagnose")[0]


def _check_same_cut(fraction, own, path, name: str) -> None:
    """Refuse a ``--holdout`` other than the model file's own cut of the recording at ``path``."""
    if fraction is not None and abs(fraction - own.fraction) > 1e-12:
        raise ParameterError(
            f"--holdout {fraction:g}: {name} was identified on the first {100 * (1 - own.fraction):g} % of "
            f"{path}; {own.describe()}: another cut would train on samples it validated on, or validate "
            "on samples it trained on. Drop --holdout: the model's own cut is used."
        )


def other_part(part, load, train_path, name: str):
    """The held-out part of a recording the model cut other than ``--train``; when it is gone, the message says too
    that ``--train`` is not it (its content matches none the model cut: moved and edited, or another recording)."""
    try:
        return reload_part(part, load, command="diagnose")[1]
    except RecordingError as exc:
        raise RecordingError(
            f"--train {train_path} is not the recording {name} held out a part of ({part.name}: its content differs), "
            f"so it trains whole and the validation is that part of {part.name}. {exc}"
        ) from None


def held_out_sentences(train_paths, held) -> tuple:
    """The report's sentences on which parts ``diagnose_parts`` (and ``other_training_parts``) held out (``held``;
    none: no sentence) of the training recordings ``train_paths`` (one path, or several: ``--train A B``)."""
    paths = [train_paths] if isinstance(train_paths, (str, os.PathLike)) else list(train_paths)
    lines = [f"validation: {part.describe()}" for _, _, part in held]
    cut = {os.path.abspath(path): part for path, _, part in held}
    own = [f"training: the first {cut[os.path.abspath(p)].cut_sample} samples of {p}" for p in paths
           if os.path.abspath(p) in cut]  # fmt: skip
    return tuple(own) + tuple(lines)
