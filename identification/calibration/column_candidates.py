"""The candidate drive columns of the column choice (``column_choice``, steps 1-2), summed in blocks.

The training recordings are prepared once (``PreparedTraining``: filtered, differentiated, decimated and trimmed as
the fit prepares them; the Coulomb smoothing velocity is chosen from these, ``coulomb_smoothing``) and summed into
normal equations with every candidate column, in ``N_BLOCKS`` contiguous blocks per recording: the Stribeck shape's
two Coulomb columns (its velocities found first), each reversing joint's offset, each separate drive-inertia column,
and with currents each joint's drive loss. ``Candidates.evaluate`` fits any sub-model (a linear map of these columns)
by weighted least squares from the summed blocks, and gives its training and held-out residuals (the validation
recordings', else each block predicted by the fit on the others).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.coulomb_width import joint_width
from identification.calibration.drive_loss import loss_columns, prior_theta
from identification.calibration.payload_fit import FlangeBodies, subtract_known_payloads
from identification.calibration.residual_correlation import residual_correlation_time
from identification.calibration.separate_inertia import separate_inertia_joints
from identification.calibration.stribeck import base_regressors, fit_stribeck_velocity
from identification.calibration.trajectory_checks import MIN_REVERSAL_FRACTION
from identification.calibration.trajectory_data import (
    NormalEquations,
    drive_column_names,
    drive_columns,
    prepare_recording,
    prepare_recordings,
    viscous_column,
)
from identification.calibration.trajectory_fit import torque_constants
from identification.calibration.viscous_power import ViscousExponents, fit_viscous_exponents

__all__ = [
    "N_BLOCKS",
    "Candidates",
    "PreparedTraining",
    "candidates",
    "loss_candidates",
    "viscous_power_rows",
    "prepare_training",
    "residual_weights",
    "reversing_joints",
    "solve_columns",
    "sum_blocks",
]

#: Contiguous blocks per training recording for the cross-validation (without validation recordings).
N_BLOCKS = 5


@dataclass(frozen=True, eq=False)
class PreparedTraining:
    """The training recordings prepared once for the choice: torque constants (None: torques), cutoffs [Hz] per
    recording and the prepared recordings (``trajectory_data.prepare_recordings``)."""

    kt: object
    cutoffs: tuple
    prepared: tuple


def prepare_training(robot, recordings, options) -> PreparedTraining:
    """The raw training ``recordings`` prepared (and refused) as ``identify_trajectories`` prepares them."""
    kt = torque_constants(robot, options, recordings)
    cutoffs, _, prepared = prepare_recordings(robot, recordings, kt, options.cutoff_hz, options.edge_periods)
    return PreparedTraining(kt, tuple(cutoffs), tuple(prepared))


@dataclass(frozen=True)
class Candidates:
    """The full column set the choice works on, and the training and held-out normal equations."""

    names: tuple
    n_base: int
    stribeck: bool
    blocks: tuple
    held: NormalEquations | None
    weights: np.ndarray
    effective: np.ndarray
    parts: tuple = ()  # the held-out normal equations of each validation recording (``held`` is their sum)
    exponents: ViscousExponents | None = None  # the viscous exponent per joint, its column ``fp<j>`` a candidate
    viscous: tuple = ()  # joints (0-based) whose viscous column is the power law in every sub-model (``with_viscous``)

    def blocks_count(self, joint: int) -> int:
        """Training samples of ``joint``."""
        return int(sum(block.count[joint] for block in self.blocks))

    def with_viscous(self, joints) -> Candidates:
        """These candidates with the power-law viscous column in place of the linear one on ``joints`` (0-based)."""
        out = replace(self, viscous=tuple(joints))
        out.__dict__["_summed"] = self.__dict__.setdefault("_summed", {})  # the same sums
        return out

    def transform(self, stribeck, dropped=()) -> np.ndarray:
        """Map from a sub-model's columns to the full ones: the joints of ``stribeck`` (0-based) keep the Stribeck
        shape, on the others (Coulomb-viscous) ``fs`` joins ``fc``. A joint's viscous column is the linear one ``fv``,
        or the power law ``fp`` on the joints of ``viscous`` or where ``dropped`` drops ``fv`` (a sub-model that drops
        either takes the other)."""
        full = [f"theta{k}" for k in range(self.n_base)] + list(self.names)
        power = {n[2:]: f"fv{n[2:]}" in dropped or (f"fp{n[2:]}" not in dropped and int(n[2:]) - 1 in self.viscous)
                 for n in self.names if n.startswith("fp")}  # fmt: skip
        dropped = {*dropped, *(("fv" if on else "fp") + j for j, on in power.items())}
        flat = {f"{j + 1}" for j in range(self.weights.size) if j not in stribeck} if self.stribeck else set()
        kept = [n for n in full if n not in dropped and not (n.startswith("fs") and n[2:] in flat)]
        out = np.zeros((len(full), len(kept)))
        for k, name in enumerate(kept):
            out[full.index(name), k] = 1.0
            if name.startswith("fc") and name[2:] in flat:
                out[full.index("fs" + name[2:]), k] = 1.0
        return out

    def evaluate(self, stribeck, dropped=()) -> tuple:
        """(training RSS per joint, held-out RSS per joint, estimate in full columns, its std) of a sub-model whose
        joints ``stribeck`` (0-based) have the Stribeck shape."""
        transform = self.transform(stribeck, dropped)
        (total, weighted), folds = self.summed(None), range(len(self.blocks))
        x, std = solve_columns(weighted, transform)
        held = None if self.held is None else self.held.residual_sum(x)
        if held is None or np.any(self.held.count == 0):  # no held-out rows of a joint (its torque missing): CV
            cv = sum(self.blocks[k].residual_sum(solve_columns(self.summed(k)[1], transform)[0]) for k in folds)
            held = cv if held is None else np.where(self.held.count == 0, cv, held)
        return total.residual_sum(x), held, x, std

    def part_sums(self, stribeck, dropped=()) -> np.ndarray:
        """Held-out RSS per validation recording and joint (parts, n_dof) of the sub-model (as ``evaluate``'s), each
        recording on its own: a column must hold on each (``column_choice``)."""
        x = solve_columns(self.summed(None)[1], self.transform(stribeck, dropped))[0]
        return np.array([part.residual_sum(x) for part in self.parts]).reshape(len(self.parts), self.weights.size)

    def summed(self, skip) -> tuple:
        """(every block's normal equations but ``skip``'s, summed; their weighted Gram matrix and moment): the same for
        every candidate, so made once (the sums and products as each candidate would make them)."""
        memory = self.__dict__.setdefault("_summed", {})
        if skip not in memory:
            memory[skip] = (equations := sum_blocks(self.blocks, skip=skip)), equations.weighted(self.weights)[:2]
        return memory[skip]


def sum_blocks(blocks, skip=None) -> NormalEquations:
    first = blocks[0]
    out = NormalEquations(first.n_dof, first.n_columns)
    for k, block in enumerate(blocks):
        if k != skip:
            for name in ("gram", "moment", "energy", "count", "total"):
                setattr(out, name, getattr(out, name) + getattr(block, name))
    return out


def solve_columns(weighted, transform) -> tuple:
    """Weighted least squares of the sub-model ``transform`` from the weighted Gram matrix and moment ``weighted``, as
    full-column estimate and standard deviations."""
    gram, moment = transform.T @ weighted[0] @ transform, transform.T @ weighted[1]
    scale = np.sqrt(np.clip(np.diag(gram), 1e-300, None))
    inverse = np.linalg.pinv(gram / np.outer(scale, scale), rcond=1e-12, hermitian=True) / np.outer(scale, scale)
    return transform @ (inverse @ moment), transform @ np.sqrt(np.clip(np.diag(inverse), 0.0, None))


def reversing_joints(prepared, speed) -> list:
    """Joints that move faster than ``speed`` (one, or one per joint) both ways on enough samples to tell an offset
    from Coulomb friction."""
    qd = np.concatenate([r.qd for r in prepared])
    speed = np.asarray(speed, dtype=float)
    share = np.minimum(np.mean(qd > speed, axis=0), np.mean(qd < -speed, axis=0))
    return [j for j in range(qd.shape[1]) if share[j] >= MIN_REVERSAL_FRACTION]


def candidates(robot, model, training: PreparedTraining, options, request, validation, configurations) -> tuple:
    """(Candidates, offset candidates, inertia candidates) of the prepared training recordings (module docstring); known
    payloads are taken off, unknown ones get their flange-body columns (``payload_fit``), as in the fit."""
    kt, cutoffs = training.kt, training.cutoffs
    prepared = subtract_known_payloads(robot, list(training.prepared), configurations)
    bodies = FlangeBodies.of(configurations, len(prepared))
    extras = bodies.extras(robot)
    offsets = reversing_joints(prepared, options.coulomb_velocity) if request.offset != "off" else []
    inertia = separate_inertia_joints(model, robot) if request.drive_inertia != "off" else []
    stribeck = request.friction in ("auto", "stribeck", "lugre")
    losses, theta = loss_candidates(robot, model, kt, request)
    offset = ("offset",) if offsets or request.offset == "on" else ()
    terms = (("fc", "fs", "fv") if stribeck else ("fc", "fv")) + offset
    full = replace(options, friction=terms, offset_joints=None, inertia_joints=None)
    regressors = base_regressors(model, prepared)  # evaluated once: the costly part
    vs = fit_stribeck_velocity(model, prepared, full, inertia, extras, regressors, trial=True) if stribeck else None
    every = drive_column_names(robot.n_dof, terms, inertia)
    # an offset of a joint that does not reverse is no candidate: its Coulomb column is a constant too
    names = [n for n in every if not (n.startswith("offset") and request.offset == "auto" and int(n[6:]) - 1
                                      not in offsets)]  # fmt: skip
    keep = list(range(model.n_base)) + [model.n_base + every.index(n) for n in names]
    keep += list(range(model.n_base + len(every), model.n_base + len(every) + bodies.n_columns))
    names += [f"payload{k}" for k in range(bodies.n_columns)] + [f"loss{j + 1}" for j in losses]

    def rows(recording, rigid, extra=None):
        drive = drive_columns(recording.qd, recording.qdd, terms, inertia, options.coulomb_velocity, vs)
        bodies_rows = np.zeros((*drive.shape[:2], bodies.n_columns))
        if extra is not None:
            bodies_rows = extra.columns(recording.q, recording.qd, recording.qdd)
        loss = loss_columns(rigid, recording.qd, theta, losses, options.coulomb_velocity) if losses else None
        plain = np.concatenate([rigid, drive, bodies_rows], axis=2)[:, :, keep]
        return plain if loss is None else np.concatenate([plain, loss], axis=2)

    fitted = [(rows(r, np.concatenate(chunks), extra), r.tau) for r, chunks, extra in zip(prepared, regressors, extras)]
    total = NormalEquations(robot.n_dof, len(keep) + len(losses))
    for columns, tau in fitted:
        total.add(columns, tau)
    weights, effective = residual_weights(total, fitted)  # the linear viscous model's: the choice's weights as before
    exponents = fit_viscous_exponents(fitted, names, model.n_base, options.coulomb_velocity, weights, effective)
    power = exponents.candidates() if request.friction == "auto" else ()

    def with_power(columns, qd):  # the power-law viscous column of each candidate joint, after the others
        return np.concatenate([columns, viscous_power_rows(qd, exponents, power, options.coulomb_velocity)], axis=2)

    blocks, n_columns = [], len(keep) + len(losses) + len(power)
    for recording, (columns, tau) in zip(prepared, fitted):
        columns = with_power(columns, recording.qd)
        edges = np.linspace(0, recording.n_samples, N_BLOCKS + 1).astype(int)
        for a, b in zip(edges[:-1], edges[1:]):
            blocks.append(NormalEquations(robot.n_dof, n_columns))
            blocks[-1].add(columns[a:b], tau[a:b])
    del fitted
    parts = []
    for recording in validation:
        ready = prepare_recording(recording, kt, cutoffs[0], options.edge_periods)[0]
        parts.append(NormalEquations(robot.n_dof, n_columns))
        parts[-1].add(with_power(rows(ready, model.regressor(ready.q, ready.qd, ready.qdd)), ready.qd), ready.tau)
    held = sum_blocks(parts) if parts else None
    names += [f"fp{j + 1}" for j in power]
    found = Candidates(tuple(names), model.n_base, stribeck, tuple(blocks), held, weights, effective, tuple(parts),
                       exponents=exponents)  # fmt: skip
    return found, offsets, inertia


def viscous_power_rows(qd, exponents, joints, coulomb_velocity) -> np.ndarray:
    """The power-law viscous columns ``fp<j>`` of ``joints`` (``viscous_power.viscous_column``), (n_samples, n_dof,
    len(joints)): each on its own joint's rows."""
    out = np.zeros((qd.shape[0], qd.shape[1], len(joints)))
    for k, j in enumerate(joints):
        out[:, j, k] = viscous_column(qd[:, j], exponents.value[j], joint_width(coulomb_velocity, j))
    return out


def loss_candidates(robot, model, kt, request) -> tuple:
    """(joints, reference base parameters) of the drive-loss candidates (``column_choice``, step 5): every joint when
    currents are the torque source (``kt``) or ``request.drive_loss`` is ``"on"``, none for LuGre friction (its
    exported code cannot hold a multiple of its own torque) or without the robot file's links."""
    wanted = request.drive_loss == "on" or (request.drive_loss == "auto" and kt is not None)
    theta = prior_theta(robot, model) if wanted and request.friction != "lugre" else None
    return ([], None) if theta is None else (list(range(robot.n_dof)), theta)


def residual_weights(total, training) -> tuple:
    """Per joint, the weight ``1 / sigma^2`` of the full model's residual, and the effective sample count: the
    sample count over the residual's correlation time (``residual_correlation.correlation_time``)."""
    rms = np.sqrt(total.energy / np.maximum(total.count, 1))
    x, _ = solve_columns(total.weighted(1.0 / np.maximum(rms, 1e-12) ** 2)[:2], np.eye(total.n_columns))
    dof = np.maximum(total.count - total.n_columns / total.n_dof, 1.0)
    sigma = np.sqrt(np.maximum(total.residual_sum(x), 1e-300) / dof)
    tau = np.max([residual_correlation_time(tau - columns @ x) for columns, tau in training], axis=0)
    return 1.0 / sigma**2, np.maximum(total.count / tau, 2.0)
