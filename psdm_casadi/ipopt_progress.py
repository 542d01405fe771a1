"""Ipopt's iterations as a progress bar on a terminal: one progress record per iteration, through logging.

Long Ipopt solves (the consistent fit of a 7-joint arm, LuGre multiple shooting, the excitation design) run
for seconds to minutes with nothing on the screen. :class:`IpoptProgress` is a CasADi iteration callback
(``nlpsol`` option ``iteration_callback``): after every Ipopt iteration it logs one record with
``extra={"progress": (iteration, max_iter), "tick": True, "bar_only": True, "postfix": "obj ..., inf_pr ..."}``
that the command line's ``ProgressHandler`` draws as a tqdm bar on a terminal (the objective and the primal
infeasibility in its postfix) and drops elsewhere (a file, a pipe, ``--json``, ``--quiet``: nothing printed);
:meth:`IpoptProgress.close` ends the bar. The library decides nothing about terminals: it only logs.

:func:`progress_options` gives the ``nlpsol`` options with the callback only when a handler on the logger's
way says it draws bars (``draws_progress_bars()``: the command line's on a terminal); elsewhere (a library
user's own logging, a file, a pipe, ``--json``) the solve has no callback: nothing printed, nothing paid.
The callback's own cost is a copy of the iterate and a max over the constraints
(``benchmarks/ipopt_progress.py`` measures it on the Panda's consistent fit).
"""

from __future__ import annotations

import logging
import time

import casadi as ca
import numpy as np

__all__ = ["IpoptProgress", "progress_options", "shows_progress_bars"]


class IpoptProgress(ca.Callback):
    """Ipopt iteration callback that logs one progress record per iteration (module docstring).

    Parameters
    ----------
    name : str
        CasADi's name of the callback function.
    sizes : tuple of int
        ``(n_x, n_g, n_p)`` of the NLP.
    max_iter : int
        Ipopt's iteration cap: the bar's total.
    label : str
        The bar's description (``"identify: consistent fit (Ipopt)"``).
    logger : logging.Logger
        Where the records go.
    lbg, ubg : array, optional
        The constraint bounds, for the primal infeasibility shown (default: equalities ``g = 0``).

    Attributes
    ----------
    iterations : int
        Iterations seen so far.
    seconds : float
        Time spent inside the callback [s] (its cost, measured).
    """

    def __init__(self, name: str, sizes: tuple, max_iter: int, label: str, logger: logging.Logger,
                 lbg=None, ubg=None):  # fmt: skip
        ca.Callback.__init__(self)
        n_x, n_g, n_p = (int(v) for v in sizes)
        self._sizes = {"x": n_x, "lam_x": n_x, "g": n_g, "lam_g": n_g, "p": n_p, "lam_p": n_p, "f": 1}
        self.max_iter, self.label, self.logger = int(max_iter), label, logger
        self.set_bounds(lbg, ubg)
        self.iterations, self.seconds = 0, 0.0
        self.construct(name, {})

    def set_bounds(self, lbg=None, ubg=None) -> None:
        """The constraint bounds of the next solve (for the infeasibility in the postfix)."""
        n_g = self._sizes["g"]
        self._lbg = np.zeros(n_g) if lbg is None else np.broadcast_to(np.asarray(lbg, dtype=float), (n_g,))
        self._ubg = np.zeros(n_g) if ubg is None else np.broadcast_to(np.asarray(ubg, dtype=float), (n_g,))

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "stop"

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self._sizes.get(ca.nlpsol_out(i), 0), 1)

    def eval(self, arg):
        start = time.perf_counter()
        self.iterations += 1
        objective = float(arg[1])
        g = np.asarray(arg[2], dtype=float).reshape(-1)
        violation = max(np.max(self._lbg - g, initial=0.0), np.max(g - self._ubg, initial=0.0))
        self.logger.info(
            "%s", self.label,
            extra={"progress": (min(self.iterations, self.max_iter), self.max_iter), "tick": True, "bar_only": True,
                   "postfix": f"obj {objective:.6g}, inf_pr {float(violation):.1e}"},
        )  # fmt: skip
        self.seconds += time.perf_counter() - start
        return [0]

    def close(self) -> None:
        """End the bar of this solve (the next solve starts a new one)."""
        if self.iterations:
            self.logger.info("%s", self.label, extra={"progress_end": True, "bar_only": True})
        self.iterations = 0


def progress_options(name: str, sizes: tuple, max_iter: int, label: str, logger: logging.Logger,
                     lbg=None, ubg=None) -> tuple:  # fmt: skip
    """``(nlpsol options, IpoptProgress or None)``: the iteration callback when a handler of ``logger`` draws
    progress bars (the command line's on a terminal: ``draws_progress_bars()``), else none (nothing to pay)."""
    if not shows_progress_bars(logger):
        return {}, None
    callback = IpoptProgress(name, sizes, max_iter, label, logger, lbg, ubg)
    return {"iteration_callback": callback}, callback


def shows_progress_bars(logger: logging.Logger) -> bool:
    """Whether ``logger`` shows INFO and a handler on its way up draws progress bars (a terminal, not a file)."""
    if not logger.isEnabledFor(logging.INFO):
        return False
    current = logger
    while current is not None:
        if any(getattr(h, "draws_progress_bars", lambda: False)() for h in current.handlers):
            return True
        current = current.parent if current.propagate else None
    return False
