"""Beyond the library: the function library and the sparse term of a joint whose residual stays structured.

After the selection and refinement of the named terms (``diagnose``), each joint's training residual is
regressed on a larger function library of the joint's own state (``sparse_features``): products of a
position factor (1, a cubic polynomial in the centred angle, sines and cosines of 1-3 times the angle)
with a velocity factor (1, the velocity sign), low-speed humps ``sign(qd) exp(-(qd/v)^2)`` of several
widths, ``qd``, ``qd |qd|``, ``qdd``, and single lobes of the angle (``u exp(-u^2/2)`` and ``exp(-u^2/2)``,
``u = (q - c) / s``: a cam, a detent, a counterbalance acting over part of the travel) whose centre and width
the search (``sparse_fit``) picks from the recording. The kept sum is an unnamed effect with its formula
(``SparseTerm``), a CasADi expression of (q, qd, qdd) like every other term, so the augmented model, the model
file (``SparseTerm.spec``) and the exported code carry it.

Why not pysindy's feature libraries: the velocity-sign columns must be filtered like the recording (see
``context``) and every feature must also exist as a CasADi expression; the feature set is therefore
written out here, and pysindy provides the sparse optimiser (``sparse_fit``).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from identification.diagnosis.candidates.base import SMOOTH_VELOCITY, CandidateTerm, joint_columns, joint_expression
from psdm_casadi.errors import ParameterError

HUMP_VELOCITIES = (0.05, 0.1, 0.2, 0.4)  # [rad/s] widths of the low-speed hump features
HARMONICS = (1, 2, 3)  # sines and cosines of these multiples of the angle
POLY_DEGREE = 3  # polynomial of the centred angle


@dataclass(frozen=True)
class SparseFeature:
    """One feature ``position factor x velocity factor`` of a joint.

    ``position``: ``("one", 0)``, ``("poly", p)`` (``(q - centre)^p``), ``("sin", k)`` or ``("cos", k)`` (of ``k q``),
    ``("lobe", 0)`` (``exp(-u^2/2)``) or ``("lobe", 1)`` (``u exp(-u^2/2)``), ``u = (q - lobe_centre) / lobe_width``;
    ``velocity``: ``"one"``, ``"sign"``, ``"hump"`` (``sign(qd) exp(-(qd/width)^2)``), ``"qd"``, ``"qd_abs"``
    (``qd |qd|``) or ``"qdd"``.
    """

    position: tuple
    velocity: str
    width: float = 0.0
    lobe_centre: float = 0.0
    lobe_width: float = 0.0

    def __post_init__(self):
        if self.position[0] == "lobe" and not self.lobe_width > 0:
            raise ParameterError(
                f"SparseFeature.lobe_width must be positive for a lobe [rad]; got {self.lobe_width!r}."
            )

    def name(self, joint: int) -> str:
        q, qd = f"q{joint + 1}", f"qd{joint + 1}"
        kind, order = self.position
        u = f"(({q}-{self.lobe_centre:.4g})/{self.lobe_width:.4g})"
        pos = {
            "one": "",
            "poly": f"(dq{joint + 1})" + ("" if order == 1 else f"^{order}"),
            "sin": f"sin({order if order != 1 else ''}{q})",
            "cos": f"cos({order if order != 1 else ''}{q})",
            "lobe": ("" if order == 0 else u + " ") + f"exp(-{u}^2/2)",
        }[kind]
        vel = {
            "one": "",
            "sign": f"sign({qd})",
            "hump": f"sign({qd}) exp(-({qd}/{self.width:g})^2)",
            "qd": qd,
            "qd_abs": f"{qd}|{qd}|",
            "qdd": f"qdd{joint + 1}",
        }[self.velocity]
        return " ".join(x for x in (pos, vel) if x) or "1"

    def position_factor(self, q, centre: float, lib=np):
        """The position factor on angles ``q`` (an array with ``lib=np``, a CasADi expression with ``lib=casadi``);
        ``centre`` is the term's polynomial centre [rad]."""
        kind, order = self.position
        if kind == "one":
            return 1.0 + 0.0 * q
        if kind == "poly":
            return (q - centre) ** order
        if kind == "lobe":
            u = (q - self.lobe_centre) / self.lobe_width
            return (u if order == 1 else 1.0) * lib.exp(-0.5 * u * u)
        return lib.sin(order * q) if kind == "sin" else lib.cos(order * q)


def sparse_features(lobes=()) -> tuple:
    """The function library of one joint (see the module docstring), in a fixed order, with ``lobes``
    (``(lobe_centre, lobe_width)`` pairs [rad], each giving the odd and the even lobe) at its end."""
    positions = [("one", 0)] + [("poly", p) for p in range(1, POLY_DEGREE + 1)]
    positions += [(kind, k) for k in HARMONICS for kind in ("sin", "cos")]
    out = [SparseFeature(p, v) for v in ("one", "sign") for p in positions]
    out += [SparseFeature(("one", 0), "hump", w) for w in HUMP_VELOCITIES]
    out += [SparseFeature(("one", 0), v) for v in ("qd", "qd_abs", "qdd")]
    out += [
        SparseFeature(("lobe", parity), "one", lobe_centre=float(c), lobe_width=float(w))
        for c, w in lobes
        for parity in (1, 0)
    ]
    return tuple(out)


