"""The controller's belief: the span it is told, calibrated from the records, and the model of
the line it predicts with.

The simulated line is the truth (:mod:`.simulated`); a real robot is told only the nominal span
(catalogue conductor, length, supports, stringing tension), which can be several per cent off,
and sees only what its sensors record (design.md 4.7). Everything the policy predicts with comes
from one :class:`Belief`, built by :func:`believe` from the nominal span meshed as the line is,
never from the simulated line's own model; :class:`BeliefTracker` rebuilds it during the run from
the span :func:`~powerline_control.identify.calibrate_span` reads in the sensors' records.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from .._validation import check_int, read_only
from ..errors import CalibrationWarning, IdentificationError, InputError, TruncationWarning
from ..fem import MDR, LineModel, ModalDamping
from ..identify import calibrate_span
from ..line import Span
from ..simulation.plant import ModalPlant, default_modes
from .policy_settings import PolicySettings

# A nominal span must have the simulated span's length within this fraction: a record or a model
# of another span is no belief about this one (lengths are surveyed; tensions drift).
LENGTH_TOLERANCE = 0.01
#: A record must grow by this much (s) before it is calibrated again.
MIN_NEW_RECORD = 1.0
# When a calibration moves the belief (min_cycles, belief_tolerance, trusted_share,
# less_certain) is the policy's to set: PolicySettings, with the evidence for each value.
#: The line damping a controller told only a Span assumes: a conductor's self-damping at aeolian
#: amplitudes is 0.05-0.5 % of critical; this is the middle of that range on a log scale.
ASSUMED_DAMPING = ModalDamping(0.0015)


@dataclass(frozen=True, eq=False)
class Belief:
    """What the controller predicts with: the span it believes, meshed, and its modal model.

    Attributes
    ----------
    span : Span
        The believed span (the nominal one as told, or as calibrated from the records).
    bare : LineModel
        The believed line without the robot (its mesh, supports and damping).
    plant : ModalPlant
        The policy's receptances: the believed line's band of bare modes with the robot, no load
        basis (the controller does not know the loads).
    rows : ndarray, shape (p, r)
        The plant's modes' displacements at the sensors' positions.
    weights : ndarray, shape (n_nodes,)
        Trapezoid weights of the believed mesh's nodes (the span RMS of a prediction).
    node_positions : ndarray, shape (n_nodes,)
        The believed mesh's nodes, m (where predicted shapes are given).
    mode_frequencies : ndarray, shape (r,)
        The plant's bare-mode frequencies, Hz, ascending.
    sensor_positions : ndarray, shape (p,)
        Where the sensors measure, m from the left support.

    Examples
    --------
    >>> import powerline_control as plc
    >>> truth = plc.LineModel(plc.Span.paper_lab(), 40, damping=plc.ModalDamping(0.005))
    >>> told = plc.Span(3.66, 0.97 * truth.span.tension, truth.span.conductor)
    >>> belief = believe(told, like=truth, robot=plc.MDR(1.2, 0.02), n_modes=12, dt=1e-3,
    ...                  sensor_positions=[0.5, 1.5])
    >>> belief.bare.n_elements, belief.rows.shape, belief.span.tension == told.tension
    (40, (2, 12), True)
    """

    span: Span
    bare: LineModel = field(repr=False)
    plant: ModalPlant = field(repr=False)
    rows: np.ndarray = field(repr=False)
    weights: np.ndarray = field(repr=False)
    node_positions: np.ndarray = field(repr=False)
    mode_frequencies: np.ndarray = field(repr=False)
    sensor_positions: np.ndarray = field(repr=False)

    def loop_length(self, frequency: float) -> float:
        """Half-wavelength of the believed span at ``frequency`` Hz, m."""
        return float(self.span.loop_length(frequency))

    def within(self, low: float, high: float) -> tuple[float, float]:
        """The interval [low, high] (m) cut to the believed span: where it can predict."""
        return max(low, 0.0), min(high, self.span.length)

    def inside(self, position: float) -> float:
        """``position`` (m) on the believed span (a robot beyond a believed support end is
        predicted at that end; possible only when the nominal length is short by < 1 %)."""
        return float(np.clip(position, 0.0, self.span.length))


def checked_nominal(nominal: Span | LineModel | None, truth: LineModel) -> Span | LineModel | None:
    """``nominal`` checked against the line simulated (``truth``, its bare model): a Span or a
    bare LineModel (a robot it carries is dropped: the robot is run_closed_loop's) of the
    simulated span's length within LENGTH_TOLERANCE; None stays None (the model's own span). A
    Span becomes its LineModel: meshed as the line is, with ASSUMED_DAMPING."""
    if nominal is None:
        return None
    if not isinstance(nominal, Span | LineModel):
        raise InputError(
            "The 'nominal' parameter must be a Span, a LineModel or None (the span the "
            f"controller is told). Got {type(nominal).__name__}."
        )
    span = nominal.span if isinstance(nominal, LineModel) else nominal
    length = truth.span.length
    low, high = (1 - LENGTH_TOLERANCE) * length, (1 + LENGTH_TOLERANCE) * length
    if not low <= span.length <= high:
        raise InputError(
            f"The 'nominal' parameter describes a span {span.length:g} m long, but the line "
            f"simulated ('model') is {length:g} m long: the nominal span must have its length "
            f"within {100 * LENGTH_TOLERANCE:g} % ({low:.6g} to {high:.6g} m). A span or record "
            "of another line is no nominal for this one."
        )
    if isinstance(nominal, Span):
        # A span says nothing of the line's damping: the controller assumes a typical one (the
        # records do not tell it: docs/validation/calibration.md); the mesh is a numerical
        # choice, the line's own.
        return meshed_like(nominal, truth, damping=ASSUMED_DAMPING)
    if nominal.mdr is not None:
        return nominal.with_robot(None)
    return nominal


def meshed_like(span: Span, like: LineModel, damping: object = None) -> LineModel:
    """``span`` meshed as ``like`` is: the same number of equal elements when its mesh is
    uniform, else the physics mesh of ``span`` for the same band top and frequency tolerance
    (the default elements per loop); the same supports, and ``like``'s damping unless
    ``damping`` is given. The mesh's own warnings were given when ``like`` was built."""
    lengths = np.asarray(like.element_lengths)
    damping = like.damping if damping is None else damping
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TruncationWarning)
        if np.ptp(lengths) == 0.0:
            return LineModel(span, like.n_elements, like.bc, damping=damping)
        return LineModel(span, None, like.bc, damping=damping,
                         max_frequency=like.max_frequency,
                         frequency_tolerance=like.frequency_tolerance)


