"""Thread counts of the BLAS libraries numpy and scipy call, made explicit for a run.

A step calls BLAS on small or thin operands (vector norms and dot products
of GMRES, the triangular solves inside SuperLU, the batched element
contractions).  With the default pool — one OpenBLAS thread per core — each
such call wakes the pool; on a machine with 2 cores shared with other
processes the threads wait for each other and a 22k-vector norm can cost
milliseconds instead of microseconds (docs/performance.md, "Threads").  A
run therefore limits BLAS to ``[solver] threads`` (default 1) through
threadpoolctl; 0 leaves the libraries' own defaults (e.g. the environment
variables ``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS``).  MKL PARDISO's
OpenMP pool (extra ``fast``) is not a BLAS pool and keeps its threads for
the factorization: set ``MKL_NUM_THREADS`` to change it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator


@contextlib.contextmanager
def blas_threads(threads: int) -> Iterator[None]:
    """Within the block, BLAS libraries use at most ``threads`` threads (0: unchanged).

    >>> with blas_threads(1):
    ...     pass
    """
    if threads <= 0:
        yield
        return
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=threads, user_api="blas"):
        yield
