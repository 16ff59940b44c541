"""What :func:`run_closed_loop` returns: the run's histories and its comparisons."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._results import Result
from ..errors import InputError
from .policy import quiet_from
from .policy_settings import PolicySettings


@dataclass(frozen=True, eq=False)
class Comparison:
    """The line's vibration for one robot placement, in steady state where it has one.

    Attributes
    ----------
    name : str
        ``"no_robot"``, ``"near_clamp"``, ``"start"`` (parked where the closed loop started),
        ``"best"`` (parked at the best position within reach of the steady-state scan) or
        ``"closed_loop"`` (parked where the loop ended).
    position : float
        Where the robot was parked, m (NaN without a robot; the final position for the loop).
    rms : float
        RMS displacement over the span (length-weighted), m: of the exact steady state with the
        robot parked at ``position`` when the last load is one sine (``steady``), else over the
        settled window of the run.
    peak : float
        Largest displacement amplitude over the span, m (steady state or window, as ``rms``).
    damper_power : float
        Mean power dissipated in the robot's damper, W (as ``rms``).
    envelope : ndarray, shape (n_nodes,)
        Displacement amplitude at each node, m (as ``rms``).
    window_rms : float
        The time-domain RMS over the settled window, m (what the run itself showed).
    steady : bool
        True when ``rms``, ``peak``, ``damper_power`` and ``envelope`` are the exact steady state.
    transient : bool
        True when the settled window still rings: its RMS is more than 10 % away from the steady
        state (or, without one, its two halves' RMS differ by more than 10 %), so ``window_rms``
        says little about where the line settles.
    amplitude : float
        Antinode amplitude, zero-to-peak, m: over the settled window the largest over the nodes
        of sqrt(2 mean y^2) (how :func:`~powerline_control.severity.simulate_aeolian` measures
        it; a beat does not raise it as it raises ``peak``); in exact steady state ``peak``.

    Examples
    --------
    >>> import numpy as np
    >>> c = Comparison("start", 1.2, 1e-3, 2e-3, 0.0, np.zeros(3))
    >>> c.name, c.rms, c.steady
    ('start', 0.001, False)
    """

    name: str
    position: float
    rms: float
    peak: float
    damper_power: float
    envelope: np.ndarray = field(repr=False)
    window_rms: float = float("nan")
    steady: bool = False
    transient: bool = False
    amplitude: float = float("nan")


@dataclass(frozen=True, eq=False)
class ClosedLoopResult(Result):
    """What happened in :func:`run_closed_loop`.

    Attributes
    ----------
    t : ndarray, shape (n_t,)
        Sample times, s (calibration window included, starting at 0).
    x : ndarray, shape (n_nodes,)
        Node positions, m.
    displacement : ndarray, shape (n_nodes, n_t)
        True (noise-free) displacement with the robot under closed-loop control.
    baseline_displacement : ndarray, shape (n_nodes, n_t)
        True displacement with the robot parked at its start for the whole run.
    estimated_field : ndarray, shape (n_nodes, n_t)
        The Kalman filter's estimate of the field (the calibration record filtered first).
    robot_position, robot_velocity : ndarray, shape (n_t,)
        Robot state, m and m/s.
    target : ndarray, shape (n_t,)
        Where the robot was steering to (NaN before the first target).
    sensors : tuple of int
        Measured node indices.
    calibration_time : float
        Length of the initial window (robot parked) used to identify the estimator's model, s.
    statuses : tuple of str
        Motion status of every control step ("closed_form", "blocked", or the MPC's status).
    wall_time : float
        Wall-clock time of the loop (after calibration), s.
    settled_window : (float, float)
        Time window (s) over which every metric is computed: from ``settle_margin`` after the robot
        last arrived (stayed within 1 % of a loop of its final position) to the end of the run.
    settled : bool
        False when the robot never stayed put long enough (the window is then the last second).
    comparisons : tuple of Comparison
        no robot, parked near a clamp, parked at the start, parked at the best position, and
        the closed loop, over the same settled window.
    scan_positions, scan_rms : ndarray
        The exact steady-state scan (:func:`parked_steady_state`): RMS displacement over the
        span (m) with the robot parked at each position it could reach in the run (rest-to-rest
        within half the time after calibration, inside its free interval), for the last harmonic
        load (empty when the load is not harmonic).
    best_position : float
        Minimiser of the scan, m (NaN without a harmonic load).
    loop_length : float
        Half-wavelength of the bare line at the final dominant frequency, m.
    frequency : ndarray, shape (n_steps,)
        Dominant frequency the controller watched at each control step, Hz: over the last
        ``frequency_window`` (wind changes are detected on it). Each decision's own tone, from
        the excitation's record, is ``predictions[i][4]``.
    retarget_times, settle_times : tuple of float
        When the controller chose a new target (s), and how long the robot then took to arrive
        and stay within 1 % of a loop (s; NaN if it did not).
    follow_times : tuple of float
        For every change of load in a schedule (a wind change): the time from the change until
        the robot arrived at its new target and stayed (detection, retarget and move), s; NaN
        when it did not.
    innovation_ratio : ndarray, shape (n_steps,)
        RMS one-step prediction error of the sensors over the last window, relative to its value
        on the calibration record: the estimator's model is taken as valid below 3.
    damper_power : ndarray, shape (n_t,)
        Power dissipated in the robot's damper, W.
    predictions : tuple of (float, ndarray, ndarray, ndarray, float)
        At each target choice and confirmation: the time (s), the positions and the figure the
        controller predicted for the robot parked there (the steady-state RMS, m; in the
        self-limiting wind the inverse coupling to the locked mode), the shape it predicted from
        (the robot-free excited shape, complex amplitude at every node, m; in the self-limiting
        wind the locked mode's shape), and the tone it was made at (Hz, measured on the
        excitation's record since it began, not on the last window).
    decisions : tuple of (float, str)
        Every decision of the policy, in words: the time (s) and what it chose ("target ...",
        "confirm ...", "another loop ...", "final ...") or why it held still ("hold ...: the
        best predicted position is only 2 % lower"); with calibration, when the span calibrated
        from the records moved its belief ("believe tension ...") or could not be calibrated
        ("belief kept ...: why").
    span : Span or None
        The line simulated (the truth).
    nominal : Span or None
        The span the controller was told (``run_closed_loop``'s ``nominal``; the truth's when
        it was None).
    belief : Span or None
        The span the controller last believed: the nominal one, or as calibrated from the
        records (:attr:`calibrations`).
    calibrations : tuple of (float, SpanCalibration)
        Every calibration of the span from the sensors' records during the run: the time (s)
        and the :class:`~powerline_control.identify.SpanCalibration` (empty without
        calibration).
    misfits : tuple of (float, float, float)
        Each check of the belief against the measurements: the time (s), where the robot had
        settled (m) and the misfit of shapes (sqrt(1 - MAC)) between the sensors' phasors
        measured there and those the belief predicted at the decision that sent it.
    contradictions : tuple of (float, str)
        Each move whose measured effect contradicted the belief (the sensors measured a rise of
        vibration many times what the belief predicted,
        :class:`~powerline_control.closed_loop.PolicySettings` ``contradiction_rise`` and
        ``contradiction_factor``): the time (s) and what the robot did, in words (went back, or
        held when the run left no time to go back). Each is also a
        :class:`~powerline_control.errors.BeliefContradictedWarning`.
    policy : PolicySettings
        The policy's settings the run used (``run_closed_loop(settings=...)``).
    aeolian_steady : AeolianSteady or None
        With ``run_closed_loop(aeolian_steady=True)`` and an aeolian load: the robot where the
        loop ended, judged again in the self-limiting wind in steady state (the energy
        balance's wind power and the conductor's self-damping,
        :func:`~powerline_control.severity.simulate_aeolian`), against no robot, a fixed damper
        near the clamp and the antinode (:class:`~.aeolian_steady.AeolianSteady`). The
        :attr:`comparisons` are under the run's own load, a lift of fixed amplitude: they rank
        positions under one load; these are where the line settles. None when not asked.
    estimator_consistency : Consistency or None
        The windowed NIS test (:class:`~powerline_control.estimate.Consistency`) of the
        estimator's filters over the calibration record and the loop (each window from the
        filter running at its end; None when no window completed): with the "recipe"
        estimator, ``consistent`` False says the model identified with the robot parked at its
        start no longer fits (the robot's own damping changes the line); with "robot_input",
        whose model carries the robot wherever it is and follows the controller's belief of
        the line and the load's tone (:attr:`estimator_updates`), that the line or its load
        changed in a way the model does not follow. The policy does not act on that
        estimate; it targets from the sensors' phasors and the line's modes.
    estimator : str
        The estimator's model (``run_closed_loop``'s ``estimator``): "recipe" or
        "robot_input".
    wind : str
        What the aeolian load did to the simulated line (``run_closed_loop``'s ``wind``):
        "fixed_lift" or "self_limiting" (then :attr:`comparisons` are over the settled window
        of runs in that wind, each started at the energy balance's amplitude).
    estimator_updates : tuple of (float, str)
        When (s) and why the "robot_input" estimator was rebuilt, warmed on the last
        calibration window's length of the records (the new filter runs from the next sample):
        "line", a calibration moved the belief beyond twice its uncertainty from the line the
        estimator modelled; "tone", the sensors' tone moved away from the one its load
        oscillates at as far and as long as a wind change the policy acts on.
    timings : dict
        Wall-clock seconds spent in: setup (modes, calibration, identification), plant (sample
        stepping and sensing), plant update (re-discretising after a move), filter (Kalman
        steps), policy and motion, comparisons (parked runs and the steady-state scan); the
        process times (less sensitive to the machine's load) "setup cpu", "loop cpu",
        "comparisons cpu", "calibration cpu" (the span's calibrations and the belief's
        rebuilds, within the loop's), "estimator updates cpu" (the estimator's rebuilds on the
        belief, within the loop's), "aeolian steady cpu" (the self-limiting runs, when asked)
        and "call cpu" (the whole call); "modes", the number of bare-line modes the plant
        kept; and with ``wind="self_limiting"`` "damping rebuilds", the discretisations the
        held amplitude-dependent damping rebuilt over the call's runs.

    Examples
    --------
    >>> import powerline_control as plc
    >>> robot = plc.MDR.tuned(1.2, 0.02, 0.05, 24.5, 0.1)
    >>> result = plc.run_closed_loop(plc.Span.paper_lab(), plc.HarmonicForce(1.0, 24.0, 0.5),
    ...                              robot, n_elements=20, sensors=[4, 9, 15], duration=5.0,
    ...                              calibration=1.0)
    >>> result.displacement.shape, len(result.statuses)      # 80 control steps of 50 ms
    ((21, 5001), 80)
    >>> [c.name for c in result.comparisons]
    ['no_robot', 'near_clamp', 'start', 'best', 'closed_loop']
    >>> result.decisions[0]
    (1.0, 'target 0.6882 m (predicted 96 % lower)')
    """

    t: np.ndarray
    x: np.ndarray
    displacement: np.ndarray
    baseline_displacement: np.ndarray
    estimated_field: np.ndarray
    robot_position: np.ndarray
    robot_velocity: np.ndarray
    target: np.ndarray
    sensors: tuple
    calibration_time: float
    statuses: tuple
    wall_time: float = field(repr=False)
    settled_window: tuple = (0.0, 0.0)
    settled: bool = False
    comparisons: tuple = ()
    scan_positions: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    scan_rms: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    best_position: float = float("nan")
    loop_length: float = float("nan")
    frequency: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    retarget_times: tuple = ()
    settle_times: tuple = ()
    innovation_ratio: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    damper_power: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    predictions: tuple = field(default=(), repr=False)
    timings: dict = field(default_factory=dict, repr=False)
    follow_times: tuple = ()
    decisions: tuple = ()
    estimator_consistency: object = field(default=None, repr=False)
    span: object = field(default=None, repr=False)
    nominal: object = field(default=None, repr=False)
    belief: object = field(default=None, repr=False)
    calibrations: tuple = field(default=(), repr=False)
    misfits: tuple = field(default=(), repr=False)
    contradictions: tuple = ()
    policy: PolicySettings = field(default_factory=PolicySettings, repr=False)
    aeolian_steady: object = field(default=None, repr=False)
    estimator: str = field(default="recipe", repr=False)
    estimator_updates: tuple = field(default=(), repr=False)
    wind: str = field(default="fixed_lift", repr=False)

    def comparison(self, name: str) -> Comparison:
        """The comparison called ``name`` (see :attr:`comparisons`)."""
        for item in self.comparisons:
            if item.name == name:
                return item
        raise InputError(
            f"The 'name' parameter must be one of {[c.name for c in self.comparisons]}. "
            f"Got {name!r}."
        )

    @property
    def window_mask(self) -> np.ndarray:
        """Boolean mask of the samples in :attr:`settled_window`."""
        return (self.t >= self.settled_window[0]) & (self.t <= self.settled_window[1])

    @property
    def estimator_valid(self) -> np.ndarray:
        """Per control step: the estimator's model still fits (innovation ratio below
        ``policy.innovation_ratio_limit``, 3 by default)."""
        return self.innovation_ratio < self.policy.innovation_ratio_limit

    @property
    def last_quarter_range(self) -> float:
        """Range of the robot's position over the last quarter of the run (the policy's quiet
        end, where no move is made), in loops (the robot has settled when it is at most 0.02)."""
        last = self.t >= quiet_from(self.t[0], self.t[-1], self.policy)
        return float(np.ptp(self.robot_position[last]) / self.loop_length)

    @property
    def rms_closed_loop(self) -> float:
        """RMS displacement over the span in the settled window, m."""
        return self.comparison("closed_loop").rms

    @property
    def rms_baseline(self) -> float:
        """The same with the robot parked at its start, m."""
        return self.comparison("start").rms

    @property
    def vibration_reduction(self) -> float:
        """rms_baseline / rms_closed_loop: how many times less the line vibrates."""
        return self.rms_baseline / self.rms_closed_loop

    @property
    def real_time_factor(self) -> float:
        """Simulated loop time over the loop's process (CPU) time (> 1: faster than real time).

        Process time, not wall-clock time, so that the figure does not depend on what else the
        machine runs (:attr:`wall_time` is the loop's wall-clock time; a result built without
        ``timings["loop cpu"]`` falls back to it). The whole call, calibration and comparisons
        included, is ``timings["call cpu"]``.
        """
        busy = self.timings.get("loop cpu", self.wall_time)
        return (self.t[-1] - self.calibration_time) / max(busy, 1e-12)

    @property
    def steady_verdict(self) -> bool:
        """True when the run was in the self-limiting wind and judged there
        (:attr:`aeolian_steady`): its verdict (:attr:`shortfalls`, the report's comparisons) is
        then that steady state, since its own window is the amplitude still on its way (with the
        robot it settles over minutes)."""
        return self.aeolian_steady is not None and self.wind == "self_limiting"

    @property
    def shortfalls(self) -> tuple:
        """What the run fell short of, in words: ending more than 5 % worse than the robot parked at
        its start, or worse than a fixed damper parked near the clamp. Under the run's load the
        settled window decides; when the run was judged in the self-limiting wind
        (:attr:`aeolian_steady`) its steady state decides too, and alone when the run itself was in
        that wind (:attr:`steady_verdict`). Empty when it did neither, or when the robot had not
        settled (a run that ends with the robot still moving is no verdict) or the run lacks those
        comparisons.

        Examples
        --------
        >>> import powerline_control as plc
        >>> robot = plc.MDR.tuned(1.2, 0.02, 0.05, 24.5, 0.1)
        >>> result = plc.run_closed_loop(plc.Span.paper_lab(), plc.HarmonicForce(1.0, 24.0, 0.5),
        ...                              robot, n_elements=20, sensors=[4, 9, 15], duration=5.0,
        ...                              calibration=1.0)
        >>> result.shortfalls
        ()
        """
        names = {c.name for c in self.comparisons}
        if not self.settled or not {"closed_loop", "start", "near_clamp"} <= names:
            return ()
        limits = (("start", 1.05, "where the robot started"),
                  ("near_clamp", 1.0, "a fixed damper parked near the clamp"))
        steady = self.aeolian_steady
        out = []
        if not self.steady_verdict:
            closed = self.comparison("closed_loop")
            for name, tolerance, what in limits:
                other = self.comparison(name)
                if closed.rms > tolerance * other.rms:
                    out.append(f"the line ends {closed.rms / other.rms:.2f}x as high (RMS "
                               f"{1e3 * closed.rms:.4g} mm) as with the robot parked at "
                               f"{other.position:.4g} m, {what} ({1e3 * other.rms:.4g} mm)")
        if steady is not None:
            ended = steady.closed_loop
            for name, tolerance, what in limits:
                other = getattr(steady, name)
                if ended.amplitude > tolerance * other.amplitude:
                    out.append(f"in the self-limiting wind the line settles "
                               f"{ended.amplitude / other.amplitude:.2f}x as high (antinode "
                               f"amplitude {1e3 * ended.amplitude:.4g} mm) as with the robot "
                               f"parked at {other.robot_position:.4g} m, {what} "
                               f"({1e3 * other.amplitude:.4g} mm)")
        return tuple(out)

    def summary(self) -> str:
        """A few lines: what the controller believed, the settled window, every comparison (under
        the run's load), what the run fell short of, and the self-limiting steady state when it
        was judged (:attr:`aeolian_steady`)."""
        lines = [] if self.belief is None else [self._belief_line()]
        lines.append(
            f"settled window {self.settled_window[0]:.2f}-{self.settled_window[1]:.2f} s"
            + ("" if self.settled else " (robot did not settle)"))
        for c in self.comparisons:
            lines.append(
                f"{c.name:12s} x = {c.position:7.3f} m  rms {1e3 * c.rms:8.4f} mm  "
                f"peak {1e3 * c.peak:8.4f} mm  damper {1e3 * c.damper_power:8.4f} mW"
            )
        lines += [f"shortfall: {text}" for text in self.shortfalls]
        if self.aeolian_steady is not None:
            lines.append(self.aeolian_steady.summary())
        return "\n".join(lines)

    def _belief_line(self) -> str:
        """The tension the controller believed at the end (with the last calibration's, and
        its standard deviation, when it calibrated), what it was told and the truth's."""
        believed = f"belief: tension {self.belief.tension:.5g} N"
        if self.calibrations:
            time, last = self.calibrations[-1]
            believed += (f" (last calibration {last.tension:.5g} +- {last.tension_std:.2g} N "
                         f"at {time:.3g} s)")
        told = "" if self.nominal is None else f", told {self.nominal.tension:.5g} N"
        truth = "" if self.span is None else f"; truth {self.span.tension:.5g} N"
        return believed + told + truth

