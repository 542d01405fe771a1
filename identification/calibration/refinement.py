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
least-squares problem with no state variables, so Ipopt converges in tens of iterations from
the step estimates; the LuGre dynamics (z states) are left to the shooting step where they are
observable. The payload rows of the motor step fix the scale shared by Kt and the other parameters.

With ``consistency="constrain"``, D(q_k, theta) = L_k L_k^T + eps I is imposed at sampled
configurations q_k with L_k lower-triangular decision variables (a Cholesky certificate of
positive definiteness; D is linear in theta).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError, ShapeError, SolverError
from psdm_casadi.model import PSDMModel

from identification.calibration.consistency import mass_matrices
from identification.friction.models import LuGreParameters
from identification.data.recording import Recording
from identification.calibration.steps import regressor_chunked

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
        dedicated experiment, and the refinement's rows carry the errors of its simpler models. On
        the virtual Denso freeing Kt let model errors of the other rows pull all Kt by about 3 %;
        freeing friction moved fs by 5-12 % (the steady-state curve does not see the bristle
        dynamics), and freeing gravity moved the small gravity parameters by up to 24 %.
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
            raise ParameterError(f"RefinementOptions.consistency must be 'none' or 'constrain'; got {self.consistency!r}.")
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
    """Rows whose joint slid further than ``factor * fs / sigma0`` since its last reversal and moves faster than ``min_speed``."""
    q = np.concatenate([[0.0], np.cumsum(0.5 * (qd[1:] + qd[:-1]) * np.diff(t))])
    sign = np.sign(qd)
    change = np.concatenate([[True], sign[1:] != sign[:-1]])
    anchor = np.maximum.accumulate(np.where(change, np.arange(q.size), 0))
    travelled = np.abs(q - q[anchor])
    return (travelled > factor * lugre.fs / lugre.sigma0) & (np.abs(qd) > min_speed)


