"""``--holdout FRACTION``: the held-out part of one-log recordings, for ``identify``, ``validate`` and ``diagnose``.

``identify --holdout 0.3`` cuts the last 30 % off each training recording before any preparation
(``identification.data.holdout``), validates on those parts as on ``--validate`` recordings and stores where it cut in
the model file. ``validate MODEL`` (no recordings, or the training recording again) and ``diagnose MODEL --train REC``
(no ``--validate``) then reuse the stored parts: a recording is recognised by its content hash, and one changed since
identify is refused (``data.holdout.diagnose_parts``, which the Python ``diagnose_model`` uses too). ``diagnose ROBOT
--train REC --holdout 0.3`` cuts REC itself; ``diagnose MODEL --train A B --holdout 0.3`` cuts each
(``data.holdout.other_training_parts``), each held-out part a validation recording of its own.
"""

from __future__ import annotations

import sys

from identification.data.holdout import (
    check_holdout_fraction,
    cut_recording,
    matching_part,
    reload_part,
    stored_parts,
)
from psdm_casadi.errors import ParameterError

__all__ = ["add_holdout_argument", "cut_training", "holdout_fraction", "validate_parts"]

HOLDOUT_HELP = {
    "identify": "hold out the last FRACTION of each --data recording (e.g. 0.3; 0 < FRACTION < 0.9): the first part "
    "trains, the rest validates as a --validate recording does (validation report, the column checks and the "
    "counterbalance's judges; with --validate too, a choice must hold on each). Cut on the raw recording, before the "
    "filter, so no held-out sample reaches the fit; stored in the model file, so 'psdm validate MODEL' and 'psdm "
    "diagnose MODEL --train REC' reuse the same held-out part",
    "diagnose": "hold out the last FRACTION of each --train recording (e.g. 0.3; 0 < FRACTION < 0.9), cut before the "
    "filter: the first part of each trains (the first --train's is diagnosed, all join --apply's refit) and each "
    "held-out part is a validation recording of its own, so a finding must hold on each (a model identified with "
    "--holdout needs none: its stored cut of each of its training recordings is used)",
}


def add_holdout_argument(parser, command: str) -> None:
    parser.add_argument("--holdout", default=None, metavar="FRACTION", help=HOLDOUT_HELP[command])


def holdout_fraction(args) -> float | None:
    """The checked ``--holdout`` (None when not given); a bad one exits 2 naming the option and the fix."""
    return None if args.holdout is None else check_holdout_fraction(args.holdout)


def cut_training(recordings, paths, fraction: float, cutoff_hz: float | None = None) -> tuple:
    """``(training parts, held-out parts, HeldOutPart per recording)`` of ``identify --holdout``; a part too short to
    prepare at ``cutoff_hz`` is refused before any fit."""
    cuts = [cut_recording(recording, fraction, path, cutoff_hz) for recording, path in zip(recordings, paths)]
    return [c[0] for c in cuts], [c[1] for c in cuts], [c[2] for c in cuts]


def validate_parts(document, paths, load, name: str) -> list:
    """``(path, recording, HeldOutPart or None)`` of ``psdm validate``: each given recording, the held-out part of
    one the model cut (recognised by its content); with none given, every held-out part the model stores."""
    parts = stored_parts(document, name)
    if not paths:
        if not parts:
            raise ParameterError(
                f"validate {name}: no recordings given, and the model stores no held-out part (it was identified "
                "without --holdout). Pass the recordings to validate on: psdm validate MODEL.json B.csv."
            )
        return [(p.path, reload_part(p, load)[1], p) for p in parts]
    out = []
    for path in paths:
        part = matching_part(parts, path)
        out.append((path, load(path) if part is None else reload_part(part, load, path)[1], part))
        if part is not None:
            print(f"psdm validate: note: {path}: {part.describe()} by 'psdm identify --holdout'; validated on that "
                  "part only", file=sys.stderr)  # fmt: skip
        elif parts:
            print(f"psdm validate: note: {path} is none of the recordings {name} held out a part of (its content "
                  f"matches none of {', '.join(p.name for p in parts)}): validated on all its {out[-1][1].n_samples} "
                  "samples. If it is one of them edited or written again since identify, the model trained on its "
                  f"first {100 * (1 - parts[0].fraction):g} %: validate on the original, or identify again.",
                  file=sys.stderr)  # fmt: skip
    return out
