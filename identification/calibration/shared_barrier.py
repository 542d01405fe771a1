"""Consistent fits of one structure solved by one barrier-path solver, their data as its parameters.

weighted normal equations + the consistent fit's pieces (``consistent_fit``) -> the barrier path's problem with the
data as parameters, and the key of its structure -> ``barrier_path.barrier_solution(shared=...)``.

Building the Ipopt solver of a consistent fit (``ca.nlpsol``: the barrier's and the data term's derivatives, made
symbolically) costs as much as solving it: on the Panda about 0.3 s of a 0.75-s fit, twice per fit (the second
pass is reweighted). The column check's judges (``column_check``) are eight fits of two column sets on the blocks of
the training recording: sixteen solvers for two structures. Inside :func:`shared_solvers` a fit whose structure (the
variables, the regression vector ``x`` they make, the links' constraints, the pull towards the robot file, the
bodies' sizes and margin) was built before takes that solver, and its data enter as parameters: the data term
written as ``consistent_fit.centred_residual`` writes it,

    ((x - x_ls)' G (x - x_ls) - 2 r' (x - x_ls) + e_ls) / count,

with the weighted Gram matrix ``G``, the least-squares minimum ``x_ls``, its round-off ``r``, the value there
``e_ls``, the sample count and the pull's weight (which follows the data's independent samples, ``prior_pull``) as
parameters. It is the same convex problem, reached to Ipopt's tolerance; the iterates' round-off differs from the
unshared solve's, which moves a fit along a flat valley by a small share of a standard deviation. A fit whose shared
solver stops short of the path's end (an Ipopt failure, its iteration cap) is solved again with a solver of its own,
as outside the scope (``consistent_fit``): the chart fallback's answer would differ from the fit alone (by 3e-4 of a
Denso fold's RMSE), so a judge never rests on a shared solve that failed.

The scope is for judges: the model a command writes is fitted outside it (identify's written Panda model is the same
bit for bit). On the Panda's column check the fold fits take 0.23 s instead of 0.75 (two solvers built instead of
sixteen) and the verdict's numbers are the same to 4 digits. The other judges fitted over blocks of the training
recordings share theirs too, each keeping its solvers between its turns (the written model's fits come between):
identify's counterbalance (``counterbalance_folds.BlockFolds``: the models without and with the springs on each
block, the laws' neutral angles, their never-worse refits; the heavy virtual arm's 12 fold fits build 3 solvers
instead of 24) and the never-worse gate's refits without each block (``never_worse.TrainingRefits``, ``psdm diagnose
--apply``'s second opinion: 16 refits on the virtual Denso with a spring and a delay, 2 solvers instead of 32).
"""

from __future__ import annotations

import contextlib
import contextvars

import casadi as ca
import numpy as np

__all__ = ["shared_problem", "shared_solvers", "sharing"]

#: The solvers of the open :func:`shared_solvers` block, by structure (None: no block open).
_SOLVERS = contextvars.ContextVar("psdm_shared_barrier_solvers", default=None)


@contextlib.contextmanager
def shared_solvers(solvers: dict | None = None):
    """Within: consistent fits of one structure share one barrier-path solver (module docstring); the solvers are
    dropped when the outermost block ends, or kept in ``solvers`` when given (a judge whose fold fits come in turns,
    with fits of the written model outside the scope between them: ``never_worse.TrainingRefits``,
    ``counterbalance_folds.BlockFolds``). A block inside an open one uses the open block's solvers."""
    token = _SOLVERS.set({} if solvers is None else solvers) if _SOLVERS.get() is None else None
    try:
        yield
    finally:
        if token is not None:
            _SOLVERS.reset(token)


def sharing() -> bool:
    """Whether a :func:`shared_solvers` block is open: a fit made here is solved by a shared solver, whose round-off
    differs from its own solver's (a memory of fits keys on it, ``trial_fits``)."""
    return _SOLVERS.get() is not None


def shared_problem(plain, normal, margin: float) -> tuple:
    """``(problem, (solvers, key, values))`` for ``barrier_path.barrier_solution`` inside :func:`shared_solvers`,
    ``(None, None)`` outside: ``plain`` the fit's pieces in the standard parameters (``consistent_fit``:
    ``variables``, ``x``, ``pull`` (unweighted, weight), ``g``, ``sizes``), ``normal`` its weighted normal equations
    ``(gram, moment, energy, count)``."""
    solvers = _SOLVERS.get()
    if solvers is None:
        return None, None
    v, pull, x = plain["variables"], plain["pull"], plain["x"]
    gram, moment, energy, count = normal
    centre = np.linalg.lstsq(gram, moment, rcond=None)[0]  # as ``consistent_fit.centred_residual``
    rest = moment - gram @ centre
    level = energy - 2.0 * moment @ centre + centre @ gram @ centre
    values = np.concatenate([gram.reshape(-1, order="F"), centre, rest, [level, count, pull[1]]])
    floors = tuple(None if f is None else np.asarray(f).tobytes() for f in plain.get("floors", ()))
    key = (v.numel(), tuple(plain["sizes"]), floors, margin,
           ca.Function("key", [v], [x, plain["g"], pull[0]]).serialize())  # fmt: skip
    if key in solvers:
        return {}, (solvers, key, values)
    n = x.numel()
    g, c, r = ca.SX.sym("gram", n, n), ca.SX.sym("centre", n), ca.SX.sym("rest", n)
    e, m, w = ca.SX.sym("level"), ca.SX.sym("count"), ca.SX.sym("weight")
    d = x - c
    f = (ca.bilin(g, d, d) - 2 * ca.dot(r, d) + e) / m + w * pull[0]
    return {"x": v, "f": f, "g": plain["g"], "p": ca.vertcat(ca.vec(g), c, r, e, m, w)}, (solvers, key, values)
