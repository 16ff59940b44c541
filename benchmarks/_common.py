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


# ------------------------------------------- reduced coordinates (bench_estimate, bench_sensors)
CANDIDATES = (101, 1001)
RANKS = (20, 80)


def reduced_model(m: int, r: int, seed: int = 0):
    """A rank-``r`` DMD model of an ``m``-node field (r/2 string modes, two tones each, 1 %
    noise): ``r`` states, ``m`` outputs (C = the field map), Q = its residual covariance."""
    import warnings

    import numpy as np

    import powerline_control as plc

    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, m)
    k = np.arange(1, r // 2 + 1)
    t = np.arange(3000) * 1e-3
    modal = np.array([(1e-3 / j) * (np.sin(2 * np.pi * 6.5 * j * t + rng.uniform(0, 6))
                                    + 0.3 * np.sin(2 * np.pi * 6.5 * 1.01 * j * t))
                      for j in k])
    field = np.sin(np.pi * np.outer(x, k)) @ modal
    noisy = field + 1e-2 * field.std() * rng.standard_normal(field.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plc.UnstableModelWarning)
        dmd = plc.fit_dmd(noisy, dt=1e-3, alpha=1e-6, alpha_mode="relative", rank=r)
    noise_var = float((1e-2 * field.std()) ** 2)
    return dmd.to_statespace(), dmd.residual_covariance, noise_var


def slope(t_small: float, t_large: float, small: int, large: int) -> float:
    """Log-log slope of cost against size between two sizes."""
    import numpy as np

    return float(np.log(t_large / t_small) / np.log(large / small))


def code_version() -> str:
    """HEAD and a hash of the uncommitted changes to the package: two runs compare only on the
    same version (the package may be edited while a long benchmark runs)."""
    import hashlib
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, text=True,
                              capture_output=True, check=True).stdout.strip()
        diff = subprocess.run(["git", "diff", "HEAD", "--", "powerline_control"], cwd=root,
                              capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + (f"+dirty:{hashlib.sha1(diff).hexdigest()[:10]}" if diff else "")


def run_captured(scenario, **run_kwargs):
    """Run the closed loop of a family scenario (``tests/closed_loop_family.py``) and keep what
    the loop's plant step sees: (result, {"records", "line", "calibration"}), through a hook on
    ``closed_loop.loop.advance_plant`` (removed again afterwards). Warnings are silenced: the
    benchmarks measure, the tests judge."""
    import warnings

    import powerline_control as plc
    from powerline_control.closed_loop import loop

    kept = {}
    original = loop.advance_plant

    def hook(plant_state, records, line, calibration, *args):
        kept.update(records=records, line=line, calibration=calibration)
        return original(plant_state, records, line, calibration, *args)

    loop.advance_plant = hook
    try:
        args = scenario.run_arguments()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = plc.run_closed_loop(args.pop("span"), args.pop("force"), args.pop("robot"),
                                         args.pop("limits"), **args, **run_kwargs)
    finally:
        loop.advance_plant = original
    return result, kept
