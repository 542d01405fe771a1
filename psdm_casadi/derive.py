"""derive_psdm(): the PSDM pipeline from a RobotDescription to a PSDMModel.

1. Sample Pinocchio's joint-torque regressor (RNEA in regressor form) for gravity and for each
   unit joint acceleration: tau = g G(q) X + sum_k qdd_k M_k(q) X.
2. For each of these, find the joints it depends on, sample it on a tensor grid of 5 angles per
   revolute joint (3 positions per prismatic joint) and invert the per-joint basis
   {1, s, c, sc, c^2} ({1, q, q^2}) exactly: the coefficient of every candidate function.
   Candidates whose coefficients vanish for every admissible parameter vector are redundant.
   The qd_k^2 and qd_j qd_k coefficients follow exactly from the mass-matrix ones through the
   Christoffel symbols, differentiation being a linear map on that basis.
3. Reduce the per-joint lumped parameters to base parameters (reduction.py).
4. Check the model against Pinocchio's rnea on random states and random parameters.

The grid costs 5^n: a robot beyond it (more than 8 revolute joints, see :data:`MAX_DOF`), or any
robot with ``DeriveOptions(form="recursive")``, is derived instead from the regressor's column
space at random states (``column_space.py``), in time and memory polynomial in n: the same base
parameter space, no monomial table, the model evaluated through its joint tree and preimage.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin
from threadpoolctl import threadpool_limits

from psdm_casadi.chain_regressor import ChainRegressor
from psdm_casadi.column_space import column_space_basis
from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import DerivationError, ParameterError
from psdm_casadi.model import PSDMModel
from psdm_casadi.oracle import (
    N_LINK_PARAMETERS,
    N_PARAMETERS_PER_JOINT,
    PinocchioOracle,
    build_kinematic_model,
    link_to_joint_frame_maps,
    standard_parameter_names,
)
from psdm_casadi.reduction import reduce_to_base_parameters
from psdm_casadi.sampling import free_parameter_basis, random_standard_parameters, random_states

REVOLUTE_NODES = 2.0 * np.pi * np.arange(5) / 5.0 + 0.1
PRISMATIC_NODES = np.array([-1.0, 0.0, 1.0])
# Per-joint basis exponents: revolute digits 0..4 = 1, s, c, s c, c^2; prismatic digits 0..2 = 1, q, q^2.
REVOLUTE_DIGITS = ((0, 0), (1, 0), (0, 1), (1, 1), (0, 2))  # (sin power, cos power)

logger = logging.getLogger(__name__)

MAX_DOF = 8
"""The largest robot (number of joints) that ``derive_psdm`` derives with its monomial table (the sum form).

The derivation's memory grows as 5^n: a function of the accelerations that depends on every
joint (gravity, qdd of joint 1) is sampled on a tensor grid of 5 angles per revolute joint, and at
each of the 5^n points Pinocchio's regressor (n x 10n) and its lift to the free parameters
(n x 11n) are kept, 8 bytes a number; the inverse-basis steps hold about four such arrays at once,
so the peak is about 4 * 5^n * n * 11n * 8 bytes (:func:`derivation_memory_bytes`). Measured on
all-revolute DH robots: 6 joints 0.4 GiB and 2 s, 7 joints 1.6 GiB and 11 s, 8 joints 8.0 GiB and
about 90 s; 9 joints would need about 52 GiB and 12 joints about 11 TiB (and beyond about 27
joints the array sizes overflow 64-bit integers). Larger robots are derived without the table
(``DeriveOptions.form``), in polynomial time; ``form="sum"`` refuses them before anything is allocated.

