"""The baselines a sensor layout is compared with: greedy, evenly spaced, QR pivoting of the
basis, random layouts (mean and best) and, when every layout was enumerated, the brute-force
optimum. Each is judged on the same exact criterion as the chosen layout.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .constraints import _Feasibility
from .results import Baseline


def _baselines(crit, feas: _Feasibility, k: int, greedy: list[int] | None,
               psi: np.ndarray | None, x: np.ndarray | None, rng: np.random.Generator,
               n_random: int, brute: tuple[list[int], float] | None, to_physical
               ) -> dict[str, Baseline]:
    """The obvious layouts a report compares against, judged on the exact criterion."""
    m = len(feas.allowed)
    layouts: dict[str, list[int]] = {"first-k": list(range(k))}
    if x is not None:
        targets = np.linspace(x.min(), x.max(), k + 2)[1:-1]
        even: list[int] = []
        for t in targets:
            for j in np.argsort(np.abs(x - t), kind="stable"):
                if int(j) not in even:
                    even.append(int(j))
                    break
        layouts["evenly-spaced"] = even
    else:
        layouts["evenly-spaced"] = np.unique(np.round(np.linspace(0, m - 1, k + 2)[1:-1])
                                             ).astype(int).tolist()
    if greedy is not None:
        layouts["greedy"] = greedy
    if psi is not None:
        # QR column pivoting on Psi^T (the method of PySensors' SSPOR): rows maximising |det|.
        _, _, piv = sla.qr(psi.T, pivoting=True, mode="economic")
        qr_layout = piv[: min(k, len(piv))].tolist()
        for j in range(m):  # k larger than the basis: fill in candidate order
            if len(qr_layout) == k:
                break
            if j not in qr_layout:
                qr_layout.append(j)
        layouts["qr-pivoting"] = qr_layout
    out: dict[str, Baseline] = {}
    named = [v for v in layouts.values() if len(set(v)) == k]
    values = crit.exact(np.array(named, dtype=int))
    for (name, layout), value in zip(
        [(nm, v) for nm, v in layouts.items() if len(set(v)) == k], values, strict=True):
        out[name] = Baseline(name, tuple(sorted(int(i) for i in layout)), to_physical(value))
    if n_random:
        rand = np.array([rng.choice(m, size=k, replace=False) for _ in range(n_random)])
        values = crit.exact(rand)
        physical = np.array([to_physical(v) for v in values])
        finite = physical[np.isfinite(physical)]
        mean = float(finite.mean()) if finite.size == len(physical) else to_physical(np.inf)
        out["random-mean"] = Baseline("random-mean", None, mean)
        best = int(np.argmin(values))
        out["random-best"] = Baseline("random-best", tuple(sorted(rand[best].tolist())),
                                      to_physical(values[best]))
    if brute is not None:
        out["brute-force"] = Baseline("brute-force", tuple(sorted(brute[0])),
                                      to_physical(brute[1]))
    return out
