"""AugmentedModel: the nominal PSDM model plus the missing physics found by ``diagnose``, buildable as a CasADi
Function.

Terms that change base parameters (payload, rotor inertia) are folded into ``theta`` (a rotor inertia the
base parameters have no place for, as on a URDF robot without drive inertias, is a torque ``Im qdd_j``
instead, never dropped); friction and the
additive terms (spring, offset, ripple, asymmetry, drift, load-dependent friction, coupling) become
CasADi expressions; signal-level effects (delay, backlash, joint elasticity) and the gravity tilt are
kept as reported parameters (``signal_corrections``) because they are not a torque of (q, qd, qdd, t).
``build_function`` returns ``augmented_inverse_dynamics(q, qd, qdd, t) -> tau``, which
``Function.save`` writes and the code generator can export like any other CasADi Function.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from identification.calibration.held_friction import HeldFriction
from identification.diagnosis.candidates import joint_expression
from identification.diagnosis.candidates.base import SMOOTH_VELOCITY
from identification.diagnosis.nominal import friction_casadi
from psdm_casadi.fileio import atomic_write


@dataclass(frozen=True, eq=False)
class AugmentedModel:
    """Nominal model + found terms. ``theta`` are the base parameters before the terms' changes. ``parameter_map``:
    the model's with the flange body's block (``carried_payload.flange_parameter_map``: a payload on a robot whose
    flange link the model does not hold goes to the last link it does); None: the model's own. ``held_friction``: the
    friction a model file holds (``held_friction.HeldFriction``, in the file's own form), beside the fitted one, whose
    coefficients on the held joints are 0. ``coulomb_velocity``: the smoothing of the fitted friction's sign (a model
    file's, ``DiagnosisOptions.coulomb_velocity``)."""

    model: object
    theta: np.ndarray
    friction_kind: str
    friction_coefficients: np.ndarray
    friction_vs: np.ndarray
    friction_dv: np.ndarray
    terms: tuple
    coefficients: tuple
    parameter_map: np.ndarray | None = None
    held_friction: HeldFriction = HeldFriction()
    coulomb_velocity: float | tuple = SMOOTH_VELOCITY

    @property
    def terms_map(self) -> np.ndarray:
        """The parameter map the terms' base-parameter changes go through (``parameter_map`` or the model's)."""
        return np.asarray(self.model.parameter_map if self.parameter_map is None else self.parameter_map, dtype=float)

    @property
    def theta_augmented(self) -> np.ndarray:
        """Base parameters with the payload and rotor-inertia changes folded in."""
        theta = np.array(self.theta, dtype=float)
        for term, c in zip(self.terms, self.coefficients):
            change = term.theta_change(c, self.terms_map)
            if change is not None:
                theta = theta + change
        return theta

    def outside_theta(self, term, coefficients) -> bool:
        """Whether a rotor-inertia term has no place in the base parameters (its theta change is zero)."""
        if term.key != "rotor_inertia":
            return False
        change = term.theta_change(coefficients, self.terms_map)
        return change is not None and not np.any(change) and float(coefficients[0]) != 0.0

    @property
    def signal_corrections(self) -> dict:
        """Found terms that are not part of the torque function: label -> physical parameters."""
        q = ca.SX.sym("q", self.model.n_dof)
        out = {}
        for term, c in zip(self.terms, self.coefficients):
            if (
                term.theta_change(c, self.terms_map) is None
                and term.casadi_expression(q, q, q, ca.SX.sym("t"), q, c) is None
                and not self.outside_theta(term, c)
            ):
                out[term.label] = term.physical_parameters(c)
        return out

    def build_function(self) -> ca.Function:
        """``augmented_inverse_dynamics(q, qd, qdd, t) -> tau`` (CasADi, SX)."""
        from psdm_casadi.recursive import build_recursive_functions
        from psdm_casadi.symbolic import build_functions

        n = self.model.n_dof
        q, qd, qdd = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd"))
        t = ca.SX.sym("t")
        if self.model.has_monomials:
            fns = build_functions(self.model, self.theta_augmented)
        else:  # derived without monomial table (beyond 8 joints): the model carries its joint tree
            fns = build_recursive_functions(self.model, None, self.theta_augmented)
        tau_rigid = fns.inverse_dynamics(q, qd, qdd)
        tau = tau_rigid + friction_casadi(
            self.friction_kind,
            qd,
            self.friction_coefficients,
            self.friction_vs,
            self.friction_dv,
            self.coulomb_velocity,
        )
        if self.held_friction.values:
            tau = tau + self.held_friction.expression(qd, qdd)
        nominal = tau
        for term, c in zip(self.terms, self.coefficients):
            extra = term.casadi_expression(q, qd, qdd, t, nominal, c)
            if extra is None and self.outside_theta(term, c):
                extra = joint_expression(n, term.joint, float(c[0]) * qdd[term.joint])
            if extra is not None:
                tau = tau + extra
        return ca.Function(
            "augmented_inverse_dynamics", [q, qd, qdd, t], [tau], ["q", "qd", "qdd", "t"], ["tau"], {"cse": True}
        )

    def describe(self) -> dict:
        return {
            "format": "psdm-augmented/1",
            "robot": self.model.robot_name,
            "theta": self.theta.tolist(),
            "theta_augmented": self.theta_augmented.tolist(),
            "base_names": list(self.model.base_names),
            "friction": {
                "kind": self.friction_kind,
                "coefficients": self.friction_coefficients.tolist(),
                "vs": self.friction_vs.tolist(),
                "dv": self.friction_dv.tolist(),
                "held": dict(self.held_friction.values),
                "held_coulomb_velocity": self.held_friction.coulomb_velocity,
                "held_viscous_exponent": list(self.held_friction.viscous_exponent),  # [] linear viscous
                "coulomb_velocity": self.coulomb_velocity,
            },
            "terms": [
                {
                    "effect": term.key,
                    "label": term.label,
                    "features": term.feature_names(),
                    "coefficients": np.asarray(c).tolist(),
                    "parameters": term.physical_parameters(c),
                }
                for term, c in zip(self.terms, self.coefficients)
            ],
            "signal_corrections": self.signal_corrections,
        }

    def save(self, directory, overwrite: bool = False) -> dict:
        """Write ``augmented_model.json`` (parameters) and ``augmented_inverse_dynamics.casadi`` (Function.save)."""
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        text = json.dumps(self.describe(), indent=2, default=float)
        paths = {
            "augmented_json": atomic_write(
                directory / "augmented_model.json", lambda h: h.write(text + "\n"), overwrite=overwrite
            )
        }
        function = self.build_function()
        target = directory / "augmented_inverse_dynamics.casadi"
        if target.exists() and not overwrite:
            raise FileExistsError(f"{str(target)!r} exists; pass overwrite=True (or --overwrite) to replace it.")
        tmp = directory / ".augmented_inverse_dynamics.casadi.tmp"
        function.save(str(tmp))
        tmp.replace(target)
        paths["augmented_function"] = target
        return paths