def believe(span_or_model: Span | LineModel, *, like: LineModel, robot: MDR,
            n_modes: int | np.ndarray | None, dt: float, sensor_positions: Sequence[float],
            frequencies: Sequence[float] = ()) -> Belief:
    """The Belief the policy predicts with, from the span it believes.

    Parameters
    ----------
    span_or_model : Span or LineModel
        The believed span (meshed like ``like``), or its model (used as it is, without robot).
    like : LineModel
        The mesh rule, supports and damping a Span is given (:func:`meshed_like`).
    robot : MDR
        The robot (the policy's receptances include it).
    n_modes : int, ndarray or None
        Bare modes kept (a count, or indices of a band); None: the plant's rule for
        ``frequencies`` (:func:`~powerline_control.simulation.plant.default_modes`) on the
        believed line.
    dt : float
        Sample interval, s.
    sensor_positions : sequence of float
        Where the sensors measure, m (on the believed span: its mesh need have no node there).
    frequencies : sequence of float
        The frequencies (Hz) the band must cover when ``n_modes`` is None.

    Returns
    -------
    Belief

    Raises
    ------
    InputError
        When ``n_modes`` exceeds the believed line's degrees of freedom, or a sensor lies off
        the believed span (named as 'nominal').

    Examples
    --------
    >>> import powerline_control as plc
    >>> model = plc.LineModel(plc.Span.paper_lab(), 20)
    >>> belief = believe(model, like=model, robot=plc.MDR(1.2, 0.02), n_modes=None, dt=1e-3,
    ...                  sensor_positions=[0.732, 1.83], frequencies=[24.0])
    >>> belief.bare is model, belief.plant.r, round(belief.loop_length(24.0), 3)
    (True, 12, 1.239)
    """
    if isinstance(span_or_model, LineModel):
        bare = span_or_model if span_or_model.mdr is None else span_or_model.with_robot(None)
    elif isinstance(span_or_model, Span):
        bare = meshed_like(span_or_model, like)
    else:
        raise InputError(
            "The 'span_or_model' parameter must be a Span or a LineModel. "
            f"Got {type(span_or_model).__name__}."
        )
    span = bare.span
    positions = np.asarray(sensor_positions, dtype=float).ravel()
    off = positions[(positions < 0.0) | (positions > span.length)]
    if off.size:
        raise InputError(
            f"The 'nominal' span ({span.length:g} m) does not reach the sensor(s) at "
            f"{off.tolist()} m: a sensor must lie on the span the controller believes."
        )
    if n_modes is None:
        n_modes = default_modes(span, bare, list(frequencies), dt)
    elif np.ndim(n_modes) == 0:
        n_modes = check_int("n_modes", n_modes, low=1, high=bare.n_dofs)
    plant = ModalPlant(bare, robot, n_modes, dt)
    rows = np.vstack([plant.coupling(x) for x in positions])
    return Belief(
        span=span, bare=bare, plant=plant, rows=read_only(rows),
        weights=bare.span_weights, node_positions=bare.node_positions,
        mode_frequencies=read_only(np.sort(np.sqrt(plant.omega2)) / (2 * np.pi)),
        sensor_positions=read_only(positions),
    )


