"""The demo's sizes (``DemoOptions``), its result and the state one run passes from step to step."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

logger = logging.getLogger("psdm_casadi.demo")

DENSO_FILE = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"
REPORT_FORMAT = "psdm-demo-report/1"

#: Everything the demo writes into its report folder (``--overwrite`` replaces these and nothing else).
REPORT_ENTRIES = (
    "report.md",
    "report.html",
    "speed.md",
    "summary.json",
    "excitation.png",
    "validation_before.png",
    "validation_after.png",
    "c_code",
    "diagnosis",
    "speed",
)


@dataclass(frozen=True)
class DemoOptions:
    """Sizes of the demo; ``quick()`` gives the sub-minute version used in tests.

    Parameters
    ----------
    robot_file : Path
    seed : int
        Seeds every random choice (excitation starts, noise, poses): same seed, same report.
    excitation_duration : float
        Period of the optimised Fourier excitation [s].
    excitation_harmonics, excitation_starts : int
    excitation_repeats : int
        Periods recorded (the first for identification and diagnosis training, the last for validation).
    gravity_duration : float
        [s] of the gravity jog.
    friction_amplitudes : tuple of float
        Friction experiment amplitudes [rad].
    spring_joint : int
        0-based joint carrying the hidden spring (3: joint 4, the wrist cable harness).
    spring_stiffness : float
        [N m/rad].
    spring_rest : float
        Rest angle [rad].
    compile_flags : tuple of str
    speed_states : int
        Random states of the C speed comparison with Pinocchio (0: skip it). It runs in a separate
        process on the second core while the experiments are simulated and identified.
    quiet : bool
    refine : bool
        Run the joint Ipopt refinement after the four steps (both calibrations).
    """

    robot_file: Path = DENSO_FILE
    seed: int = 0
    excitation_duration: float = 10.0
    excitation_harmonics: int = 4
    excitation_starts: int = 2
    excitation_repeats: int = 3
    gravity_duration: float = 40.0
    friction_amplitudes: tuple = (2e-4, 1e-3, 5e-3, 0.03, 0.15, 0.6)
    spring_joint: int = 3
    spring_stiffness: float = 6.0
    spring_rest: float = 0.4
    compile_flags: tuple = ("-O2",)
    speed_states: int = 300_000
    quiet: bool = False
    refine: bool = True

    @classmethod
    def quick(cls, **changes) -> DemoOptions:
        """A short version: short experiments, one excitation start, no refinement, no speed run."""
        base = cls(
            excitation_duration=6.0,
            excitation_harmonics=3,
            excitation_starts=1,
            excitation_repeats=2,
            gravity_duration=16.0,
            friction_amplitudes=(1e-3, 0.03, 0.3),
            compile_flags=("-O1",),
            speed_states=0,
            refine=False,
        )
        return replace(base, **changes)


@dataclass(frozen=True)
class DemoResult:
    """What the demo measured; ``summary`` is also written as ``summary.json`` in the report folder."""

    folder: Path
    summary: dict = field(default_factory=dict)


@dataclass
class DemoRun:
    """The state one demo run passes from step to step: where it writes, its random stream, what it measured."""

    options: DemoOptions
    stage: Path
    rng: np.random.Generator
    summary: dict
    timings: dict = field(default_factory=dict)

    def say(self, message: str) -> None:
        if not self.options.quiet:
            logger.info("[demo] %s", message)

    def warn(self, message: str) -> None:
        """A warning the user must see: logged at WARNING even when quiet."""
        logger.warning("[demo] %s", message)

    def timed(self, name: str, start: float) -> float:
        self.timings[name] = time.perf_counter() - start
        return self.timings[name]
