"""BLAS threads for small matrices: the ranking and mixed-model fits multiply and solve
matrices of a few to a few hundred rows, many times over, where BLAS threads only add
waiting (on a busy two-core machine a fit took five times as long with them)."""

from __future__ import annotations

from threadpoolctl import threadpool_limits


def one_blas_thread() -> threadpool_limits:
    """A context in which BLAS runs on one thread."""
    return threadpool_limits(limits=1, user_api="blas")