The check counts grid points, 5 per revolute and 3 per prismatic joint, and accepts up to
:data:`MAX_GRID_POINTS` (twice the eight-revolute grid): a Panda with its two prismatic fingers
free (7 revolute + 2 prismatic joints, 703,125 points) is derived, nine revolute joints are not.
"""

MAX_GRID_POINTS = 2 * 5**MAX_DOF
FORMS = ("auto", "sum", "recursive")


@dataclass(frozen=True)
class DeriveOptions:
    """Options of ``derive_psdm``.

    Parameters
    ----------
    seed : int
        Seeds the dependency probes and the final check; the result is the same for every seed.
    n_check : int
        Random states of the final comparison with Pinocchio's rnea.
    tolerance : float
        Largest accepted relative error of the final check (max |error| / max |tau|).
    coefficient_rtol : float
        Coefficients smaller than this, relative to the largest of their acceleration function,
        are round-off.
    independence_rtol : float
        Tolerance of the base-parameter selection.
    form : {"auto", "sum", "recursive"}
        ``"sum"``: the monomial table (E, P) of the paper, up to :data:`MAX_DOF` revolute joints;
        ``"recursive"``: base parameters from the regressor's column space, no table, any size;
        ``"auto"`` (default): the sum form when its grid is affordable, else the recursive one.
    """

    seed: int = 0
    n_check: int = 200
    tolerance: float = 1e-9
    coefficient_rtol: float = 1e-10
    independence_rtol: float = 1e-8
    form: str = "auto"

    def __post_init__(self):
        if self.form not in FORMS:
            raise ParameterError(f"DeriveOptions.form must be one of {FORMS}; got {self.form!r}.")
        if self.n_check < 1:
            raise ParameterError(f"DeriveOptions.n_check must be >= 1; got {self.n_check}.")
        if not 0 < self.tolerance < 1:
            raise ParameterError(f"DeriveOptions.tolerance must be in (0, 1); got {self.tolerance}.")


def acceleration_functions(n_dof: int, with_gravity: bool = True) -> list:
    """The acceleration functions in model order: g, qdd_k, qd_k^2, then qd_j qd_k (j < k)."""
    out = [("g",)] if with_gravity else []
    out += [("qdd", k) for k in range(n_dof)]
    out += [("qd2", k) for k in range(n_dof)]
    out += [("qdqd", j, k) for j in range(n_dof) for k in range(j + 1, n_dof)]
    return out


class _RegressorSampler:
    """Evaluates F_a(q) (n_dof x n_free) for one acceleration function from Pinocchio's regressor."""

    def __init__(self, robot: RobotDescription, free_basis: np.ndarray):
        n = robot.n_dof
        self.n = n
        kinematic, _ = build_kinematic_model(robot)
        self.model_still = kinematic.copy()
        self.model_still.gravity.linear = np.zeros(3)
        self.model_gravity = kinematic.copy()
        g = robot.gravity_magnitude
        self.model_gravity.gravity.linear = robot.gravity / g if g > 0 else np.zeros(3)
        self.data_still = self.model_still.createData()
        self.data_gravity = self.model_gravity.createData()
        # Pinocchio's regressor is in joint-frame parameters; map link-frame standard parameters to them.
        maps = link_to_joint_frame_maps(robot)
        lift = np.zeros((N_LINK_PARAMETERS * n, N_PARAMETERS_PER_JOINT * n))
        drive_rows = np.zeros((n, N_PARAMETERS_PER_JOINT * n))
        for i in range(n):
            lift[10 * i : 10 * i + 10, 11 * i : 11 * i + 10] = maps[i]
            drive_rows[i, 11 * i + 10] = 1.0
        self.lift = lift @ free_basis
        self.drive = drive_rows @ free_basis  # tau_i += Im_i * qdd_i

    def evaluate(self, function, q_grid: np.ndarray) -> np.ndarray:
        """F_a on every row of q_grid: array (n_points, n_dof, n_free)."""
        n = self.n
        zero = np.zeros(n)
        unit = np.eye(n)
        reg = pin.computeJointTorqueRegressor
        kind = function[0]
        out = np.empty((q_grid.shape[0], n, N_LINK_PARAMETERS * n))
        if kind == "g":
            for s, q in enumerate(q_grid):
                out[s] = reg(self.model_gravity, self.data_gravity, q, zero, zero)
        elif kind == "qdd":
            a = unit[function[1]]
            for s, q in enumerate(q_grid):
                out[s] = reg(self.model_still, self.data_still, q, zero, a)
        else:
            raise ValueError(f"the oracle samples only gravity and joint accelerations; got {function!r}")
        result = out @ self.lift
        if kind == "qdd":
            result += self.drive[function[1]][None, None, :] * unit[function[1]][None, :, None]
        return result


