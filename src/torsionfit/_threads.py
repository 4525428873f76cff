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


@contextmanager
def single_blas_thread():
    """One BLAS thread inside the block: the BLAS libraries loaded already are limited
    (threadpoolctl) and those loaded later (SciPy's own OpenBLAS, imported by ArviZ) read
    ``OPENBLAS_NUM_THREADS=1`` when they load; both are restored after the block."""
    before = os.environ.get(_ENV)
    os.environ[_ENV] = "1"
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
    finally:
        if before is None:
            os.environ.pop(_ENV, None)
        else:
            os.environ[_ENV] = before
