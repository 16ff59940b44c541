"""The two steps both model families end with: the sensors and the steady-state filter.

The given sensors or the layout :func:`~powerline_control.sensors.select_sensors` optimises over
the moving nodes, and the steady-state Kalman filter on the measured rows, with the process-noise
floor and the scales learned on held-out data.
"""

from __future__ import annotations

import numpy as np

from ..estimate import KalmanFilter
from ..identify import DMDModel
from ..sensors import select_sensors


def _choose_sensors(model: DMDModel, given, candidates: np.ndarray, n_sensors: int,
                    criterion: str, noise: float, positions, forbidden, seed):
    """The given sensors, or the optimised layout over the moving nodes (and its result)."""
    if given is not None:
        return given, None
    cand_positions = None if positions is None else positions[candidates]
    selection = select_sensors(
        model.to_statespace(measured=candidates.tolist()),
        k=n_sensors,
        criterion=criterion,
        Q=model.residual_covariance,
        R=noise**2,
        positions=cand_positions,
        forbidden=forbidden,
        seed=0 if seed is None else seed,
    )
    return np.sort(candidates[list(selection.nodes)]), selection


def _steady_filter(model: DMDModel, sensors: np.ndarray, noise_std: float,
                   q_floor: float, scale: float = 1.0, dof_fraction: float = 1.0,
                   warn: bool = False,
                   reference: tuple[np.ndarray, int, np.ndarray, float] | None = None,
                   field_scale: float = 1.0, field_relative: float = 0.0,
                   innovation_growth: tuple[float, float] | None = None,
                   adapt_horizon: int | None = None) -> KalmanFilter:
    """Steady-state filter on the measured rows, Q = residual covariance + floor, R = noise^2,
    both times ``scale`` (the covariance matching of :func:`_calibration`).

    The floor (1e-10 of the data's mean square per coordinate, far below any noisy record's
    residual) keeps the Riccati equation solvable on noise-free data, whose residual covariance
    is round-off: undamped modes without process noise have no stabilising solution. A common
    scale of Q and R scales the Riccati solution alike and leaves the gain, hence the estimate,
    unchanged: only the reported covariance (and the NIS) changes. ``field_scale`` and
    ``field_relative`` are the filter's ``field_variance_scale`` and ``field_relative_variance``
    (the model error at unmeasured nodes, fitted by ``dmd._field_error_model``);
    ``innovation_growth`` its ``innovation_growth`` (the model error at the sensors that grows
    with the field, measured by ``dmd._calibration``). ``reference`` is the spectral test's
    ``(innovation power, count, measurement power, noise power)`` from ``dmd._calibration``.

    With ``adapt_horizon`` the filter adapts ``Q`` (the filter's ``adapt_horizon``): it starts
    from the steady filter's stationary covariance with ``Q = scale (residual + floor)`` and
    ``R = noise^2`` unscaled (the sensor noise is known; the covariance matching moves the
    model error, ``Q``, alone); the spectral reference and ``innovation_growth``, which need a
    frozen gain, are left out.
    """
    q = np.array(model.residual_covariance)
    q[np.diag_indices_from(q)] += q_floor
    if adapt_horizon is not None:
        sys = model.to_statespace(measured=sensors.tolist())
        start = KalmanFilter(sys, Q=scale * q, R=noise_std**2, steady_state=True,
                             consistency_window=None)
        return KalmanFilter(
            sys, Q=scale * q, R=noise_std**2, P0=start._steady_solution()[2],
            field_map=model.field_map, nis_dof_fraction=dof_fraction, warn_inconsistent=warn,
            field_variance_scale=field_scale, field_relative_variance=field_relative,
            adapt_horizon=adapt_horizon,
        )
    return KalmanFilter(
        model.to_statespace(measured=sensors.tolist()),
        Q=scale * q,
        R=scale * noise_std**2,
        steady_state=True,
        field_map=model.field_map,
        nis_dof_fraction=dof_fraction,
        warn_inconsistent=warn,
        spectral_reference=None if reference is None else reference[0],
        spectral_reference_count=1 if reference is None else reference[1],
        spectral_field_reference=None if reference is None else reference[2:],
        field_variance_scale=field_scale,
        field_relative_variance=field_relative,
        innovation_growth=innovation_growth,
    )