def _dependencies(sampler, functions, robot, rng, trials=3, rtol=1e-9):
    """For each acceleration function, the sorted joints its coefficients depend on (or None if it is zero)."""
    n = robot.n_dof
    base = rng.uniform(-np.pi, np.pi, size=(trials, n))
    base[:, ~robot.revolute] = rng.uniform(-0.5, 0.5, size=(trials, int((~robot.revolute).sum())))
    moved = np.repeat(base, n, axis=0)
    shift = rng.uniform(0.7, 2.0, size=moved.shape[0])
    moved[np.arange(moved.shape[0]), np.tile(np.arange(n), trials)] += shift
    evaluations = [(sampler.evaluate(function, base), sampler.evaluate(function, moved)) for function in functions]
    overall = max(np.abs(f0).max() for f0, _ in evaluations)
    out = []
    for f0, f1 in evaluations:
        scale = np.abs(f0).max()
        if scale <= rtol * overall:  # identically zero up to round-off
            out.append(None)
            continue
        f1 = f1.reshape(trials, n, n, -1)  # trial, moved joint, torque, parameter
        change = np.abs(f1 - f0[:, None]).max(axis=(0, 2, 3))
        out.append(tuple(int(j) for j in np.nonzero(change > rtol * scale)[0]))
    return out


def _function_label(function) -> str:
    """``gravity`` or ``qdd3`` (1-based joint): the acceleration function being sampled, for progress lines."""
    return "gravity" if function[0] == "g" else f"{function[0]}{function[1] + 1}"


def _basis_matrix(revolute: bool) -> np.ndarray:
    if revolute:
        s, c = np.sin(REVOLUTE_NODES), np.cos(REVOLUTE_NODES)
        return np.stack([np.ones(5), s, c, s * c, c * c], axis=1)
    x = PRISMATIC_NODES
    return np.stack([np.ones(3), x, x * x], axis=1)


def _coefficients(sampler, function, joints, robot, rtol):
    """Coefficient tensor of one acceleration function: dict multi-index -> (n_dof, n_free)."""
    n = robot.n_dof
    nodes = [REVOLUTE_NODES if robot.revolute[j] else PRISMATIC_NODES for j in joints]
    grid = np.zeros((int(np.prod([len(x) for x in nodes])), n))
    if joints:
        mesh = np.meshgrid(*nodes, indexing="ij")
        for axis, j in enumerate(joints):
            grid[:, j] = mesh[axis].ravel()
    values = sampler.evaluate(function, grid)  # (points, n_dof, n_free)
    tensor = values.reshape(*[len(x) for x in nodes], n, values.shape[-1])
    for axis, j in enumerate(joints):  # apply the inverse basis matrix along each grid axis, in place of shape
        inverse = np.linalg.inv(_basis_matrix(bool(robot.revolute[j])))
        shape = tensor.shape
        blocks = tensor.reshape(int(np.prod(shape[:axis], dtype=int)), shape[axis], -1)
        tensor = np.einsum("ij,ajb->aib", inverse, blocks).reshape(shape)
    magnitude = np.abs(tensor).reshape(*tensor.shape[: len(joints)], -1).max(axis=-1)
    largest = magnitude.max()
    if largest == 0.0:
        return {}
    tensor = np.where(np.abs(tensor) > rtol * largest, tensor, 0.0)
    result = {}
    indices = [()] if not joints else zip(*np.nonzero(magnitude > rtol * largest))
    for index in indices:
        digits = [0] * n
        for axis, j in enumerate(joints):
            digits[j] = int(index[axis])
        result[tuple(digits)] = tensor[index]
    return result


# d/dq of the per-joint basis, as (digit, factor) lists: d(sc) = 2c^2 - 1, d(c^2) = -2sc, d(q^2) = 2q.
_REVOLUTE_DERIVATIVE = {0: (), 1: ((2, 1.0),), 2: ((1, -1.0),), 3: ((4, 2.0), (0, -1.0)), 4: ((3, -2.0),)}
_PRISMATIC_DERIVATIVE = {0: (), 1: ((0, 1.0),), 2: ((1, 2.0),)}