def _within_nyquist(band, dt: float):
    """``band`` cut to what calibrate_span accepts (0.4 / dt); None stays None."""
    if band is None:
        return None
    return band[0], min(band[1], 0.4 / dt)


@dataclass(frozen=True, eq=False)
class SensorRecord:
    """The sensors' record so far, as :func:`~powerline_control.identify.calibrate_span` reads
    a :class:`~powerline_control.Record` (rows: sensors; NaN: a missing sample)."""

    t: np.ndarray               # (n_t,) sample times, s
    positions: np.ndarray       # (p,) where the sensors measure, m
    values: np.ndarray          # (p, n_t) displacements, m
    dt: float                   # sample interval, s


def longest_still(path: np.ndarray) -> tuple[int, int]:
    """The first and last sample of the longest stretch over which the robot's position
    ``path`` (m, one per sample) does not change; the latest of equally long ones.

    Examples
    --------
    >>> longest_still(np.array([2.0, 2.0, 2.0, 2.1, 2.2, 2.2]))
    (0, 2)
    >>> longest_still(np.array([2.0, 2.1, 2.2, 2.2]))
    (2, 3)
    """
    breaks = np.flatnonzero(np.diff(path) != 0.0)       # the robot moves after these samples
    firsts = np.concatenate(([0], breaks + 1))
    lasts = np.concatenate((breaks, [path.size - 1]))
    longest = lasts.size - 1 - int(np.argmax((lasts - firsts)[::-1]))
    return int(firsts[longest]), int(lasts[longest])