@dataclass(frozen=True)
class SparseTerm(CandidateTerm):
    """An unnamed effect on one joint: a sparse sum of library features with fitted coefficients.

    Parameters
    ----------
    joint : int
    features : tuple of SparseFeature
        The features the sparse regression kept.
    centre : float
        Centre of the angle polynomials [rad] (the training recording's mean angle).
    """

    joint: int | None = None
    features: tuple = ()
    centre: float = 0.0

    key = "unnamed_effect"
    explanation = "a torque outside the library of named effects, found by sparse regression"
    signature = "residual still structured (not white, correlated with the joint's state) after the library's terms"
    per_joint = False

    def __post_init__(self):
        if not self.features:
            raise ParameterError("SparseTerm.features must hold at least one SparseFeature; got none.")

    @property
    def joints(self) -> tuple:
        return (int(self.joint),)

    @property
    def label(self) -> str:
        return f"{self.key}[j{self.joint + 1}]"

    def feature_names(self) -> list:
        return [f.name(self.joint) for f in self.features]

    def columns(self, context) -> np.ndarray:
        """Columns on a ``DiagnosisContext`` (the velocity signs filtered like the recording); on a context of the
        joint state only (``t, q, qd, qdd``, as the calibration's) the smooth sign of ``casadi_expression``."""
        if not hasattr(context, "friction_sign"):
            j = self.joint
            values = self.smooth_values(context.q[:, j], context.qd[:, j], context.qdd[:, j], np)
            return joint_columns(context, j, np.column_stack([v + 0.0 * context.q[:, j] for v in values]))
        return joint_columns(context, self.joint, feature_matrix(context, self.joint, self.features, self.centre))

    def smooth_values(self, qj, qdj, qddj, lib=ca) -> list:
        """Each feature's value on the joint with the smooth sign ``tanh(qd / SMOOTH_VELOCITY)``, for arrays
        (``lib=np``) or CasADi scalars (``lib=ca``): the model-file form of the term."""
        fabs = lib.fabs if lib is ca else np.abs
        s = lib.tanh(qdj / SMOOTH_VELOCITY)
        out = []
        for feature in self.features:
            pos = feature.position_factor(qj, self.centre, lib)
            vel = {
                "one": 1.0,
                "sign": s,
                "hump": s * lib.exp(-((qdj / max(feature.width, 1e-12)) ** 2)),
                "qd": qdj,
                "qd_abs": qdj * fabs(qdj),
                "qdd": qddj,
            }[feature.velocity]
            out.append(pos * vel)
        return out

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        j = self.joint
        total = 0
        for value, c in zip(self.smooth_values(q[j], qd[j], qdd[j]), coefficients):
            total = total + float(c) * value
        return joint_expression(q.shape[0], j, total)

    def formula(self, coefficients) -> str:
        """``tau_j += c1 f1 + c2 f2 ...`` with the coefficients in SI units (N m per feature unit)."""
        parts = [f"{float(c):+.4g} {name}" for c, name in zip(coefficients, self.feature_names())]
        return (
            f"tau{self.joint + 1} += "
            + " ".join(parts)
            + (f"  (dq{self.joint + 1} = q{self.joint + 1} - {self.centre:.4g} rad)" if self._has_poly else "")
        )

    @property
    def _has_poly(self) -> bool:
        return any(f.position[0] == "poly" for f in self.features)

    def interpret(self, coefficients) -> tuple:
        return self.key, f"{self.explanation}: {self.formula(coefficients)}"


def feature_matrix(context, joint: int, features, centre: float) -> np.ndarray:
    """The features of ``joint`` on a ``DiagnosisContext``'s grid, (n_samples, n_features).

    Velocity-sign features are built at full rate with the exact sign and filtered like the recording
    (``DiagnosisContext.friction_sign``); the full-rate angle is interpolated from the grid."""
    q, qd, qdd = context.q[:, joint], context.qd[:, joint], context.qdd[:, joint]
    full_q = np.interp(context.full_t, context.t, q)
    full_qd = (context.full_qd if getattr(context, "sign_qd", None) is None else context.sign_qd)[:, joint]
    out = np.empty((context.n_samples, len(features)))
    for c, f in enumerate(features):
        if f.velocity in ("sign", "hump"):
            factor = f.position_factor(full_q, centre)
            if f.velocity == "hump":
                factor = factor * np.exp(-((full_qd / f.width) ** 2))
            out[:, c] = context.friction_sign(joint, np.broadcast_to(factor, full_qd.shape), sharp=True)
        else:
            vel = {"one": 1.0, "qd": qd, "qd_abs": qd * np.abs(qd), "qdd": qdd}[f.velocity]
            out[:, c] = f.position_factor(q, centre) * vel
    return out