def _derivative(terms: dict, joint: int, revolute: bool, row: int) -> dict:
    """d/dq_joint of one torque row of a coefficient dict: multi-index -> (n_free,) vector."""
    table = _REVOLUTE_DERIVATIVE if revolute else _PRISMATIC_DERIVATIVE
    out = {}
    for digits, coef in terms.items():
        for digit, factor in table[digits[joint]]:
            moved = digits[:joint] + (digit,) + digits[joint + 1 :]
            out[moved] = out.get(moved, 0.0) + factor * coef[row]
    return out


def _velocity_coefficients(coefficients_of: dict, robot: RobotDescription, rtol: float) -> dict:
    """Coefficients of qd_k^2 and qd_j qd_k from those of the mass-matrix columns (Christoffel symbols).

    tau_i contains sum_jk c_ijk qd_j qd_k with c_ijk = dM_ij/dq_k - 1/2 dM_jk/dq_i, M_ij being row i
    of the coefficients of qdd_j.
    """
    n = robot.n_dof
    mass = [coefficients_of[("qdd", k)] for k in range(n)]
    scale = max((np.abs(c).max() for column in mass for c in column.values()), default=0.0)
    derivative_cache = {}

    def d_mass(i, j, k):  # dM_ij / dq_k as a dict
        key = (i, j, k)
        if key not in derivative_cache:
            derivative_cache[key] = _derivative(mass[j], k, bool(robot.revolute[k]), i)
        return derivative_cache[key]

    def assemble(parts):  # parts: list of (output row, factor, dict)
        out = {}
        for row, factor, terms in parts:
            for digits, vector in terms.items():
                if digits not in out:
                    out[digits] = np.zeros((n, vector.shape[0]))
                out[digits][row] += factor * vector
        return {d: np.where(np.abs(c) > rtol * scale, c, 0.0) for d, c in out.items() if np.abs(c).max() > rtol * scale}

    result = {}
    for k in range(n):
        parts = []
        for i in range(n):
            parts += [(i, 1.0, d_mass(i, k, k)), (i, -0.5, d_mass(k, k, i))]
        result[("qd2", k)] = assemble(parts)
    for j in range(n):
        for k in range(j + 1, n):
            parts = []
            for i in range(n):
                parts += [(i, 1.0, d_mass(i, j, k)), (i, 1.0, d_mass(i, k, j)), (i, -1.0, d_mass(j, k, i))]
            result[("qdqd", j, k)] = assemble(parts)
    return result


def _exponent_column(function, digits, revolute) -> np.ndarray:
    n = len(digits)
    column = np.zeros(5 * n, dtype=np.uint8)
    for j, digit in enumerate(digits):
        if revolute[j]:
            column[n + j], column[2 * n + j] = REVOLUTE_DIGITS[digit]
        else:
            column[j] = digit
    kind = function[0]
    if kind == "qdd":
        column[4 * n + function[1]] = 1
    elif kind == "qd2":
        column[3 * n + function[1]] = 2
    elif kind == "qdqd":
        column[3 * n + function[1]] = 1
        column[3 * n + function[2]] = 1
    return column


def check_against_oracle(
    model: PSDMModel, robot: RobotDescription, rng: np.random.Generator, n_samples: int = 200, parameters=None
) -> float:
    """Largest relative error of the model's torque against Pinocchio's rnea (max |error| / max |tau|).

    Parameters are random admissible ones unless given, shape (n_dof, 11).
    """
    params = random_standard_parameters(robot, rng) if parameters is None else np.asarray(parameters)
    q, qd, qdd = random_states(robot, n_samples, rng)
    reference = PinocchioOracle(robot, params).rnea(q, qd, qdd)
    ours = model.inverse_dynamics(q, qd, qdd, model.base_parameters(params))
    return float(np.abs(ours - reference).max() / max(np.abs(reference).max(), 1e-300))


def derivation_memory_bytes(n_dof: int) -> int:
    """Estimated peak memory [bytes] of deriving an all-revolute robot of ``n_dof`` joints (see :data:`MAX_DOF`)."""
    return 4 * 5**n_dof * n_dof * N_PARAMETERS_PER_JOINT * n_dof * 8


