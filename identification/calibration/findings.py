"""Findings as model terms: the torques and measurement corrections a diagnosis adds to a calibrated model.

calibrated model -> diagnose -> **findings** -> recalibrate -> calibrated model with findings -> export.

A finding of the diagnosis becomes one :class:`FindingTerm`, of one of four kinds:

- ``torque``: an additive torque of the state, linear in its coefficients, identified jointly with the
  rigid body and the drives (``recalibrate``), and part of the model's torque everywhere
  (``CalibratedModel.predict``, the exported CasADi/C functions): spring ``[q_j, 1]``, torque offset
  ``[1]``, position ripple ``[sin(h q_j), cos(h q_j)]``, coupling ``[qd_k, qdd_k]`` on joint j, Coulomb
  asymmetry ``[(1 + tanh(qd_j / v)) / 2]``, rotor inertia ``[qdd_j]`` and load-dependent friction
  ``[|tau_j| tanh(qd_j / v)]``, where ``tau`` is the model's own torque without the load-dependent
  terms (never the measurement, so the model predicts); a spring of any order, a gas spring's lever law, an
  unnamed effect (a sparse formula of the joint state), a friction shape a Coulomb-viscous model lacks (a Stribeck
  peak ``exp(-(qd/vs)^2) tanh(qd/v)``, a smooth Coulomb ``tanh(qd/v)``) and a counterbalance written as one finding
  (``[1, sin(h q_j), cos(h q_j)]``, ``counterbalance_finding``) are stored by their candidate term's spec
  (``CandidateTerm.spec``) and their columns are that term's own (``term_from_spec``), the ones the diagnosis fitted;
- ``rigid_body``: a payload (or a last link lighter than the file says): a change of the standard
  parameters, absorbed by the recalibrated rigid body;
- ``signal``: a delay of the torque signal behind the motion, and an encoder that reads the motor side of
  a compliant joint or of a play (joint elasticity, backlash): corrections of the measurement
  (:func:`correct_recording`) that the recalibration and ``psdm validate`` apply alike; they are not a
  torque of the state, so the exported code does not hold them;
- ``reported``: stored with its parameters but not applied (gravity tilt, whose torque the base
  parameters of the robot file's gravity direction cannot hold; friction drift, a function of the time
  since the start of a recording).

The one definition of every column (:func:`term_values`) serves numbers and CasADi expressions alike, so
the fit, the prediction and the exported code cannot differ.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np

from identification.calibration.extra_terms import TermContext
from identification.calibration.held_friction import CONSTANT_FEATURE
from identification.data.recording import Recording
from identification.diagnosis.term_spec import term_from_spec
from identification.physical_bounds import POSITIVE_FRICTION_SHAPES
from psdm_casadi.errors import ModelFileError, ParameterError

__all__ = [
    "FINDING_KINDS",
    "HELD_KEY",
    "FindingColumns",
    "FindingTerm",
    "correct_recording",
    "filled_entries",
    "finding_kind",
    "held_findings",
    "offsets_left_to_findings",
    "physical_parameters",
    "term_values",
]

TORQUE_EFFECTS = (
    "spring",
    "torque_offset",
    "torque_ripple",
    "coupling",
    "coulomb_asymmetry",
    "rotor_inertia",
    "load_dependent_friction",
    "unnamed_effect",
    "gas_spring",
    "friction_shape",
    "counterbalance",
)
# torque findings whose columns are their candidate term's (a spec): a spring of any order, a gas spring's lever law,
# a friction shape, a counterbalance written as one finding (its constant and its bend, ``counterbalance_finding``)
SPEC_EFFECTS = ("spring", "unnamed_effect", "gas_spring", "friction_shape", "counterbalance")
RIGID_BODY_EFFECTS = ("payload", "last_link_mass_excess")
SIGNAL_EFFECTS = ("delay", "joint_elasticity", "backlash")
FINDING_KINDS = ("torque", "rigid_body", "signal", "reported")
#: The key of a torque entry a refit holds at its coefficients rather than fitting them (a carried finding written at
#: the size the diagnosis's recordings give, ``resized_findings.held_entries``): it enters the refit's entries only,
#: never a written file (``filled_entries`` takes it off).
HELD_KEY = "held"


def finding_kind(effect: str) -> str:
    """``torque``, ``rigid_body``, ``signal`` or ``reported`` for an effect key (module docstring)."""
    if effect in TORQUE_EFFECTS:
        return "torque"
    if effect in RIGID_BODY_EFFECTS:
        return "rigid_body"
    return "signal" if effect in SIGNAL_EFFECTS else "reported"


def _symbolic(x) -> bool:
    return isinstance(x, (ca.SX, ca.MX, ca.DM))


def _joint(x, j: int):
    """Column j of an (n_samples, n_dof) array, or entry j of an (n_dof, 1) CasADi vector."""
    return x[j] if _symbolic(x) else np.asarray(x)[:, j]


@dataclass(frozen=True)
class FindingTerm:
    """One torque-type finding on joint ``joint`` (0-based): what its columns are (module docstring).

    ``source`` is the driving joint of a coupling, ``harmonic`` the periods per revolution of a ripple,
    ``velocity`` [rad/s] the smoothing of the sign ``tanh(qd / velocity)`` of the friction-like terms; ``spec``
    the candidate term's ``spec()`` of a spring (any order) or an unnamed effect, whose columns are then the
    rebuilt term's (``candidate``).
    """

    effect: str
    joint: int
    source: int | None = None
    harmonic: int | None = None
    velocity: float = 0.05
    spec: dict | None = field(default=None, compare=False, hash=False)

    def __post_init__(self):
        if self.effect not in TORQUE_EFFECTS:
            raise ModelFileError(f"FindingTerm.effect must be one of {TORQUE_EFFECTS}; got {self.effect!r}.")
        if self.effect == "unnamed_effect" and self.spec is None:
            raise ModelFileError("FindingTerm.spec must hold the term spec of an unnamed effect; got None.")
        if self.spec is not None:
            candidate = self.candidate
            if candidate.key != self.effect or candidate.joints != (self.joint,):
                raise ModelFileError(
                    f"FindingTerm.spec {self.spec!r} describes {candidate.label}, not {self.effect} on joint "
                    f"{self.joint + 1}. Re-run 'psdm diagnose MODEL --apply'."
                )
        if self.effect == "coupling" and self.source is None:
            raise ModelFileError("FindingTerm.source must be the driving joint of a coupling; got None.")
        if self.effect == "torque_ripple" and not self.harmonic:
            raise ModelFileError(
                f"FindingTerm.harmonic must be a positive integer for a ripple; got {self.harmonic!r}."
            )
        if not (np.isfinite(self.velocity) and self.velocity > 0):
            raise ModelFileError(f"FindingTerm.velocity must be > 0 [rad/s]; got {self.velocity!r}.")

    @property
    def candidate(self):
        """The candidate term rebuilt from ``spec`` (None without a spec)."""
        if self.spec is None:
            return None
        try:
            return term_from_spec(self.spec)
        except ParameterError as exc:
            raise ModelFileError(
                f"calibrated model findings[].term.spec: {exc} Re-run 'psdm diagnose MODEL --apply'."
            ) from None

    @property
    def label(self) -> str:
        if self.spec is not None:
            return self.candidate.label
        if self.effect == "coupling":
            return f"coupling[j{self.source + 1}->j{self.joint + 1}]"
        if self.effect == "torque_ripple":
            return f"torque_ripple[j{self.joint + 1},h={self.harmonic}]"
        return f"{self.effect}[j{self.joint + 1}]"

    @property
    def load_dependent(self) -> bool:
        """Whether the column needs the model's own torque (``load_dependent_friction``)."""
        return self.effect == "load_dependent_friction"

    def feature_names(self) -> list:
        """Column labels ending in the 1-based joint the torque acts on (``spring_k_4``, ``mu_3``, ...)."""
        j = self.joint + 1
        candidate = self.candidate
        if self.effect == "unnamed_effect":  # a column label ends in its joint (the fit reads it)
            return [f"{name}_on_{j}" for name in candidate.feature_names()]
        if candidate is not None and not (self.effect == "spring" and candidate.order == 1):
            return list(candidate.feature_names())
        return {
            "spring": [f"spring_k_{j}", f"spring_c_{j}"],
            "torque_offset": [f"bias_{j}"],
            "torque_ripple": [f"ripple_sin{self.harmonic}_{j}", f"ripple_cos{self.harmonic}_{j}"],
            "coupling": [f"coupling_qd{(self.source or 0) + 1}_on_{j}", f"coupling_qdd{(self.source or 0) + 1}_on_{j}"],
            "coulomb_asymmetry": [f"asymmetry_{j}"],
            "rotor_inertia": [f"Im_{j}"],
            "load_dependent_friction": [f"mu_{j}"],
        }[self.effect]

    def lower_bounds(self) -> list:
        """Lower bound of each coefficient in the consistent fit: a drive inertia, a friction, a Stribeck peak and a
        smooth Coulomb friction (``physical_bounds.POSITIVE_FRICTION_SHAPES``) are >= 0."""
        positive = self.effect in ("rotor_inertia", "load_dependent_friction") or (
            self.effect == "friction_shape" and self.spec.get("shape") in POSITIVE_FRICTION_SHAPES
        )  # a peak, not a dip; a level, not a fall
        return [0.0 if positive else -np.inf] * len(self.feature_names())

    def to_dict(self) -> dict:
        out = {"effect": self.effect, "joint": self.joint + 1, "velocity": self.velocity}
        if self.source is not None:
            out["source"] = self.source + 1
        if self.harmonic is not None:
            out["harmonic"] = int(self.harmonic)
        if self.spec is not None:
            out["spec"] = dict(self.spec)
        return out

    @classmethod
    def from_dict(cls, entry: dict) -> FindingTerm:
        try:
            source = entry.get("source")
            return cls(
                effect=str(entry["effect"]),
                joint=int(entry["joint"]) - 1,
                source=None if source is None else int(source) - 1,
                harmonic=entry.get("harmonic"),
                velocity=float(entry.get("velocity", 0.05)),
                spec=entry.get("spec"),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFileError(
                f"calibrated model findings[].term must hold effect, joint (1-based) and its options; got {entry!r} "
                f"({exc}). Re-run 'psdm diagnose MODEL --apply'."
            ) from None


def term_values(term: FindingTerm, q, qd, qdd, tau_base=None) -> list:
    """The values of a term's features on joint ``term.joint``: arrays (n_samples,) or CasADi scalars.

    ``q, qd, qdd`` are (n_samples, n_dof) arrays or (n_dof, 1) CasADi vectors; ``tau_base`` (same shape) is
    the model's torque without load-dependent friction, needed only by that term.
    """
    if term.spec is not None:
        return _candidate_values(term, q, qd, qdd)
    sym = _symbolic(q)
    sin, cos, tanh, fabs = (ca.sin, ca.cos, ca.tanh, ca.fabs) if sym else (np.sin, np.cos, np.tanh, np.abs)
    j = term.joint
    qj, qdj = _joint(q, j), _joint(qd, j)
    one = 1.0 + 0.0 * qj
    if term.effect == "spring":
        return [qj, one]
    if term.effect == "torque_offset":
        return [one]
    if term.effect == "torque_ripple":
        return [sin(term.harmonic * qj), cos(term.harmonic * qj)]
    if term.effect == "coupling":
        return [_joint(qd, term.source), _joint(qdd, term.source)]
    if term.effect == "coulomb_asymmetry":
        return [0.5 * (1.0 + tanh(qdj / term.velocity))]
    if term.effect == "rotor_inertia":
        return [_joint(qdd, j)]
    return [fabs(_joint(tau_base, j)) * tanh(qdj / term.velocity)]  # load_dependent_friction


def _candidate_values(term: FindingTerm, q, qd, qdd) -> list:
    """The features of a spec-defined term on its joint: its candidate term's columns (arrays) or its CasADi
    expression with unit coefficients (the expression is linear in them)."""
    candidate = term.candidate
    n = len(candidate.feature_names())
    if _symbolic(q):
        return [candidate.casadi_expression(q, qd, qdd, 0.0, None, list(np.eye(n)[k]))[term.joint] for k in range(n)]
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    columns = candidate.columns(TermContext(np.zeros(q.shape[0]), q, qd, qdd))
    return [columns[:, term.joint, k] for k in range(n)]


@dataclass(frozen=True, eq=False)
class FindingColumns:
    """Extra linear columns of the recordings-route fit: the features of ``terms``, in order.

    ``reference(q, qd, qdd)`` is the torque [N m] the load-dependent terms are proportional to (the
    previous model's torque without them); ``keep[i]`` says whether feature i enters the fit (a feature the
    fit's other columns already span is left out, its coefficient 0). ``held``: ``(FindingTerm, coefficients)`` of
    terms at given coefficients (``HELD_KEY``): no column of the fit; their torque (:meth:`held_torque`) is taken off
    the prepared recordings the fit sees (:meth:`without_held`), as held friction's is.
    """

    terms: tuple
    reference: object = None
    keep: tuple | None = None
    held: tuple = ()

    @property
    def all_names(self) -> list:
        return [name for term in self.terms for name in term.feature_names()]

    @property
    def mask(self) -> np.ndarray:
        return np.ones(len(self.all_names), dtype=bool) if self.keep is None else np.asarray(self.keep, dtype=bool)

    @property
    def names(self) -> list:
        return [name for name, kept in zip(self.all_names, self.mask) if kept]

    @property
    def lower(self) -> np.ndarray:
        bounds = np.array([b for term in self.terms for b in term.lower_bounds()], dtype=float)
        return bounds[self.mask]

    def all_columns(self, q, qd, qdd) -> np.ndarray:
        """Every feature's column (n_samples, n_dof, n_features), zero off the term's joint."""
        n_samples, n_dof = q.shape
        tau_base = None
        if any(term.load_dependent for term in self.terms):
            tau_base = np.asarray(self.reference(q, qd, qdd), dtype=float)
        blocks = []
        for term in self.terms:
            for value in term_values(term, q, qd, qdd, tau_base):
                column = np.zeros((n_samples, n_dof, 1))
                column[:, term.joint, 0] = value
                blocks.append(column)
        return np.concatenate(blocks, axis=2) if blocks else np.zeros((n_samples, n_dof, 0))

    def columns(self, q, qd, qdd) -> np.ndarray:
        """The kept features' columns (n_samples, n_dof, len(names))."""
        return self.all_columns(q, qd, qdd)[:, :, self.mask]

    def held_torque(self, q, qd, qdd) -> np.ndarray:
        """The torque of the ``held`` terms at their coefficients (n_samples, n_dof) [N m]."""
        q = np.asarray(q, dtype=float)
        out = np.zeros(q.shape)
        if not self.held:
            return out
        base = np.asarray(self.reference(q, qd, qdd), dtype=float) if any(t.load_dependent for t, _ in self.held) \
            else None  # fmt: skip
        for term, coefficients in self.held:
            values = term_values(term, q, qd, qdd, base)
            out[:, term.joint] += sum(float(c) * v for c, v in zip(coefficients, values) if c is not None)
        return out

    def without_held(self, prepared) -> list:
        """The prepared recordings with the ``held`` terms' torque taken off (a missing torque stays missing)."""
        if not self.held:
            return list(prepared)
        return [replace(r, tau=np.asarray(r.tau, dtype=float) - self.held_torque(r.q, r.qd, r.qdd)) for r in prepared]


def offsets_left_to_findings(options, terms):
    """``options`` (``trajectory_fit.TrajectoryOptions``) without the torque offsets chosen from the data on the joints
    where a torque finding has a constant of its own (``CONSTANT_FEATURE``: a spring's, which holds its rest angle).

    The offset and the constant are one column, so a fit keeps one of them (``recalibrate``: the other absorbed).
    Beside an offset, a spring's constant was absorbed and its rest angle read 0 (``q0 = -c / k``, the offset holding
    ``-k q0``). An offset chosen from the data (``column_choice``, ``--offset auto``: ``offset_joints`` a tuple) was
    chosen on a fit without the finding's columns, where the missing spring's constant asked for it; with the
    spring in the model, the constant is the spring's. An offset asked for (``--offset on``: ``offset_joints`` None)
    is kept. The model's torque is the same either way."""
    if options.offset_joints is None or "offset" not in options.friction:
        return options
    held = {t.joint for t in terms if any(CONSTANT_FEATURE.fullmatch(name) for name in t.feature_names())}
    kept = tuple(j for j in options.offset_joints if j not in held)
    return options if kept == tuple(options.offset_joints) else replace(options, offset_joints=kept)


def physical_parameters(term: FindingTerm, c) -> dict:
    """Named physical parameters of a torque finding from its coefficients (absorbed features count 0)."""
    if term.spec is not None:
        return {k: float(v) for k, v in term.candidate.physical_parameters(np.asarray(c, dtype=float)).items()}
    if term.effect == "spring":
        return {"k": c[0], "q0": (-c[1] / c[0]) if c[0] else 0.0}
    if term.effect == "torque_ripple":
        return {
            "amplitude": float(np.hypot(c[0], c[1])),
            "harmonic": float(term.harmonic),
            "phase": float(np.arctan2(c[1], c[0])),
        }
    if term.effect == "coupling":
        return {"viscous": c[0], "inertia": c[1], "source_joint": float(term.source + 1)}
    key = {
        "torque_offset": "offset",
        "coulomb_asymmetry": "delta",
        "rotor_inertia": "inertia",
        "load_dependent_friction": "coefficient",
    }[term.effect]
    return {key: c[0]}


def filled_entries(entries, terms, columns: FindingColumns, extra) -> list:
    """The findings block: each torque entry gets its jointly fitted coefficients, sigma and parameters; one held at
    its coefficients (``HELD_KEY``) keeps them."""
    values, ols, std = (iter(np.asarray(a, dtype=float).tolist()) for a in extra)
    by_label = {}
    for term, mask in zip(terms, _split_mask(terms, columns.mask)):
        fitted = [(next(values), next(ols), next(std)) if kept else (None, None, None) for kept in mask]
        by_label[term.label] = (term, fitted)
    out = []
    for entry in entries:
        entry = copy.deepcopy(entry)
        if entry.pop(HELD_KEY, None):  # its coefficients and parameters as held (``FindingColumns.held``)
            out.append(entry)
            continue
        if entry["kind"] == "torque":
            term, fitted = by_label[FindingTerm.from_dict(entry["term"]).label]
            entry["feature_names"] = term.feature_names()
            entry["coefficients"], entry["ols"], entry["std"] = (list(x) for x in zip(*fitted))
            entry["absorbed"] = [n for n, (v, _, _) in zip(term.feature_names(), fitted) if v is None]
            entry["parameters"] = physical_parameters(term, [0.0 if v is None else v for v, _, _ in fitted])
        else:
            entry.setdefault("parameters", entry["diagnosis"]["parameters"])
            entry["applied"] = (
                entry.get("applied")
                or {
                    "rigid_body": "taken up by the re-identified rigid body (base parameters)",
                    "signal": "measurement correction (the 'corrections' block)",
                    "reported": "reported only: not part of the model's torque",
                }[entry["kind"]]
            )
        out.append(entry)
    return out


def held_findings(entries) -> tuple:
    """``FindingColumns.held`` of the torque ``entries`` marked ``HELD_KEY``: (FindingTerm, coefficients) each."""
    return tuple((FindingTerm.from_dict(e["term"]), tuple(e["coefficients"])) for e in entries
                 if e.get(HELD_KEY) and e.get("kind") == "torque")  # fmt: skip


def _split_mask(terms, mask) -> list:
    out, k = [], 0
    for term in terms:
        n = len(term.feature_names())
        out.append(list(mask[k : k + n]))
        k += n
    return out


def correct_recording(recording: Recording, corrections: dict, kt=None) -> Recording:
    """The recording with the measurement corrections of a calibrated model applied (``signal`` findings).

    ``corrections`` maps a finding's label to its effect and parameters (joints 1-based), applied in this order:

    - ``{"effect": "delay", "delay_s": d}``: the recorded torque (or current) is advanced by d seconds,
      ``tau(t) = tau_rec(t + d)`` (linear interpolation, the last sample held), in line with the positions again;
    - ``{"effect": "joint_elasticity", "joint": j, "compliance_rad_per_Nm": c}``: the encoder sits before a
      torsion spring, ``q_link = q_rec - c tau``;
    - ``{"effect": "backlash", "joint": j, "backlash_rad": b, "torque_scale_Nm": s}``: the encoder sits before a
      play, ``q_link = q_rec - (b / 2) tanh(tau / s)``.

    ``tau`` is the recorded joint torque, or ``kt`` times the current. The same function serves the
    recalibration and ``psdm validate``. A joint whose torque the recording does not hold (``missing_torque``,
    its column NaN) keeps its recorded position: the correction needs that torque, and the joint's positions still
    drive the other joints' torques. The recording's other fields (missing torque, temperature) are kept.
    """
    entries = [dict(v, effect=v.get("effect", k)) for k, v in corrections.items()]
    delay = sum(float(e.get("delay_s", 0.0)) for e in entries if e["effect"] == "delay")
    t = recording.t + delay

    def shifted(x):
        if x is None or delay == 0.0:
            return x
        return np.column_stack([np.interp(t, recording.t, x[:, j]) for j in range(x.shape[1])])

    tau, current = shifted(recording.tau), shifted(recording.current)
    q = np.array(recording.q, dtype=float)
    for entry in entries:
        if entry["effect"] in ("joint_elasticity", "backlash"):
            j = int(entry["joint"]) - 1
            torque = tau[:, j] if tau is not None else float(np.asarray(kt)[j]) * current[:, j]
            torque = np.where(np.isfinite(torque), torque, 0.0)  # a missing torque: the recorded position kept
            if entry["effect"] == "joint_elasticity":
                q[:, j] -= float(entry["compliance_rad_per_Nm"]) * torque
            else:
                q[:, j] -= 0.5 * float(entry["backlash_rad"]) * np.tanh(torque / float(entry["torque_scale_Nm"]))
    positions = any(e["effect"] != "delay" for e in entries)
    if delay == 0.0 and not positions:
        return recording
    derivatives = (None, None) if positions else (recording.qd, recording.qdd)  # stale once q is corrected
    return replace(recording, q=q, tau=tau, current=current, qd=derivatives[0], qdd=derivatives[1])
