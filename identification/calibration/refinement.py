"""Joint refinement of all parameters together by Ipopt: base parameters, motor constants and friction.

What the paper lacks: its four steps each hold the previous steps' estimates fixed, so their
errors stack up (paper 3.4). :func:`refine_parameters` starts from the step estimates and
minimises the torque error over every experiment at once:

    r_i = Kt_i i_i - Y_i(q, qd, qdd) theta - tau_tool,i - f_i(qd_i)

Friction model (documented choice): the steady-state LuGre (Stribeck) curve
``f = (fc + (fs - fc) exp(-(qd/vs)^2) + fv |qd|^dv) sign(qd)`` with ``fc, fs, fv, dv`` free (when
``refine_friction``; by default only the inertial base parameters are refined, see RefinementOptions) and
``vs, sigma0, sigma1`` held at the multiple-shooting values. Rows in the pre-sliding regime (joint
displacement since its last reversal below ``presliding_factor * fs / sigma0``, or ``|qd|`` below
``min_speed``) are dropped, since there the bristle state is not at steady state. This is a smooth
least-squares problem with no state variables, so Ipopt converges quickly from the step
estimates; the LuGre dynamics (z states) are left to the shooting step where they are
observable. The payload rows of the motor step fix the scale shared by Kt and the other parameters.

With ``consistency="constrain"``, D(q_k, theta) = L_k L_k^T + eps I is imposed at sampled
configurations q_k with L_k lower-triangular decision variables (a Cholesky certificate of
positive definiteness; D is linear in theta).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from identification.calibration.consistency import mass_matrices
from identification.calibration.excitation import EXCITATION_FIX, thresholds_of
from identification.calibration.steps import regressor_chunked
from identification.data.recording import Recording
from identification.data.regressor_check import ZERO_COLUMN, base_parameter_joints, check_regressor
from identification.friction.models import LuGreParameters
from identification.metrics import rms
from psdm_casadi.errors import ParameterError, ShapeError, SolverError
from psdm_casadi.model import PSDMModel

logger = logging.getLogger(__name__)

__all__ = ["RefinementOptions", "RefinementBlock", "RefinementResult", "refine_parameters", "steady_mask"]

_SUCCESS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


@dataclass(frozen=True)
class RefinementOptions:
    """Options of :func:`refine_parameters`.

    Parameters
    ----------
    refine_kt, refine_friction, refine_gravity : bool
        Free the motor constants / the friction parameters ``fc, fs, fv, dv`` / the gravity base
        parameters (else held at the step estimates). All are held by default: each comes from its
        dedicated experiment, and the refinement's rows carry the errors of its simpler models. Freed,
        Kt absorbs model errors of the other rows, the friction's fs absorbs the bristle dynamics
        the steady-state curve does not see, and the small gravity parameters absorb both.
    consistency : {"none", "constrain"}
        ``"constrain"`` imposes a positive-definite mass matrix at ``n_consistency`` configurations.
    n_consistency : int
        Configurations of the constraint, >= 1.
    eps : float
        Smallest allowed mass-matrix eigenvalue in the constraint [kg m^2], >= 0.
    presliding_factor : float
        Rows within this many break-away displacements ``fs / sigma0`` after a reversal are dropped.
    min_speed : float
        Rows slower than this [rad/s] are dropped.
    max_iter : int
    tol : float
    print_level : int
    ipopt_options : dict
        Raw Ipopt options, passed through unchanged.
    """

    refine_kt: bool = False
    refine_friction: bool = False
    refine_gravity: bool = False
    consistency: str = "none"
    n_consistency: int = 24
    eps: float = 1e-4
    presliding_factor: float = 20.0
    min_speed: float = 1e-3
    max_iter: int = 200
    tol: float = 1e-10
    print_level: int = 0
    ipopt_options: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.consistency not in ("none", "constrain"):
            raise ParameterError(
                f"RefinementOptions.consistency must be 'none' or 'constrain'; got {self.consistency!r}."
            )
        for name in ("n_consistency", "max_iter"):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and value >= 1):
                raise ParameterError(f"RefinementOptions.{name} must be an integer >= 1; got {value!r}.")
        for name in ("eps", "presliding_factor", "min_speed"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ParameterError(f"RefinementOptions.{name} must be >= 0; got {value!r}.")
        if not (np.isfinite(self.tol) and self.tol > 0):
            raise ParameterError(f"RefinementOptions.tol must be > 0; got {self.tol!r}.")


@dataclass(frozen=True, eq=False)
class RefinementBlock:
    """One preprocessed recording for the refinement, with the known tool torque.

    Parameters
    ----------
    recording : Recording
        Preprocessed (qd, qdd) and decimated; currents or torques.
    tool_torque : array, shape (n_samples, n_dof), optional
        Known end-effector torque [N m] (e.g. the calibration mass); zeros when omitted.
    """

    recording: Recording
    tool_torque: np.ndarray | None = None

    def __post_init__(self):
        rec = self.recording
        if rec.qd is None or rec.qdd is None:
            raise ParameterError(f"RefinementBlock.recording needs qd and qdd ({rec.name}); run preprocess first.")
        tool = np.zeros_like(rec.q) if self.tool_torque is None else np.asarray(self.tool_torque, dtype=float)
        if tool.shape != rec.q.shape:
            raise ShapeError(f"RefinementBlock.tool_torque must have shape {rec.q.shape}; got {tool.shape}.")
        object.__setattr__(self, "tool_torque", tool)


@dataclass(frozen=True, eq=False)
class RefinementResult:
    """Result of :func:`refine_parameters`.

    Attributes
    ----------
    theta : array, shape (n_base,)
    kt : array, shape (n_dof,)
    lugre : tuple of LuGreParameters
    status : str
    iterations : int
    objective_initial, objective_final : float
        Normalised mean squared torque error before and after.
    seconds : float
    """

    theta: np.ndarray
    kt: np.ndarray
    lugre: tuple
    status: str
    iterations: int
    objective_initial: float
    objective_final: float
    seconds: float


def steady_mask(t, qd, lugre: LuGreParameters, factor: float, min_speed: float) -> np.ndarray:
    """Rows whose joint slid further than ``factor * fs / sigma0`` since its last reversal and moves faster than
    ``min_speed``."""
    q = np.concatenate([[0.0], np.cumsum(0.5 * (qd[1:] + qd[:-1]) * np.diff(t))])
    sign = np.sign(qd)
    change = np.concatenate([[True], sign[1:] != sign[:-1]])
    anchor = np.maximum.accumulate(np.where(change, np.arange(q.size), 0))
    travelled = np.abs(q - q[anchor])
    return (travelled > factor * lugre.fs / lugre.sigma0) & (np.abs(qd) > min_speed)


@dataclass(frozen=True, eq=False)
class _JointRows:
    """The rows of one joint over all blocks: regressor, current, direct torque, tool torque, qd and steady weight."""

    y: np.ndarray
    current: np.ndarray
    direct: np.ndarray
    tool: np.ndarray
    qd: np.ndarray
    weight: np.ndarray


@dataclass(frozen=True, eq=False)
class _Variables:
    """The scaled decision variables and the parameters they give (module docstring of the scaling)."""

    theta: ca.MX
    kt: ca.MX
    friction: ca.MX
    theta_expr: ca.MX
    kt_expr: object
    theta_scale: np.ndarray


def refine_parameters(
    model: PSDMModel,
    blocks,
    theta,
    kt,
    lugre,
    options: RefinementOptions | None = None,
    q_min=None,
    q_max=None,
    rng: np.random.Generator | None = None,
    excitation=None,
) -> RefinementResult:
    """Refine base parameters, motor constants and friction together by Ipopt (module docstring).

    Parameters
    ----------
    model : PSDMModel
    blocks : sequence of RefinementBlock
    theta : array, shape (n_base,)
        Starting base parameters (steps 2 and 4).
    kt : array, shape (n_dof,)
        Starting motor constants (step 1).
    lugre : sequence of LuGreParameters, length n_dof
        Starting friction (step 3).
    options : RefinementOptions, optional
    q_min, q_max : array, shape (n_dof,), optional
        Joint ranges for the consistency constraint.
    rng : numpy.random.Generator, optional
        Configurations of the consistency constraint.
    excitation : ExcitationThresholds, optional
        ``max_condition`` bounds the condition number of the freed base parameters' (and Kt's) columns
        over the steady rows, weighted as in the objective and scaled to unit norm (default
        ``ExcitationThresholds()``); the friction parameters are bounded near the step values instead.

    Returns
    -------
    RefinementResult

    Raises
    ------
    SolverError
        When Ipopt fails (status and iterations attached).
    InsufficientExcitationError
        When the rows do not excite a freed parameter (rank-deficient or ill-conditioned columns).
    """
    options = RefinementOptions() if options is None else options
    blocks, theta0, kt0, lugre = _check_inputs(model, blocks, theta, kt, lugre)
    start = time.perf_counter()
    rows = _joint_rows(model, blocks, lugre, options)
    _check_excited(model, rows, kt0, options, thresholds_of("refine_parameters", excitation))
    variables = _variables(model, theta0, kt0, options)
    objective = _objective(rows, variables, kt0, lugre, options)
    x = ca.vertcat(variables.theta, variables.kt, variables.friction)
    g, extra, extra0 = [], [], []
    if options.consistency == "constrain":
        g, extra, extra0 = _consistency_constraints(model, variables.theta_expr, theta0, options, q_min, q_max, rng)
        x = ca.vertcat(x, *extra)
    x0 = np.concatenate([np.zeros(model.n_base + 5 * model.n_dof)] + extra0)
    xo, f0, f_final, status, iterations = _solve(model, x, objective, g, x0, options)
    theta_new, kt_new, new_lugre = _parameters(xo, variables.theta_scale, theta0, kt0, lugre, options)
    return RefinementResult(
        theta=theta_new,
        kt=kt_new,
        lugre=new_lugre,
        status=status,
        iterations=iterations,
        objective_initial=f0,
        objective_final=f_final,
        seconds=time.perf_counter() - start,
    )


def _check_inputs(model, blocks, theta, kt, lugre):
    if not isinstance(model, PSDMModel):
        raise ParameterError(f"refine_parameters.model must be a PSDMModel; got {type(model).__name__}.")
    blocks = list(blocks)
    if not blocks or not all(isinstance(b, RefinementBlock) for b in blocks):
        raise ParameterError("refine_parameters.blocks must be a non-empty sequence of RefinementBlock.")
    n, l = model.n_dof, model.n_base
    theta0 = np.asarray(theta, dtype=float).reshape(-1)
    kt0 = np.asarray(kt, dtype=float).reshape(-1)
    if theta0.size != l or kt0.size != n:
        raise ShapeError(f"refine_parameters.theta/kt must have {l}/{n} values; got {theta0.size}/{kt0.size}.")
    lugre = tuple(lugre)
    if len(lugre) != n or not all(isinstance(p, LuGreParameters) for p in lugre):
        raise ParameterError(f"refine_parameters.lugre must hold {n} LuGreParameters; fit the friction step first.")
    return blocks, theta0, kt0, lugre


def _joint_rows(model, blocks, lugre, options) -> list:
    """Per joint, the rows of every block stacked (steady weight from :func:`steady_mask`)."""
    n = model.n_dof
    parts = [[] for _ in range(n)]
    for block in blocks:
        rec = block.recording
        y = regressor_chunked(model, rec.q, rec.qd, rec.qdd)
        current = rec.current if rec.current is not None else np.zeros_like(rec.q)
        direct = rec.tau if rec.current is None else np.zeros_like(rec.q)
        for j in range(n):
            w = steady_mask(rec.t, rec.qd[:, j], lugre[j], options.presliding_factor, options.min_speed)
            parts[j].append(
                (y[:, j, :], current[:, j], direct[:, j], block.tool_torque[:, j], rec.qd[:, j], w.astype(float))
            )
    return [
        _JointRows(np.vstack([p[0] for p in joint]), *(np.concatenate([p[k] for p in joint]) for k in range(1, 6)))
        for joint in parts
    ]


def _check_excited(model, rows, kt0, options, thresholds) -> None:
    """The freed linear parameters' columns (base parameters, and Kt when freed) over the steady rows, weighted as
    the objective weights them, must be excited. The friction parameters are left out: they stay within
    ``exp(+-3)`` of the step values (``_bounds``), so an unexcited one keeps its value instead of running off."""
    n = model.n_dof
    free = ~model.gravity_mask | bool(options.refine_gravity)
    n_free = int(free.sum())
    kt_free = [j for j in range(n) if options.refine_kt and np.any(rows[j].current != 0)]
    names = [name for name, f in zip(model.base_names, free) if f] + [f"kt{j + 1}" for j in kt_free]
    column_joints = [o for o, f in zip(base_parameter_joints(model), free) if f] + [(j,) for j in kt_free]
    parts, weights = [], []
    for j, r in enumerate(rows):
        keep = r.weight > 0
        if not keep.any():
            continue
        block = np.zeros((int(keep.sum()), len(names)))
        block[:, :n_free] = r.y[keep][:, free]
        if j in kt_free:
            block[:, n_free + kt_free.index(j)] = r.current[keep]
        scale = max(float(rms(kt0[j] * r.current[keep] + r.direct[keep])), 1e-6)
        parts.append(block)
        weights.append(np.full(block.shape[0], 1.0 / (block.shape[0] * scale**2)))
    matrix = np.vstack(parts) if parts else np.zeros((0, len(names)))
    w = np.concatenate(weights) if weights else np.zeros(0)
    # a column the refinement's rows do not touch cannot move its objective: that parameter keeps the value
    # its step identified (and checked); only the columns the rows do touch must be excited
    if matrix.size:
        norms = np.sqrt(w @ matrix**2)
        touched = norms > ZERO_COLUMN * float(norms.max(initial=0.0))
    else:  # no rows at all: the check below says so
        touched = np.ones(len(names), dtype=bool)
    if not touched.all():
        held = [name for name, keep in zip(names, touched) if not keep]
        logger.info("refine: %s not in the refinement's rows; kept at the values of their steps", ", ".join(held))
    check_regressor(
        matrix[:, touched],
        w,
        names=[name for name, keep in zip(names, touched) if keep],
        column_joints=[joints for joints, keep in zip(column_joints, touched) if keep],
        owner="refine_parameters",
        source="the training parts of every experiment",
        fix=EXCITATION_FIX,
        max_condition=thresholds.max_condition,
    )


def _variables(model, theta0, kt0, options) -> _Variables:
    """Scaled variables: theta = theta0 + s_theta x, kt = kt0 (1 + x), friction = p0 exp(x)."""
    n, l = model.n_dof, model.n_base
    s_theta = np.maximum(np.abs(theta0), 1e-2 * max(np.abs(theta0).max(), 1e-9))
    x_theta = ca.MX.sym("x_theta", l)
    x_kt = ca.MX.sym("x_kt", n)
    x_fr = ca.MX.sym("x_friction", 4 * n)  # fc, fs, fv, dv per joint
    theta_expr = ca.DM(theta0) + ca.DM(s_theta) * x_theta
    kt_expr = ca.DM(kt0) * (1 + x_kt) if options.refine_kt else ca.DM(kt0)
    return _Variables(x_theta, x_kt, x_fr, theta_expr, kt_expr, s_theta)


def _objective(rows, variables, kt0, lugre, options):
    """Normalised mean squared torque error over the steady rows of every joint."""
    n = len(rows)
    objective = 0
    for j in range(n):
        p = lugre[j]
        if options.refine_friction:
            fc, fs, fv, dv = (
                v0 * ca.exp(variables.friction[4 * j + k]) for k, v0 in enumerate((p.fc, p.fs, p.fv, p.dv))
            )
        else:
            fc, fs, fv, dv = p.fc, p.fs, p.fv, p.dv
        r = rows[j]
        keep = r.weight > 0
        if not keep.any():
            continue
        qd_k = r.qd[keep]
        log_v = ca.DM(np.log(np.abs(qd_k)))
        sgn = ca.DM(np.sign(qd_k))
        stribeck = (fc + (fs - fc) * ca.exp(-ca.DM((qd_k / p.vs) ** 2)) + fv * ca.exp(dv * log_v)) * sgn
        measured = variables.kt_expr[j] * ca.DM(r.current[keep]) + ca.DM(r.direct[keep])
        predicted = ca.mtimes(ca.DM(r.y[keep]), variables.theta_expr) + ca.DM(r.tool[keep]) + stribeck
        residual = measured - predicted
        observed = kt0[j] * r.current[keep] + r.direct[keep]
        scale = max(float(rms(observed)), 1e-6)
        objective = objective + ca.sumsqr(residual) / (keep.sum() * scale**2 * n)
    return objective


def _consistency_constraints(model, theta_expr, theta0, options, q_min, q_max, rng):
    """D(q_k, theta) = L_k L_k^T + eps I at sampled q_k: constraints, Cholesky variables and their start values."""
    n, l = model.n_dof, model.n_base
    rng = np.random.default_rng(0) if rng is None else rng
    if q_min is None or q_max is None:
        raise ParameterError("refine_parameters needs q_min and q_max with consistency='constrain'.")
    qs = rng.uniform(np.asarray(q_min, float), np.asarray(q_max, float), (options.n_consistency, n))
    # D(q, theta) is linear in theta: D = sum_k theta_k D_k(q)
    basis = np.stack([mass_matrices(model, np.eye(l)[k], qs) for k in range(l)], axis=-1)  # (m, n, n, l)
    tril = np.tril_indices(n)
    g, extra, extra0 = [], [], []
    for m in range(qs.shape[0]):
        lvars = ca.MX.sym(f"L{m}", len(tril[0]))
        lmat = ca.MX.zeros(n, n)
        for k, (r, c) in enumerate(zip(*tril)):
            lmat[int(r), int(c)] = lvars[k]
        d_theta = sum(ca.DM(basis[m, :, :, k]) * theta_expr[k] for k in range(l) if np.any(basis[m, :, :, k]))
        diff = d_theta - ca.mtimes(lmat, lmat.T) - options.eps * ca.DM.eye(n)
        g.append(ca.vertcat(*[diff[int(r), int(c)] for r, c in zip(*tril)]))
        extra.append(lvars)
        d0 = mass_matrices(model, theta0, qs[m : m + 1])[0] - options.eps * np.eye(n)
        w_eig, v_eig = np.linalg.eigh(d0)
        l0 = np.linalg.cholesky(v_eig @ np.diag(np.maximum(w_eig, 1e-6)) @ v_eig.T)
        extra0.append(l0[tril])
    return g, extra, extra0


def _bounds(model, size, options):
    """Variable bounds: Kt within 50 %, friction within exp(+-3), held parameters fixed at their start."""
    n, l = model.n_dof, model.n_base
    bound = np.full(size, np.inf)
    lbx, ubx = -bound, bound.copy()
    lbx[l : l + n], ubx[l : l + n] = -0.5, 0.5
    lbx[l + n : l + 5 * n], ubx[l + n : l + 5 * n] = -3.0, 3.0
    if not options.refine_kt:
        lbx[l : l + n] = ubx[l : l + n] = 0.0
    if not options.refine_friction:
        lbx[l + n : l + 5 * n] = ubx[l + n : l + 5 * n] = 0.0
    if not options.refine_gravity:
        lbx[:l][model.gravity_mask] = ubx[:l][model.gravity_mask] = 0.0
    return lbx, ubx


def _solve(model, x, objective, g, x0, options):
    """Ipopt from ``x0``: the solution, the objective before and after, status and iterations."""
    nlp = {"x": x, "f": objective, "g": ca.vertcat(*g) if g else ca.MX(0, 1)}
    ipopt = {
        "max_iter": int(options.max_iter),
        "tol": float(options.tol),
        "print_level": int(options.print_level),
        "sb": "yes",
    }
    ipopt.update(options.ipopt_options)
    solver = ca.nlpsol("refinement", "ipopt", nlp, {"ipopt": ipopt, "print_time": False})
    f0 = float(ca.Function("f0", [x], [objective])(x0))
    lbx, ubx = _bounds(model, x0.size, options)
    sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=0.0 if g else [], ubg=0.0 if g else [])
    stats = solver.stats()
    status = str(stats.get("return_status", "unknown"))
    iterations = int(stats.get("iter_count", -1))
    if status not in _SUCCESS:
        raise SolverError(
            f"refine_parameters: Ipopt returned status {status} after {iterations} iterations. "
            "Check the step estimates or raise RefinementOptions.max_iter.",
            status=status,
            iterations=iterations,
        )
    return np.asarray(sol["x"]).ravel(), f0, float(sol["f"]), status, iterations


def _parameters(xo, s_theta, theta0, kt0, lugre, options):
    """Base parameters, Kt and LuGre of the scaled solution ``xo``."""
    n, l = kt0.size, theta0.size
    theta_new = theta0 + s_theta * xo[:l]
    kt_new = kt0 * (1 + xo[l : l + n]) if options.refine_kt else kt0.copy()
    fr = xo[l + n : l + 5 * n].reshape(n, 4)
    new_lugre = []
    for j, p in enumerate(lugre):
        if options.refine_friction:
            fc, fs, fv, dv = (v0 * np.exp(fr[j, k]) for k, v0 in enumerate((p.fc, p.fs, p.fv, p.dv)))
            new_lugre.append(LuGreParameters(fc=fc, fs=fs, vs=p.vs, fv=fv, dv=dv, sigma0=p.sigma0, sigma1=p.sigma1))
        else:
            new_lugre.append(p)
    return theta_new, kt_new, tuple(new_lugre)
