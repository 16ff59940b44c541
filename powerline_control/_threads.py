"""One home for pinning BLAS to one thread around small-matrix work.

Thousands of small products and solves (matrices up to ~100 wide) run far slower with contending
BLAS threads than with one. The limit is scoped (a ``with`` block or a
decorated function), so a caller's own BLAS settings are restored afterwards.
"""

from threadpoolctl import threadpool_limits


def one_blas_thread():
    """A context manager that runs its body on one BLAS thread.

    Examples
    --------
    >>> import numpy as np
    >>> with one_blas_thread():
    ...     float(np.sum(np.eye(3) @ np.ones(3)))
    3.0
    """
    return threadpool_limits(limits=1, user_api="blas")


def on_one_blas_thread(function):
    """Decorator: each call of ``function`` runs on one BLAS thread.

    threadpoolctl's own decorator, one per decorated function: it looks the BLAS libraries up
    once, where building a new limit per call would look them up on every call, too slow for
    functions called once per time step.

    Examples
    --------
    >>> import numpy as np
    >>> @on_one_blas_thread
    ... def trace(n):
    ...     return float(np.trace(np.eye(n) @ np.eye(n)))
    >>> trace(4)
    4.0
    """
    return threadpool_limits.wrap(limits=1, user_api="blas")(function)
