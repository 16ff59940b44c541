"""Model -> states: KalmanFilter and its recursion, Estimate and Accuracy, the consistency tests
(windowed NIS, NEES, spectral), and observability (rank, Gramian, steady covariance, reports).

``filter.py`` holds :class:`KalmanFilter`; ``_recursion.py`` its per-sample and modal batch
recursion, which reads the filter's frozen specification (``FilterSpec``) and nothing else of
it; ``result.py`` what a run returns (:class:`Estimate`, :class:`Consistency`), how close it
came (:func:`estimation_accuracy`) and how fast it recovers (:func:`recovery_time`);
``consistency.py`` the NIS / NEES tests (:func:`filter_consistency`) and ``_spectrum.py`` the
spectral test of the whitened innovations; ``observability.py`` what a sensor set can see before
any filter runs.
"""

from ._model_error import running_mean_square as running_mean_square
from ._model_error import sensor_mean_square as sensor_mean_square
from ._recursion import _SCAN_BLOCK as _SCAN_BLOCK
from ._recursion import _diagonal_recursion as _diagonal_recursion
from ._recursion import _recursion_tables as _recursion_tables
from ._spectrum import measurement_psd as measurement_psd
from ._spectrum import spectral_test as spectral_test
from ._spectrum import whitened_psd as whitened_psd
from ._spectrum import whitening_factor as whitening_factor
from .consistency import DEFAULT_CONSISTENCY_WINDOW as DEFAULT_CONSISTENCY_WINDOW
from .consistency import Consistency as Consistency
from .consistency import filter_consistency as filter_consistency
from .consistency import windowed_consistency as windowed_consistency
from .filter import KalmanFilter as KalmanFilter
from .observability import ObservabilityReport as ObservabilityReport
from .observability import SensorSetComparison as SensorSetComparison
from .observability import __all__ as _observability_all
from .observability import analyze_observability as analyze_observability
from .observability import compare_sensor_sets as compare_sensor_sets
from .observability import observability_gramian as observability_gramian
from .observability import observability_rank as observability_rank
from .observability import steady_state_covariance as steady_state_covariance
from .result import Accuracy as Accuracy
from .result import Estimate as Estimate
from .result import Recovery as Recovery
from .result import estimation_accuracy as estimation_accuracy
from .result import recovery_time as recovery_time

__all__ = [
    "Estimate",
    "KalmanFilter",
    "Accuracy",
    "estimation_accuracy",
    "Consistency",
    "filter_consistency",
    "windowed_consistency",
    "Recovery",
    "recovery_time",
    *_observability_all,
]