class BeliefTracker:
    """The controller's belief over a run (a class with evolving state).

    It starts from the nominal span's :class:`Belief`; at each :meth:`update` (after the
    calibration window, then at each decision of the policy) it calibrates the span on the
    sensors' whole record so far, and the robot's own while it has not moved
    (:func:`~powerline_control.identify.calibrate_span`, the nominal model as prior, the robot
    parked where it spent most of the record); once the robot has moved, it also calibrates the
    longest stretch it stood still in (:func:`longest_still`) and believes that one where the
    two disagree by more than ``settings.moved_record_z`` combined standard deviations. It
    rebuilds the Belief from the calibrated span when its tension differs from the believed one
    by more than ``settings.belief_tolerance`` of it (a rebuild costs a modal plant). A
    calibration whose main peak holds less than ``settings.trusted_share`` of its posterior
    (several tensions explain the record) moves nothing: its highest peak may be a neighbouring
    mode's; nor does one ``settings.less_certain`` times less certain than the one believed; nor
    one on fewer than ``settings.min_cycles`` cycles of the fundamental.
    """

    def __init__(self, nominal: Belief, *, robot: MDR, n_modes, dt: float,
                 frequencies: Sequence[float], calibrate: bool,
                 settings: PolicySettings | None = None):
        self.settings = PolicySettings() if settings is None else settings
        self.nominal = nominal
        self.belief = nominal
        self.calibrate = calibrate
        self.calibrations: list = []       # (time, SpanCalibration)
        self.trusted = False               # a calibration has told the tension
        self.cpu = 0.0                     # process time spent calibrating and rebuilding, s
        self._robot, self._n_modes, self._dt = robot, n_modes, dt
        self._frequencies = tuple(frequencies)
        self._last = -1                    # the sample the last update read up to
        self._believed_std = np.inf        # the std of the calibration believed, N

    @property
    def waiting(self) -> bool:
        """Whether a first target waits for the span's calibration: calibrating and none
        trusted yet (``settings.trusted_share``). A target chosen on a nominal tension several
        per cent off lands loops away on a long span (a 330 m span told 1 % low: 2.9x worse than
        where the robot started), so the robot holds until its records tell the tension."""
        return self.calibrate and not self.trusted

    @property
    def believed_std(self) -> float:
        """The standard deviation (N) of the calibrated tension believed (inf before one is
        trusted)."""
        return self._believed_std

    def update(self, seen, k: int, band: tuple[float, float] | None = None) -> str | None:
        """Calibrate on the measurements ``seen`` up to sample ``k`` and rebuild the belief if
        the tension moved (on the lines within ``band``, Hz: all by default); returns what
        changed, in words (None: the belief stands). A record grown by less than MIN_NEW_RECORD
        s and a quarter since the last calibration is not calibrated again (a calibration costs
        a fraction of a second on a long span)."""
        grown = k - self._last
        if not self.calibrate or grown <= 0 or (
                self._last >= 0 and grown * self._dt < max(MIN_NEW_RECORD,
                                                           0.25 * self._last * self._dt)):
            return None
        self._last = k
        started = time.process_time()
        try:
            return self._update(seen, k, band)
        finally:
            self.cpu += time.process_time() - started

    def _calibrated(self, seen, first: int, last: int, band):
        """calibrate_span on the samples ``first`` to ``last`` of the measurements ``seen``, the
        robot parked where it spent them (its own record one more channel when it did not move
        in them); the error in words when the record cannot be calibrated."""
        path = seen.position[first : last + 1]
        parked = replace(self._robot, position=self.nominal.inside(float(np.median(path))))
        positions, values = seen.sensor_positions, seen.sensors[:, first : last + 1]
        if np.ptp(path) == 0.0 and not np.any(np.isclose(positions, parked.position)):
            positions = np.append(positions, parked.position)
            values = np.vstack([values, seen.robot[None, first : last + 1]])
        record = SensorRecord(t=seen.t[first : last + 1], positions=positions, values=values,
                              dt=self._dt)
        try:
            with warnings.catch_warnings():
                # what the record cannot tell is kept on the calibration (its ``warnings``)
                warnings.simplefilter("ignore", CalibrationWarning)
                return calibrate_span(record, self.nominal.bare, robot=parked,
                                      band=_within_nyquist(band, self._dt))
        except (InputError, IdentificationError) as error:
            return str(error)

    def _update(self, seen, k: int, band) -> str | None:
        """:meth:`update`'s calibration and rebuild (timed by it)."""
        now = float(seen.t[k])
        fundamental = float(self.nominal.span.pinned_frequencies(1)[0])
        policy = self.settings
        if (now - float(seen.t[0])) * fundamental < policy.min_cycles:
            return (f"belief kept at tension {self.belief.span.tension:.5g} N: the record "
                    f"({now - float(seen.t[0]):.3g} s) is shorter than {policy.min_cycles:g} "
                    "cycles of "
                    f"the fundamental ({fundamental:.3g} Hz), too short to separate the modes "
                    "beside the tone")
        calibration = self._calibrated(seen, 0, k, band)
        if isinstance(calibration, str):
            return f"belief kept at tension {self.belief.span.tension:.5g} N: {calibration}"
        first, last = longest_still(seen.position[: k + 1])
        if (last - first) < k and (seen.t[last] - seen.t[first]) * fundamental >= policy.min_cycles:
            # The robot moved during the record: a move can smear a mode into two lines
            # (closed_loop_off_nominal.md, seed 837). Where the longest stretch it stood still
            # tells another tension beyond both readings' uncertainty, that stretch is believed.
            still = self._calibrated(seen, first, last, band)
            if (not isinstance(still, str) and still.peak_share >= policy.trusted_share
                    and abs(still.tension - calibration.tension) > policy.moved_record_z
                    * np.hypot(still.tension_std, calibration.tension_std)):
                calibration = still
        self.calibrations.append((now, calibration))
        believed = self.belief.span.tension
        if calibration.peak_share < policy.trusted_share:
            # several tensions explain the record: its highest peak may be a neighbouring mode's
            return (f"belief kept at tension {believed:.5g} N: the record (its "
                    f"{calibration.duration:.3g} s) cannot tell between tensions "
                    f"{calibration.tension:.5g} +- {calibration.tension_std:.2g} N")
        if self.trusted and calibration.tension_std > policy.less_certain * self._believed_std:
            # the record grew but tells much less: the robot moved during it, its field is no
            # longer one steady state; the calibration believed stands (a new tone's
            # calibration, after a wind change, is about as certain as the last)
            return (f"belief kept at tension {believed:.5g} N: the record's calibration "
                    f"({calibration.tension:.5g} +- {calibration.tension_std:.2g} N) is less "
                    f"certain than the one believed (+- {self._believed_std:.2g} N)")
        self.trusted = True
        self._believed_std = calibration.tension_std
        if abs(calibration.tension - believed) <= policy.belief_tolerance * believed:
            return None
        self.belief = believe(calibration.span, like=self.nominal.bare, robot=self._robot,
                              n_modes=self._n_modes, dt=self._dt,
                              sensor_positions=self.nominal.sensor_positions,
                              frequencies=self._frequencies)
        odds = ("" if not calibration.ambiguous else
                f", its main peak {100 * calibration.peak_share:.0f} % of the posterior")
        return (f"believe tension {calibration.tension:.5g} +- {calibration.tension_std:.2g} N "
                f"(was {believed:.5g} N), calibrated on {calibration.duration:.3g} s of "
                f"record{odds}")