def derivation_grid_points(robot: RobotDescription) -> int:
    """Points of the largest sampling grid: 5 per revolute and 3 per prismatic joint (see :data:`MAX_DOF`)."""
    return math.prod(len(REVOLUTE_NODES) if joint.is_revolute else len(PRISMATIC_NODES) for joint in robot.joints)


def check_derivation_size(robot: RobotDescription) -> None:
    """Refuse, before any allocation, a robot whose sampling grid passes :data:`MAX_GRID_POINTS`.

    Raises
    ------
    ParameterError
        Naming the joint count, the memory it would take and the fix.
    """
    n = robot.n_dof
    origin = f" (robot file {Path(robot.source).name})" if robot.source else ""
    points = derivation_grid_points(robot)
    if points > MAX_GRID_POINTS:
        memory = 4 * points * n * N_PARAMETERS_PER_JOINT * n * 8
        raise ParameterError(
            f"RobotDescription.n_dof must be at most {MAX_DOF} for derive_psdm's sum form when the joints are "
            f"revolute (its sampling grid has 5 points per revolute and 3 per prismatic joint, at most "
            f"{MAX_GRID_POINTS}); got {n} joints in {robot.name!r}{origin}: {points} points, which would need about "
            f"{memory / 2**30:.3g} GiB. Lock joints (e.g. [urdf].locked_joints) to bring the robot to "
            f"{MAX_DOF} revolute joints or fewer, or derive it in the recursive form (psdm derive --form auto or "
            "recursive; DeriveOptions.form): no monomial table, polynomial cost."
        )


def derive_psdm(robot: RobotDescription, options: DeriveOptions | None = None, *, seed: int | None = None) -> PSDMModel:
    """Derive the minimal PSDM regressor model of a robot.

    Parameters
    ----------
    robot : RobotDescription
    options : DeriveOptions, optional
    seed : int, optional
        Shortcut for ``DeriveOptions(seed=...)``.

    Returns
    -------
    PSDMModel
        With ``metadata["max_rel_error_vs_pinocchio"]`` and ``metadata["seconds"]``.

    Raises
    ------
    ParameterError
        When ``options.form="sum"`` and the robot has more than :data:`MAX_DOF` revolute joints
        (checked before anything is allocated).
    DerivationError
        When the derived model does not reproduce Pinocchio's rnea to ``options.tolerance``.

    Examples
    --------
    >>> from psdm_casadi import load_robot, derive_psdm      # doctest: +SKIP
    >>> model = derive_psdm(load_robot("denso_vs6556g"))
    >>> model.n_functions, model.n_base, model.n_gravity
    (1318, 32, 9)
    """
    if options is None:
        options = DeriveOptions(seed=0 if seed is None else seed)
    elif seed is not None:
        raise ParameterError("derive_psdm takes either options or seed, not both. Put the seed in DeriveOptions.")
    if recursive_form_chosen(robot, options):
        with threadpool_limits(limits=1, user_api="blas"):  # small dense algebra: threads only add contention
            return _derive_recursive(robot, options)
    check_derivation_size(robot)
    start = time.perf_counter()
    rng = np.random.default_rng(options.seed)
    n = robot.n_dof
    free_basis = free_parameter_basis(robot, rng)
    sampler = _RegressorSampler(robot, free_basis)
    sampled = [("g",)] if robot.gravity_magnitude > 0 else []
    sampled += [("qdd", k) for k in range(n)]
    dependencies = _dependencies(sampler, sampled, robot, rng)
    coefficients_of = {}
    for index, (function, joints) in enumerate(zip(sampled, dependencies)):  # the slow part: a bar on a terminal
        logger.info(
            "deriving: %s", _function_label(function), extra={"progress": (index + 1, len(sampled)), "tick": True}
        )
        coefficients_of[function] = (
            {} if joints is None else _coefficients(sampler, function, joints, robot, options.coefficient_rtol)
        )
    coefficients_of.update(_velocity_coefficients(coefficients_of, robot, options.coefficient_rtol))

    columns, coefficients, keys = [], [], []
    for order, function in enumerate(acceleration_functions(n, with_gravity=robot.gravity_magnitude > 0)):
        for digits, coef in coefficients_of[function].items():
            keys.append((order, tuple(reversed(digits))))  # the last joint is the most significant digit
            columns.append(_exponent_column(function, digits, robot.revolute))
            coefficients.append(coef)
    if not columns:
        raise DerivationError(f"robot {robot.name!r} produced no dynamics at all: every link is massless.")
    order = sorted(range(len(keys)), key=keys.__getitem__)
    exponents = np.stack([columns[k] for k in order], axis=1)
    stacked = np.stack([coefficients[k] for k in order], axis=0).transpose(1, 0, 2)  # (n_dof, p, n_free)

    reduction, base_map, _ = reduce_to_base_parameters(stacked, rtol=options.independence_rtol)
    parameter_map = base_map @ free_basis.T
    parameter_map[np.abs(parameter_map) < 1e-12 * np.abs(parameter_map).max()] = 0.0
    model = PSDMModel(
        exponents=exponents,
        reduction=reduction,
        parameter_map=parameter_map,
        base_names=tuple(f"theta{j + 1}" for j in range(reduction.shape[1])),
        standard_names=tuple(standard_parameter_names(n)),
        gravity_magnitude=robot.gravity_magnitude,
        revolute=robot.revolute,
        robot_name=robot.name,
    )
    return _checked(model, robot, options, rng, start, int(free_basis.shape[1]))


