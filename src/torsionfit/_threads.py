"""NumPy's BLAS threads for the command line and the batch's worker processes.

OpenBLAS starts a thread per core and keeps it spinning for a while after every call.
torsionfit's NumPy linear algebra is on small matrices (the Laplace covariance, 12 × 12 for a
loop), which one thread does at once, while the spinning threads take the cores from XLA's
computations. Measured with `torsionfit batch` on 16 SYNTHETIC 10 001-sample units, 2 cores,
warm compilation cache: 36 s → 29 s in one process, 74 s → 25 s in two worker processes. The
library does not change this on import (no global state); the commands do.
"""

import os
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

_ENV = "OPENBLAS_NUM_THREADS"


def one_blas_thread():
    """Limit NumPy's BLAS to one thread from now on: the BLAS libraries loaded already are limited
    (threadpoolctl) and those loaded later (SciPy's own OpenBLAS, imported by ArviZ) read
    ``OPENBLAS_NUM_THREADS=1`` when they load. Returns a function that restores both."""
    before = os.environ.get(_ENV)
    os.environ[_ENV] = "1"
    limiter = threadpool_limits(limits=1, user_api="blas")

    def restore():
        limiter.restore_original_limits()
        if before is None:
            os.environ.pop(_ENV, None)
        else:
            os.environ[_ENV] = before

    return restore


@contextmanager
def single_blas_thread():
    """:func:`one_blas_thread` inside the block, the previous limits and environment after it."""
    restore = one_blas_thread()
    try:
        yield
    finally:
        restore()
