"""One BLAS thread for the mocap solvers.

The joint pose-and-rotation solver factorises one dense system of about
1000 unknowns per window and trial; the known-rotation solver and the
bearing adjustment many smaller ones. For matrices of that size OpenBLAS
threads cost more in wake-ups and spinning than they save: a 1062 x 1062
Cholesky of ``solve_joint`` took 0.18-0.6 s CPU with two threads on the
shared 2-core machine under load and 0.016 s with one (docs/benchmarks.md,
"mocap tests"). ``photogram/__init__.py`` asks for one thread through
``OPENBLAS_NUM_THREADS``, which comes too late when numpy was imported
first (a notebook, pytest); :func:`one_blas_thread` applies the same policy
at run time with threadpoolctl. A thread count the user set in
``OPENBLAS_NUM_THREADS`` is respected; without threadpoolctl it is a no-op.
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading

__all__ = ["one_blas_thread", "single_blas_thread"]


def single_blas_thread():
    """Context manager: one BLAS thread in every BLAS library loaded now
    (threadpoolctl re-scans them, about 5 ms), unless the user set
    ``OPENBLAS_NUM_THREADS``."""
    if "OPENBLAS_NUM_THREADS" in os.environ:
        return contextlib.nullcontext()
    try:
        from threadpoolctl import threadpool_limits
        return threadpool_limits(limits=1, user_api="blas")
    except Exception:   # pragma: no cover - threadpoolctl missing or failing
        return contextlib.nullcontext()


_DEPTH = threading.local()


def one_blas_thread(func):
    """Decorator: run ``func`` inside :func:`single_blas_thread`; a call
    from inside another decorated function (the solvers called per batch
    by ``reconstruct``) skips the limit already in force (threadpoolctl's
    scan of the loaded libraries costs about 5 ms a call)."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        depth = getattr(_DEPTH, "n", 0)
        if depth:
            return func(*args, **kwargs)
        _DEPTH.n = 1
        try:
            with single_blas_thread():
                return func(*args, **kwargs)
        finally:
            _DEPTH.n = 0
    return wrapper
