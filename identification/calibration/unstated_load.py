"""A training recording that carries a load no file states: identified as an unknown payload of its own, and said.

A user who mounts a gripper for one recording and not for the others, and writes no sidecar, hands identify one arm
fitted across two loads: the links absorb the load's torque, a counterbalance the links could have named hides behind
it, and joints the model explains on neither recording are blamed on swapped columns. The fit already finds such a
recording (``configuration_check``: a flange body of its own drops its residual far beyond its noise, its mass many
standard deviations from zero) and used to warn only, leaving the wrong model as the default's answer. Here, before
the route's choices, one unconstrained fit looks for such recordings; each heavier one whose load nobody stated (no
sidecar, no manifest entry; a sidecar ``{"mass": 0}`` is a statement and is kept) becomes an unknown payload of its
own, identified with the arm as a stated ``{"unknown": ...}`` would be, and the report says so with the fix to state
it. A recording only the lighter one looks different in (every heavier one stated, or none heavier) is left to the
warning: which recordings carry the load is not known then.

On a 210 kg-class arm with an unstated 85 kg gripper on one of two training traces (``benchmarks/unseen_arms.py``,
``heavy_trace_percent``) the gripper is identified within a per cent and the counterbalance its torque hid is named.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from identification.data.configuration import NO_PAYLOAD, PayloadConfiguration, sidecar_path

__all__ = ["UnstatedLoads", "take_unstated_loads", "unstated_label"]


def unstated_label(name: str) -> str:
    """The configuration name of the load a recording ``name`` carries unstated: ``unstated load (trace_002.csv)``."""
    return f"unstated load ({Path(name).name})"


@dataclass(frozen=True)
class UnstatedLoads:
    """The training recordings whose unstated load identify took as an unknown payload (``found``: their
    ``configuration_check.LoadedRecording``, the mass the detection fit saw), or the reason none was taken."""

    found: tuple = ()
    reason: str = ""

    def describe(self) -> str:
        """One sentence per recording taken (empty when none was)."""
        return "; ".join(
            f"{f.name} carries {f.mass:.3g} +- {f.mass_std:.2g} kg at the flange that no sidecar states (a flange "
            f"body of its own drops its residual {100 * f.residual_drop:.0f} %): identified as the unknown payload "
            f"'{unstated_label(f.name)}' (see its mass below); state it in {sidecar_path(f.name).name} if it is known "
            '({"mass": M, "com": [x, y, z]}), or write {"mass": 0} there if the recording carries nothing'
            for f in self.found
        )

    @property
    def line(self) -> str:
        """The report's line (``UNSTATED LOAD: ...``; empty when none was taken)."""
        return f"UNSTATED LOAD: {self.describe()}" if self.found else ""

    def to_dict(self) -> dict:
        """The model file's ``identification.unstated_loads`` block."""
        return {
            "taken": [
                {
                    "recording": f.name,
                    "configuration": unstated_label(f.name),
                    "mass": float(f.mass),
                    "mass_std": float(f.mass_std),
                    "residual_drop": float(f.residual_drop),
                }
                for f in self.found
            ],  # fmt: skip
            "reason": self.reason,
        }


def take_unstated_loads(fit_of, recordings, configurations) -> tuple:
    """``(configurations, UnstatedLoads)``: each training recording that looks loaded against the others and whose
    load nobody stated given an unknown payload of its own (module docstring).

    Parameters
    ----------
    fit_of : callable
        ``fit_of(configurations) -> TrajectoryFit``: an unconstrained fit of the training recordings whose
        ``loaded`` lists the recordings that look loaded (``configuration_check.loaded_recordings``).
    recordings : sequence of Recording
        The training recordings (their ``name`` is what ``loaded`` names).
    configurations : sequence of PayloadConfiguration or None
        What each recording carries as the user stated it (None: nothing stated anywhere).
    """
    configurations = list(configurations) if configurations is not None else [NO_PAYLOAD] * len(recordings)
    if len(recordings) < 2:
        return configurations, UnstatedLoads(reason="one training recording: nothing to compare its load with")
    if all(c.stated for c in configurations):
        return configurations, UnstatedLoads(reason="every training recording's load is stated")
    loaded = fit_of(configurations).loaded
    names = [r.name for r in recordings]
    taken, out = [], list(configurations)
    for found in loaded:
        if found.mass <= 0 or found.name not in names:
            continue
        k = names.index(found.name)
        if configurations[k].stated:
            continue
        out[k] = PayloadConfiguration(name=unstated_label(found.name), unknown=True, stated=True)
        taken.append(found)
    if not taken:
        reason = "no recording looks loaded against the others"
        if loaded:
            reason = "the recordings that look different are stated or lighter (the warning names them)"
        return configurations, UnstatedLoads(reason=reason)
    return out, UnstatedLoads(found=tuple(taken), reason="taken as unknown payloads (identify's default)")