def recursive_form_chosen(robot: RobotDescription, options: DeriveOptions) -> bool:
    """True when ``derive_psdm`` derives ``robot`` without monomial table (see ``DeriveOptions.form``)."""
    return options.form == "recursive" or (options.form == "auto" and derivation_grid_points(robot) > MAX_GRID_POINTS)


def _derive_recursive(robot: RobotDescription, options: DeriveOptions) -> PSDMModel:
    """The model without monomial table: base parameters from the regressor's column space (polynomial in n)."""
    start = time.perf_counter()
    rng = np.random.default_rng(options.seed)
    n = robot.n_dof
    logger.info("deriving %s (%d joints) from the regressor's column space", robot.name, n)
    free_basis = free_parameter_basis(robot, rng)
    basis = column_space_basis(robot, free_basis, rng)
    kinematic, _ = build_kinematic_model(robot)
    kinematic.gravity.linear = np.asarray(robot.gravity, dtype=float)
    parameter_map = basis.base_map @ free_basis.T
    parameter_map[np.abs(parameter_map) < 1e-12 * np.abs(parameter_map).max()] = 0.0
    model = PSDMModel(
        exponents=np.zeros((5 * n, 0), dtype=np.uint8),
        reduction=np.zeros((0, basis.preimage.shape[1], n)),
        parameter_map=parameter_map,
        base_names=tuple(f"theta{j + 1}" for j in range(basis.preimage.shape[1])),
        standard_names=tuple(standard_parameter_names(n)),
        gravity_magnitude=robot.gravity_magnitude,
        revolute=robot.revolute,
        robot_name=robot.name,
        chain=ChainRegressor.from_pinocchio(kinematic, basis.preimage, basis.gravity_mask),
    )
    model = _checked(model, robot, options, rng, start, int(free_basis.shape[1]))
    metadata = {**model.metadata, "form": "recursive", "relation_error": basis.relation_error}
    return replace(model, metadata={**metadata, "n_states": basis.n_states})


def _checked(model, robot, options, rng, start, n_free) -> PSDMModel:
    """The model with its provenance, after the check against Pinocchio's rnea."""
    error = check_against_oracle(model, robot, rng, options.n_check)
    if not error <= options.tolerance:
        raise DerivationError(
            f"the derived model of {robot.name!r} misses Pinocchio's rnea by {error:.3g} (relative), above "
            f"DeriveOptions.tolerance={options.tolerance:g}. The robot may violate the PSDM structure "
            "(e.g. a joint that is neither revolute nor prismatic)."
        )
    metadata = {
        "seed": options.seed,
        "seconds": time.perf_counter() - start,
        "max_rel_error_vs_pinocchio": error,
        "n_free_parameters": n_free,
    }
    return replace(model, metadata=metadata)
