"""The friction of a model file as the nominal model of ``diagnose MODEL`` holds it: each joint by its own shape.

A calibrated-model file states its friction per joint (``drive.friction_shapes``): Coulomb-viscous, Stribeck with the
file's Stribeck velocity, or LuGre with its identified parameters (``mixed_friction``), the Coulomb sign smoothed over
the file's ``coulomb_velocity`` and the viscous term a power law where the file states one. On its steady-state joints
the diagnosis's nominal model takes exactly those columns (``trajectory_data.friction_term``, the one definition the
fit, ``psdm validate`` and the exports share), refitted on the training recording in every fit: on the file's own
training recording the refit is the file's friction again (its friction columns are free in identify's fit, so the
file's values solve their least squares given its rigid body), so the nominal model predicts the validation recording
as ``psdm validate`` predicts the file, and a candidate's gain is a gain against the file.

A LuGre joint keeps the diagnosis's LuGre columns (``nominal.friction_blocks`` of ``"lugre"``: the steady-state curve
with the file's LuGre values and the bristle dynamics, simulated at full rate and filtered like the recording, each
scaled freely), and a file with LuGre joints keeps the diagnosis's friction-like candidate columns (the exact sign
filtered like the recording): the seven LuGre parameters come from identify's shooting fit, and refitting them inside
each of the diagnosis's hundreds of candidate fits is not practical; holding the friction at the file's values leaves
no room for a finding it absorbed (a delay the bristles took up in part is then overestimated, and ``--apply``'s LuGre
refit starts from that), and the file's LuGre friction, simulated along the filtered velocity, scaled freely, does
not carry from the training recording to the validation one as these columns do. On a LuGre joint the nominal model is
therefore near the file, not equal to it (the report's table shows the file's own "before").

The friction shapes the file already has on a joint are no missing physics there (``holds``): a Stribeck peak on a
Stribeck joint (its velocity the least squares' own choice on the training data, ``calibration.stribeck``, so a peak at
another velocity is one the file's fit weighed), pre-sliding and a smooth Coulomb friction on a LuGre joint. A LuGre
joint holds what the same LuGre columns hold beside a robot file's LuGre friction (``lacking_friction_shapes``): its
bristles and its one Stribeck peak at the velocity of its parameters, not a peak at another velocity; the shooting fit
sets that velocity together with six other parameters and may leave no peak there at all (a static level below the
Coulomb one), so a peak the data hold elsewhere is offered as a candidate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.coulomb_width import widths_text
from identification.calibration.mixed_friction import file_lugre_joints
from identification.calibration.trajectory_data import friction_shapes, friction_term
from identification.diagnosis.candidates.friction import lacking_friction_shapes

__all__ = ["FileFriction"]

#: The candidate shapes (``FrictionShapeTerm.shape``) a joint of each file shape already holds (module docstring): a
#: LuGre joint every shape a Coulomb-viscous nominal lacks but those a LuGre nominal lacks too.
HELD_SHAPES = {
    "stribeck": ("stribeck",),
    "lugre": tuple(
        term.shape
        for term in lacking_friction_shapes()
        if term.shape not in {lacking.shape for lacking in lacking_friction_shapes("lugre")}
    ),
}


@dataclass(frozen=True)
class FileFriction:
    """A model file's friction per joint: ``shapes`` (``"coulomb-viscous"``, ``"stribeck"``, ``"lugre"``), the Coulomb
    smoothing ``coulomb_velocity`` [rad/s] per joint (``coulomb_width``), the Stribeck velocity per joint
    ``stribeck_velocity`` [rad/s] (0: none), the viscous exponent per joint ``viscous_exponent`` (1: linear) and the
    LuGre parameters per joint ``lugre`` (``LuGreParameters``; None on a steady-state joint)."""

    shapes: tuple
    coulomb_velocity: tuple
    stribeck_velocity: tuple
    viscous_exponent: tuple
    lugre: tuple

    @classmethod
    def of_model(cls, calibrated) -> FileFriction:
        """The friction of a ``CalibratedModel``."""
        drive, n = calibrated.document["drive"], calibrated.n_dof
        lugre = calibrated.lugre_parameters or (None,) * n
        joints = file_lugre_joints(calibrated.document, n)
        vs = [float(v) for v in (drive.get("stribeck_velocity") or [0.0] * n)]
        steady = friction_shapes(drive.get("friction_terms", ()), vs, n)  # no Stribeck column: Coulomb-viscous
        shapes = tuple("lugre" if j in joints else steady[j] for j in range(n))
        return cls(shapes=shapes, coulomb_velocity=tuple(calibrated.coulomb_widths.tolist()),
                   stribeck_velocity=tuple(vs[j] if shapes[j] == "stribeck" else 0.0 for j in range(n)),
                   viscous_exponent=tuple(float(v) for v in (drive.get("viscous_exponent") or [1.0] * n)),
                   lugre=tuple(lugre))  # fmt: skip

    @property
    def kind(self) -> str:
        """The diagnosis's friction kind of the columns (``nominal.FRICTION_MODELS``): ``"lugre"`` with a LuGre joint
        (three steady-state columns per joint and one of the bristle dynamics), else ``"stribeck"`` (three) where a
        joint has a Stribeck velocity, else ``"coulomb_viscous"`` (two)."""
        if self.lugre_joints:
            return "lugre"
        return "stribeck" if any(v > 0 for v in self.stribeck_velocity) else "coulomb_viscous"

    @property
    def lugre_joints(self) -> tuple:
        """The joints (0-based) of the file's LuGre friction."""
        return tuple(j for j, p in enumerate(self.lugre) if p is not None)

    def columns(self, qd: np.ndarray, lugre: np.ndarray | None = None, joints=None) -> np.ndarray:
        """The file's friction columns (n_samples, n_dof, p) at the velocities ``qd`` (n_samples, n_dof), in the layout
        of ``nominal.friction_blocks`` for ``kind`` (joint-major ``fc``, for ``"stribeck"`` and ``"lugre"`` the hump
        ``fs - fc``, ``fv``; for ``"lugre"`` then one bristle-dynamics column per joint): on each steady-state joint of
        ``joints`` (default all) the sign ``tanh(qd / coulomb_velocity)``, the hump ``exp(-(qd / vs)^2)`` times it
        (zero without a Stribeck velocity) and the file's viscous column; a LuGre joint's are those of ``lugre`` (the
        diagnosis's ``"lugre"`` columns, same layout; module docstring); zero elsewhere."""
        qd = np.asarray(qd, dtype=float)
        n_samples, n = qd.shape
        k = 2 if self.kind == "coulomb_viscous" else 3
        out = np.zeros((n_samples, n, n * k + (n if self.kind == "lugre" else 0)))
        for j in range(n) if joints is None else joints:
            if self.lugre[j] is not None:
                out[:, j, [j * k, j * k + 1, j * k + 2, n * k + j]] = lugre[
                    :, j, [j * k, j * k + 1, j * k + 2, n * k + j]
                ]
                continue
            v, dv = self.coulomb_velocity[j], self.viscous_exponent[j]
            out[:, j, j * k] = friction_term("fc", qd[:, j], v)
            out[:, j, j * k + k - 1] = friction_term("fv", qd[:, j], v, None, None if dv == 1.0 else dv)
            if k == 3 and self.stribeck_velocity[j] > 0:
                out[:, j, j * k + 1] = friction_term("fs", qd[:, j], v, self.stribeck_velocity[j])
        return out

    def zero_columns(self) -> tuple:
        """The columns (0-based, layout of ``columns``) that are zero by construction: the hump of a steady-state joint
        without a Stribeck velocity, and a steady-state joint's bristle-dynamics column (no column of the fit: the
        nominal model's rank is the file's)."""
        n, k = len(self.shapes), 2 if self.kind == "coulomb_viscous" else 3
        steady = [j for j in range(n) if self.lugre[j] is None]
        out = [j * k + 1 for j in steady if k == 3 and self.stribeck_velocity[j] == 0.0]
        if self.kind == "lugre":
            out += [n * k + j for j in steady]
        return tuple(sorted(out))

    def holds(self, term) -> bool:
        """Whether the file already holds the friction shape of candidate ``term`` on its joint (a
        ``FrictionShapeTerm``: a Stribeck peak of a Stribeck joint, pre-sliding of a LuGre joint, ...)."""
        shape = getattr(term, "shape", None)
        if term.key not in ("friction_shape", "presliding") or term.joint is None:
            return False
        return shape in HELD_SHAPES.get(self.shapes[term.joint], ())

    def describe(self) -> str:
        """``"the model file's per-joint (Coulomb-viscous on joints 1, 2; Stribeck on joint 3 ...)"``: what the report's
        nominal-model line names, before "friction fitted on the training recording"."""
        names = {"coulomb-viscous": "Coulomb-viscous", "stribeck": "Stribeck", "lugre": "LuGre"}
        parts = []
        for shape, name in names.items():
            joints = [j + 1 for j, s in enumerate(self.shapes) if s == shape]
            if joints:
                parts.append(f"{name} on joint{'s' if len(joints) > 1 else ''} {', '.join(map(str, joints))}")
        power = [j + 1 for j, dv in enumerate(self.viscous_exponent) if dv != 1.0 and self.lugre[j] is None]
        if power:
            parts.append(f"viscous power law on joint{'s' if len(power) > 1 else ''} {', '.join(map(str, power))}")
        smooth = f"Coulomb sign smoothed over {widths_text(self.coulomb_velocity)}"
        return f"the model file's per-joint ({'; '.join(parts)}; {smooth})"