def refine_parameters(model: PSDMModel, blocks, theta, kt, lugre, options: RefinementOptions | None = None,
                      q_min=None, q_max=None, rng: np.random.Generator | None = None) -> RefinementResult:
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

    Returns
    -------
    RefinementResult

    Raises
    ------
    SolverError
        When Ipopt fails (status and iterations attached).
    """
    options = RefinementOptions() if options is None else options
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
    start = time.perf_counter()

    # data per joint: Y rows, current, direct torque, tool, qd, weights
    per_joint = {key: [[] for _ in range(n)] for key in ("y", "i", "d", "tool", "qd", "w")}
    for block in blocks:
        rec = block.recording
        y = regressor_chunked(model, rec.q, rec.qd, rec.qdd)
        current = rec.current if rec.current is not None else np.zeros_like(rec.q)
        direct = rec.tau if rec.current is None else np.zeros_like(rec.q)
        for j in range(n):
            w = steady_mask(rec.t, rec.qd[:, j], lugre[j], options.presliding_factor, options.min_speed)
            for key, value in (("y", y[:, j, :]), ("i", current[:, j]), ("d", direct[:, j]),
                               ("tool", block.tool_torque[:, j]), ("qd", rec.qd[:, j]), ("w", w.astype(float))):
                per_joint[key][j].append(value)
    data = {key: [np.concatenate(v) if key != "y" else np.vstack(v) for v in values]
            for key, values in per_joint.items()}

    # decision variables, scaled: theta = theta0 + s_theta x, kt = kt0 (1 + x), friction = p0 exp(x)
    s_theta = np.maximum(np.abs(theta0), 1e-2 * max(np.abs(theta0).max(), 1e-9))
    x_theta = ca.MX.sym("x_theta", l)
    x_kt = ca.MX.sym("x_kt", n)
    x_fr = ca.MX.sym("x_friction", 4 * n)  # fc, fs, fv, dv per joint
    theta_expr = ca.DM(theta0) + ca.DM(s_theta) * x_theta
    kt_expr = ca.DM(kt0) * (1 + x_kt) if options.refine_kt else ca.DM(kt0)
    objective = 0
    for j in range(n):
        p = lugre[j]
        if options.refine_friction:
            fc, fs, fv, dv = (v0 * ca.exp(x_fr[4 * j + k]) for k, v0 in enumerate((p.fc, p.fs, p.fv, p.dv)))
        else:
            fc, fs, fv, dv = p.fc, p.fs, p.fv, p.dv
        qd = data["qd"][j]
        w = data["w"][j]
        keep = w > 0
        if not keep.any():
            continue
        qd_k = qd[keep]
        log_v = ca.DM(np.log(np.abs(qd_k)))
        sgn = ca.DM(np.sign(qd_k))
        stribeck = (fc + (fs - fc) * ca.exp(-ca.DM((qd_k / p.vs) ** 2)) + fv * ca.exp(dv * log_v)) * sgn
        measured = kt_expr[j] * ca.DM(data["i"][j][keep]) + ca.DM(data["d"][j][keep])
        predicted = ca.mtimes(ca.DM(data["y"][j][keep]), theta_expr) + ca.DM(data["tool"][j][keep]) + stribeck
        residual = measured - predicted
        observed = kt0[j] * data["i"][j][keep] + data["d"][j][keep]
        scale = max(float(np.sqrt(np.mean(observed**2))), 1e-6)
        objective = objective + ca.sumsqr(residual) / (keep.sum() * scale**2 * n)
    x = ca.vertcat(x_theta, x_kt, x_fr)
    g, lbg, ubg, extra, extra0 = [], [], [], [], []
    if options.consistency == "constrain":
        rng = np.random.default_rng(0) if rng is None else rng
        if q_min is None or q_max is None:
            raise ParameterError("refine_parameters needs q_min and q_max with consistency='constrain'.")
        qs = rng.uniform(np.asarray(q_min, float), np.asarray(q_max, float), (options.n_consistency, n))
        # D(q, theta) is linear in theta: D = sum_k theta_k D_k(q)
        basis = np.stack([mass_matrices(model, np.eye(l)[k], qs) for k in range(l)], axis=-1)  # (m, n, n, l)
        tril = np.tril_indices(n)
        for m in range(qs.shape[0]):
            lvars = ca.MX.sym(f"L{m}", len(tril[0]))
            lmat = ca.MX.zeros(n, n)
            for k, (r, c) in enumerate(zip(*tril)):
                lmat[int(r), int(c)] = lvars[k]
            d_theta = sum(ca.DM(basis[m, :, :, k]) * theta_expr[k] for k in range(l) if np.any(basis[m, :, :, k]))
            diff = d_theta - ca.mtimes(lmat, lmat.T) - options.eps * ca.DM.eye(n)
            g.append(ca.vertcat(*[diff[int(r), int(c)] for r, c in zip(*tril)]))
            extra.append(lvars)
            d0 = mass_matrices(model, theta0, qs[m:m + 1])[0] - options.eps * np.eye(n)
            w_eig, v_eig = np.linalg.eigh(d0)
            l0 = np.linalg.cholesky(v_eig @ np.diag(np.maximum(w_eig, 1e-6)) @ v_eig.T)
            extra0.append(l0[tril])
        x = ca.vertcat(x, *extra)
        lbg = ubg = 0.0
    x0 = np.concatenate([np.zeros(l + 5 * n)] + extra0)
    nlp = {"x": x, "f": objective, "g": ca.vertcat(*g) if g else ca.MX(0, 1)}
    ipopt = {"max_iter": int(options.max_iter), "tol": float(options.tol), "print_level": int(options.print_level),
             "sb": "yes"}
    ipopt.update(options.ipopt_options)
    solver = ca.nlpsol("refinement", "ipopt", nlp, {"ipopt": ipopt, "print_time": False})
    f0 = float(ca.Function("f0", [x], [objective])(x0))
    bound = np.full(x0.size, np.inf)
    lbx, ubx = -bound, bound.copy()
    lbx[l:l + n], ubx[l:l + n] = -0.5, 0.5
    lbx[l + n:l + 5 * n], ubx[l + n:l + 5 * n] = -3.0, 3.0
    if not options.refine_kt:
        lbx[l:l + n] = ubx[l:l + n] = 0.0
    if not options.refine_friction:
        lbx[l + n:l + 5 * n] = ubx[l + n:l + 5 * n] = 0.0
    if not options.refine_gravity:
        lbx[:l][model.gravity_mask] = ubx[:l][model.gravity_mask] = 0.0
    sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg if g else [], ubg=ubg if g else [])
    stats = solver.stats()
    status = str(stats.get("return_status", "unknown"))
    iterations = int(stats.get("iter_count", -1))
    if status not in _SUCCESS:
        raise SolverError(f"refine_parameters: Ipopt returned status {status} after {iterations} iterations. "
                          "Check the step estimates or raise RefinementOptions.max_iter.", status=status,
                          iterations=iterations)
    xo = np.asarray(sol["x"]).ravel()
    theta_new = theta0 + s_theta * xo[:l]
    kt_new = kt0 * (1 + xo[l:l + n]) if options.refine_kt else kt0.copy()
    fr = xo[l + n:l + 5 * n].reshape(n, 4)
    new_lugre = []
    for j, p in enumerate(lugre):
        if options.refine_friction:
            fc, fs, fv, dv = (v0 * np.exp(fr[j, k]) for k, v0 in enumerate((p.fc, p.fs, p.fv, p.dv)))
            new_lugre.append(LuGreParameters(fc=fc, fs=fs, vs=p.vs, fv=fv, dv=dv, sigma0=p.sigma0, sigma1=p.sigma1))
        else:
            new_lugre.append(p)
    return RefinementResult(theta=theta_new, kt=kt_new, lugre=tuple(new_lugre), status=status, iterations=iterations,
                            objective_initial=f0, objective_final=float(sol["f"]), seconds=time.perf_counter() - start)
