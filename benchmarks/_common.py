"""Shared helpers of the side-by-side benchmark (``benchmarks/run.py``): BLAS pinning and timing.

Import this module before numpy: :func:`pin_blas` runs on import so that every BLAS library the
process loads uses one thread (on the shared 2-core machine multi-threaded BLAS was measured
15-50x slower under load, which would measure contention rather than algorithms).
"""

import os

BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def pin_blas() -> str:
    """Set every BLAS thread variable to 1 (must happen before numpy is imported)."""
    for name in BLAS_VARIABLES:
        os.environ[name] = "1"
    return "BLAS pinned to 1 thread (" + ", ".join(f"{n}=1" for n in BLAS_VARIABLES) + \
        ", set before numpy was imported)"


PINNED = pin_blas()

import statistics  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402


def alternate(ours, peer, repeats: int):
    """Time ``ours`` and ``peer`` alternately ``repeats`` times; medians and last results.

    Alternating (ours, peer, ours, peer, ...) spreads the load of other processes on this shared
    machine over both sides instead of penalising whichever ran second.
    """
    t_ours, t_peer, r_ours, r_peer = [], [], None, None
    for _ in range(repeats):
        start = time.perf_counter()
        r_ours = ours()
        t_ours.append(time.perf_counter() - start)
        if peer is not None:
            start = time.perf_counter()
            r_peer = peer()
            t_peer.append(time.perf_counter() - start)
    return (statistics.median(t_ours), statistics.median(t_peer) if t_peer else float("nan"),
            r_ours, r_peer)


def timed(func, repeats: int):
    """Median wall time of ``func`` over ``repeats`` calls, and its last result."""
    seconds, _, result, _ = alternate(func, None, repeats)
    return seconds, result


def peak_memory(func) -> float:
    """Peak traced Python/numpy allocation of one call of ``func``, MiB (tracemalloc).

    numpy reports its array buffers to tracemalloc, so this counts the arrays; memory held by
    compiled libraries outside numpy (SuiteSparse, IPOPT) is not seen.
    """
    tracemalloc.start()
    try:
        func()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return peak / 2**20
