"""One BLAS thread inside our least-squares loops.

The fits of the identification methods work on tall, thin matrices (samples x a few
parameters): a multi-threaded BLAS gains little on them and, on a loaded machine,
oversubscribes the cores (issue 18: log decrement at 1e6 samples 1.7 s quiet, 28-40 s
loaded, 10 s with one BLAS thread). ``threadpoolctl`` is optional: without it nothing is
limited.
"""

from __future__ import annotations

import functools
from contextlib import contextmanager

__all__ = ["one_blas_thread", "with_one_blas_thread"]


@contextmanager
def one_blas_thread():
    """Context in which the BLAS libraries loaded by numpy/scipy use one thread.

    Examples
    --------
    >>> import numpy as np
    >>> with one_blas_thread():
    ...     float(np.linalg.lstsq(np.eye(2), np.ones(2), rcond=None)[0][0])
    1.0
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency of scipy's stack
        yield
        return
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def with_one_blas_thread(func):
    """Wrap ``func`` to run inside :func:`one_blas_thread` (a decorator).

    Parameters
    ----------
    func : callable
        The estimator to wrap.

    Returns
    -------
    callable
        The wrapped estimator (same signature and docstring).
    """

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return func(*args, **kwargs)

    return wrapper
