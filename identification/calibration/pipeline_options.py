"""Options of the calibration pipeline: filter cutoffs, rates, splits and the documented choices of each step.

The reasons for the defaults are in :mod:`identification.calibration.pipeline`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.refinement import RefinementOptions
from identification.data.excitation_check import ExcitationThresholds
from psdm_casadi.errors import ParameterError

__all__ = ["PipelineOptions"]


@dataclass(frozen=True)
class PipelineOptions:
    """Options of :class:`IdentificationPipeline`.

    Parameters
    ----------
    motor_cutoff_hz, gravity_cutoff_hz, inertial_cutoff_hz : float
        Butterworth cutoffs [Hz] (paper: 4, 4, 15).
    friction_cutoff_hz : float or None
        Cutoff of the friction data [Hz] (paper 40); None (default) uses them unfiltered (module docstring).
    split_fraction : float
        Training share (paper 0.85).
    n_blocks : int
        Contiguous blocks of the split of the folded motor and gravity sweeps (``Recording.split``),
        so their validation part covers the whole sweep rather than its end.
    gravity_rate_hz, inertial_rate_hz, friction_rate_hz, refinement_rate_hz : float
        Rates [Hz] the filtered data is decimated to before the regression (the regressor
        evaluation and the shooting NLP grow with the samples; the filters remove what decimation
        would alias). ``friction_rate_hz`` defaults to 1 kHz: the pre-sliding loops need every sample.
    gravity_inertia : {"nominal", "identified", "none"}
        Which model removes the jog's inertial and Coriolis torques before eq. 18 (module docstring):
        the robot's nominal inertias (default; "none" when the robot has no links), the step-4
        estimate in a second pass, or none (the paper).
    gravity_friction : {"identified", "folded"}
        ``"identified"`` (default): after step 3, step 2 runs again on the jog with the identified
        LuGre friction (simulated along its measured velocity) removed before folding; ``"folded"``:
        folding alone cancels friction (the paper). Folding cancels only the part of the friction that
        is odd in the velocity at mirrored samples; the rest (the bristle state and the joints' speed
        changes along the jog) biases the smallest gravity parameters even without noise.
    friction_coupling : {"nominal", "none"}
        ``"nominal"`` (default; "none" when the robot has no links): the robot's nominal inertias
        remove the torques the held joints' accelerations couple into the moving joint of a friction
        experiment (``FrictionIdentifier.coupling_theta``; they ring with it after every stick).
    refine : bool
        Run the joint Ipopt refinement after the four steps.
    refinement : RefinementOptions
    shooting_options : identification.friction.shooting.ShootingOptions or None
        Default ``ShootingOptions(measurement="central-difference")`` (``"sample"`` when the friction
        data is decimated or ``held_torque`` is False): the fit compares the friction model with
        what the measurement averages (``identification.friction.measurement``), which the damping
        sigma1 of the heavy base joints needs.
    held_torque : bool
        Currents are set-points held over the next sample period (``FrictionIdentifier.held_torque``).
    consistency_samples : int
        Random configurations of the mass-matrix check.
    seed : int
        Seed of the consistency configurations.
    quiet : bool
        No progress lines (they go to the module's logger at INFO otherwise).
    excitation : ExcitationThresholds
        Thresholds of the excitation checks (:mod:`identification.calibration.excitation`): every raw
        recording before step 1, then every step's data and regressor, are refused when what the step
        identifies does not move (defaults and their reasons in ``ExcitationThresholds``).
    """

    motor_cutoff_hz: float = 4.0
    gravity_cutoff_hz: float = 4.0
    friction_cutoff_hz: float | None = None
    inertial_cutoff_hz: float = 15.0
    split_fraction: float = 0.85
    n_blocks: int = 4
    gravity_rate_hz: float = 50.0
    inertial_rate_hz: float = 200.0
    friction_rate_hz: float = 1000.0
    refinement_rate_hz: float = 50.0
    gravity_inertia: str = "nominal"
    gravity_friction: str = "identified"
    friction_coupling: str = "nominal"
    refine: bool = True
    refinement: RefinementOptions = RefinementOptions()
    shooting_options: object = None
    held_torque: bool = True
    consistency_samples: int = 200
    seed: int = 0
    quiet: bool = False
    excitation: ExcitationThresholds = ExcitationThresholds()

    def __post_init__(self):
        for name in (
            "motor_cutoff_hz",
            "gravity_cutoff_hz",
            "friction_cutoff_hz",
            "inertial_cutoff_hz",
            "gravity_rate_hz",
            "inertial_rate_hz",
            "friction_rate_hz",
            "refinement_rate_hz",
        ):
            value = getattr(self, name)
            if value is None and name == "friction_cutoff_hz":
                continue
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"PipelineOptions.{name} must be positive [Hz]; got {value!r}.")
        if not isinstance(self.excitation, ExcitationThresholds):
            raise ParameterError(
                f"PipelineOptions.excitation must be an ExcitationThresholds; got {type(self.excitation).__name__}. "
                "Pass ExcitationThresholds(...)."
            )
        if not 0.0 < self.split_fraction < 1.0:
            raise ParameterError(f"PipelineOptions.split_fraction must be in (0, 1); got {self.split_fraction!r}.")
        if self.gravity_friction not in ("identified", "folded"):
            raise ParameterError(
                f"PipelineOptions.gravity_friction must be 'identified' or 'folded'; got {self.gravity_friction!r}."
            )
        if self.friction_coupling not in ("nominal", "none"):
            raise ParameterError(
                f"PipelineOptions.friction_coupling must be 'nominal' or 'none'; got {self.friction_coupling!r}."
            )
        if self.gravity_inertia not in ("nominal", "identified", "none"):
            raise ParameterError(
                f"PipelineOptions.gravity_inertia must be 'nominal', 'identified' or 'none'; got "
                f"{self.gravity_inertia!r}."
            )
