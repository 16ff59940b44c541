"""Exceptions and warnings of powerline_control.

Every exception derives from :class:`PowerlineControlError` *and* from the builtin that fits, so
``except ValueError`` in user code keeps working (the pattern of python-control's
``control/exception.py``).
"""

from __future__ import annotations

__all__ = [
    "PowerlineControlError",
    "InputError",
    "PresetNotFoundError",
    "ModelError",
    "IdentificationError",
    "EstimationError",
    "SensorSelectionError",
    "PlanningError",
    "FileFormatError",
    "IllConditionedWarning",
    "UnstableModelWarning",
    "TruncationWarning",
]


class PowerlineControlError(Exception):
    """Base class of every error raised by powerline_control."""


class InputError(PowerlineControlError, ValueError):
    """An argument has a value without a defined meaning (wrong type, range, shape)."""


class PresetNotFoundError(InputError, KeyError):
    """A preset name (e.g. a conductor) is not in the catalogue.

    Also a ``KeyError``, so ``name in conductors`` and ``conductors.get(name)`` work as for any
    mapping.
    """

    def __str__(self) -> str:  # KeyError would quote the message; keep it readable
        return str(self.args[0]) if self.args else ""


class ModelError(PowerlineControlError, RuntimeError):
    """A physical model cannot be built or solved (e.g. an eigen-solve that fails)."""


class IdentificationError(PowerlineControlError, RuntimeError):
    """Identification from data failed (rank-deficient data, no stable alpha, ...)."""


class EstimationError(PowerlineControlError, RuntimeError):
    """State estimation failed (singular innovation covariance, diverging filter, ...)."""


class SensorSelectionError(PowerlineControlError, RuntimeError):
    """Sensor selection failed or its constraints cannot be met."""


class PlanningError(PowerlineControlError, RuntimeError):
    """A motion plan is infeasible or its solver failed."""


class FileFormatError(PowerlineControlError, ValueError):
    """A saved file is truncated, corrupted, of another format or of an unknown version."""


class IllConditionedWarning(UserWarning):
    """A computation lost significant accuracy to ill-conditioning."""


class UnstableModelWarning(UserWarning):
    """An identified model has eigenvalues outside the unit circle."""


class TruncationWarning(UserWarning):
    """A modal truncation or time step cannot resolve the requested excitation."""


class UndetectableModeWarning(UserWarning):
    """A mode on or outside the unit circle is invisible to the sensors: its error grows."""


class ExcitationWarning(UserWarning):
    """A training record is not persistently exciting: a model of it cannot know other loads."""


class ReachWarning(UserWarning):
    """The robot cannot reach where it would damp best: its limits, the run's length or the
    obstacles keep it from every better position."""


class EstimatorInconsistentWarning(UserWarning):
    """A filter's innovations contradict its own covariance: the model does not fit the record
    (a load that drives modes the training never saw, a changed line), so neither the estimate
    nor its reported uncertainty can be trusted."""


class SaturationWarning(UserWarning):
    """A measured channel is clipped at its sensor's range: many samples sit exactly at its
    largest (or smallest) value, flat tops that a model or filter takes for the motion."""


class ModelErrorRecordsWarning(UserWarning):
    """Records of other load histories given to set an estimator's model-error level
    (``design_estimator``'s ``model_error_records``) cannot be used as given: a modal design
    that has no model-error terms, no unmeasured node to measure the error at, sensor noise
    unlike the training record's, or no model error above that noise."""


class CalibrationWarning(UserWarning):
    """A record cannot tell the line's parameters well (one spectral line, sensors within one
    loop, several tensions explain it): the calibration's uncertainty covers what it cannot
    tell."""


class ShortfallWarning(UserWarning):
    """The closed loop falls short and says so: it ended worse than where the robot started or
    than a fixed damper parked near the clamp."""


class BeliefContradictedWarning(UserWarning):
    """What the closed loop's sensors measured after a move contradicts what its belief (the
    span it was told or calibrated) predicted: the vibration rose far more than predicted, so
    the robot went back, or held where it was when no time was left to go back."""


__all__ += ["CalibrationWarning", "ShortfallWarning", "BeliefContradictedWarning",
            "UndetectableModeWarning",
            "ExcitationWarning", "ReachWarning", "EstimatorInconsistentWarning",
            "SaturationWarning", "ModelErrorRecordsWarning"]
