"""The running mean square of an estimated field: the one definition the filter reports model
error with and the recipe fits it by.

An identified model of a real span is wrong by a share of the field it predicts (measured on the
estimator family of ``tests/estimator_family.py``: 20-50 % at unmeasured nodes), so its error
grows as the line rings up, which no constant covariance can follow. The filter adds
``field_relative_variance`` times this running mean square to each node's reported variance.
"""

from __future__ import annotations

import numpy as np
import scipy.signal as ssig


def running_mean_square(field: np.ndarray, window: int) -> np.ndarray:
    """Causal exponential average of ``field**2`` along time, time constant ``window`` samples.

    Parameters
    ----------
    field : numpy.ndarray
        ``(n_nodes, n_t)`` estimated field (finite).
    window : int
        Time constant in samples (``>= 1``): the average over about the last ``window``
        samples, so that the reported variance follows a field that rings up or dies down.

    Returns
    -------
    numpy.ndarray
        ``(n_nodes, n_t)``; the first column is the first sample's square (the average starts
        there as if the field had been steady before).

    Examples
    --------
    >>> import numpy as np
    >>> from powerline_control.estimate._model_error import running_mean_square
    >>> float(running_mean_square(np.full((1, 50), 2.0), 10)[0, -1])
    4.0
    """
    square = np.asarray(field, dtype=float) ** 2
    if square.shape[-1] == 0:
        return square
    keep = 1.0 - 1.0 / window
    return ssig.lfilter([1.0 - keep], [1.0, -keep], square, axis=-1,
                        zi=keep * square[..., :1])[0]
