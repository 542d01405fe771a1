"""One BLAS thread for a ``psdm`` command unless the user chose a number.

psdm's dense algebra is many small problems (least squares of a few dozen columns, eigenvalues of
10 x 10 pseudo-inertias, the column choice's refits) and a few tall ones. OpenBLAS's threads wait for
work by spinning: on a machine that also runs something else (a controller, a build, other workers)
a second thread makes a 200 x 40 least squares about 40x slower and a 20,000 x 60 one about 6x slower
(measured on this project's 2-core machine under load); on an idle machine a second thread gains at
most about 1.5x on the tallest problems. So a command runs with one BLAS thread by default, and any of
the usual variables (``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS``) set by the
user is left to decide.
"""

from __future__ import annotations

import contextlib
import os

#: Variables through which a user chooses the BLAS thread count themselves.
USER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def blas_thread_limit(environ=None):
    """A context that limits BLAS to one thread, or does nothing when the user set a thread variable."""
    environ = os.environ if environ is None else environ
    if any(environ.get(name) for name in USER_THREAD_VARIABLES):
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")
