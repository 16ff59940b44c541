"""The closed-loop policy's settings in one place: :class:`PolicySettings`.

Every number the policy (:mod:`.policy`) and the controller's belief (:mod:`.belief`) decide by,
with its value, what it guards and where the evidence for it is. The defaults are the values the
policy was tuned and held out with: ``run_closed_loop(..., settings=PolicySettings())`` is
``run_closed_loop(...)``, bit for bit. The evidence is on two validation pages:
``docs/validation/closed_loop.md`` (the families, "Measurements behind the policy's rules") and
``docs/validation/closed_loop_off_nominal.md`` (the belief, when the line is not what the
controller is told).
"""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass

from ..errors import InputError

__all__ = ["PolicySettings"]

_POLICY_PAGE = "docs/validation/closed_loop.md"
_BELIEF_PAGE = "docs/validation/closed_loop_off_nominal.md"


def _field(default, allowed: str, low=None, high=None, *, low_inclusive=False,
           high_inclusive=True, integer=False):
    """A setting: its default and the range :class:`PolicySettings` checks it against."""
    return dataclasses.field(default=default, metadata={
        "allowed": allowed, "low": low, "high": high, "low_inclusive": low_inclusive,
        "high_inclusive": high_inclusive, "integer": integer})


@dataclass(frozen=True)
class PolicySettings:
    """The closed-loop policy's settings: where the robot goes and when it trusts a calibration.

    Each setting guards one decision of the policy (``closed_loop/policy.py``) or of the
    controller's belief (``closed_loop/belief.py``). The defaults are the values the policy was
    tuned with on the even seeds of the closed-loop family and held out on the odd ones; the
    measurements behind each are on the validation pages named below
    (``docs/validation/closed_loop.md``, ``docs/validation/closed_loop_off_nominal.md``).
    Change one to study the policy, not to fix a run: a value tuned on the case it is judged on
    proves nothing (design.md 4.6).

    Parameters
    ----------
    unsteady_limit : float
        0.25. A window whose two halves give robot-free shapes differing by more than this
        (relative) still beats with a decaying mode: a decision waits for a steady one.
        Guards refinements taken from beating windows, which moved the robot 0.15 loop the
        wrong way on ``drake-300m`` (closed_loop.md, "Beating windows").
    max_wait : float
        3.0 s. How long a decision waits for a steady window; a confirmation still beating
        after it ends the search (closed_loop.md, "Beating windows").
    max_choices : int
        3. Loops tried per excitation before the choice is final: the search ends
        (closed_loop.md, "On a family nobody tuned for").
    near_optimal : float
        0.03. Local minima of the predicted span RMS within this fraction of the lowest count as
        equally good, and the robot takes the nearest: equal loops of a resonant mode need no
        long trip (closed_loop.md, "On a family nobody tuned for").
    travel_fraction : float
        0.5. A decision spends at most this share of the rest of the run travelling: without
        the travel budget the ``drake-300m`` robot chose a loop 59 m away and never arrived
        (closed_loop.md, "The reach").
    min_gain : float
        0.05. A move must be predicted to lower the span's RMS by at least this fraction: below
        it a few sensors' phasors cannot tell two positions apart and the robot holds still
        (closed_loop.md, "The edge of the reach").
    refine_gain : float
        0.01. A refinement inside the anchor's loop must be predicted to gain at least this: near
        a minimum the RMS is flat and a small move only restarts the settling
        (closed_loop.md, "On a family nobody tuned for"). After a hold it is decided on a
        window recorded after the hold.
    same_loop : float
        0.25 loop. A confirmation's choice within this many loop lengths of the anchor is the
        same minimum, better estimated (it refines); farther, it is another loop
        (closed_loop.md, "On a family nobody tuned for").
    worse_tolerance : float
        0.5. A move after which both the sensors' vibration at the load frequency and the span
        RMS estimated there are more than this fraction higher than before it is undone
        (closed_loop.md, "On a family nobody tuned for").
    contradiction_rise : float
        2.0. At a confirmation, the sensors' power at the load frequency measured after a move
        over the power measured before it: a move after which it rose more than this (the
        sensors' RMS by 41 %) ...
    contradiction_factor : float
        4.0. ... and more than this many times what the belief predicted for the move
        contradicts the belief: the robot goes back to where it was (when the rest of the run
        lets it) and trusts no further prediction for this excitation. Of the family's moves
        after which the sensors measured more than twice the power (odd seeds 169-251), the one
        that helped had been predicted to raise it (measured 1.3x the predicted rise), the two
        that ended 2.2-2.5x above the best position had been predicted to lower it (33-44x)
        (closed_loop_off_nominal.md, "Measurements that contradict the belief").
    decision_tone_window : float
        12.0 s. A decision's tone is measured on the excitation's record, at most this long: a
        2 s window's peak lands up to a mode spacing off the load on a long span and swaps nodes
        and antinodes (closed_loop.md, "The tone a decision is made at": tune seed 52, 2.85x).
    tone_resolution : float
        2.0. A new target waits for ``tone_resolution / spacing`` s of record (spacing: of the
        modes around the tone, Hz), which resolves the load from the modes beside it
        (closed_loop.md, "The tone a decision is made at": within 0.1 spacing in 9 of 12).
    max_tone_wait : float
        8.0 s. The longest that wait.
    tone_wait_fraction : float
        0.25. ... and at most this share of what is left of the run, so the robot keeps time to
        move and settle (closed_loop.md, "On a family nobody tuned for").
    confirm_resolve : float
        0.5. A confirmation waits, with the robot still, for this share of the record that
        resolves the tone (closed_loop.md, "On a family nobody tuned for").
    quiet_fraction : float
        0.25. Every move ends before the last this share of the run, the window the result
        judges settling on: of 5 moves started there, 3 made the spot worse and all 5 runs ended
        unsettled (closed_loop.md, "The quiet end").
    min_change_hold : float
        1.0 s. A wind change must hold for the change-detection window and at least this long
        before the robot chooses anew (closed_loop.md, "On a family nobody tuned for").
    grid_per_node : int
        4. Candidate parked positions per node of the believed mesh (the predicted RMS is
        evaluated on ``max(grid_per_node * n_nodes, min_grid)`` positions of the free interval).
    min_grid : int
        200. The fewest candidate positions. (A resolution, not a tuned rule: the parabola
        through the grid's minimum refines between candidates.)
    prior_damping_floor : float
        1e-3. Damping ratio floor of the modal prior the robot-free shape is fitted with
        (``1 / |omega_n^2 - omega^2 + 2 i floor omega_n omega|^2``): keeps it finite on an
        undamped line at resonance (a numerical safeguard, not a tuned rule).
    prior_regularization : float
        1e-6. Relative ridge added to the prior's Gram matrix (times its mean diagonal) before
        the shape's fit solves it: keeps two nearly equal sensor rows solvable (a numerical
        safeguard).
    reach_warning_loops : float
        0.25 loop. A ReachWarning says the limits are too slow when, in half the rest of the
        run, they let the robot travel less than this many loop lengths (closed_loop.md,
        "The reach").
    innovation_ratio_limit : float
        3.0. The estimator's recent one-step error over its calibration value above which its
        model no longer fits (``ClosedLoopResult.estimator_valid``): 0.7-0.9 while the load is
        the calibration's, 5-9 in the second after a wind change, about 1.5 after
        (closed_loop.md, "The estimator's innovation ratio").
    belief_tolerance : float
        1e-3. The belief is rebuilt on a calibrated tension that differs from the believed one by
        more than this fraction: a smaller change moves an antinode 200 m from a support by less
        than 5 % of a loop at mode 100 (closed_loop_off_nominal.md).
    trusted_share : float
        0.8. The belief moves on a calibration whose main peak holds at least this share of its
        posterior (odds of 4 to 1; an unambiguous one holds 95 %): a robot that waits for
        certainty holds still at its start, often near a node (closed_loop_off_nominal.md).
    less_certain : float
        2.0. A calibration this many times less certain than the one believed moves nothing (a
        record over which the robot moved tells less); 1 was measured on the tuning seeds and
        lost (closed_loop_off_nominal.md, seed 243).
    min_cycles : float
        2.0. The span is calibrated on records (and stretches of record the robot stood still
        in) of at least this many cycles of the nominal fundamental: shorter ones cannot tell
        neighbouring modes apart (a record resolves lines about 2 / duration apart;
        closed_loop_off_nominal.md).
    moved_record_z : float
        2.0. Once the robot has moved, a calibration of the whole record that differs from the
        one of the longest stretch the robot stood still in by more than this many combined
        standard deviations gives way to the latter: a move can smear a mode into two lines
        (seed 837: 31 415 +- 355 N over a 6.8 m move, 33 050 +- 622 N before it; the line shows
        32 982 N; closed_loop_off_nominal.md). The whole record is believed otherwise: it is
        longer and tells the tension more surely.

    Raises
    ------
    InputError
        If a setting is not a finite number in its range (the message names the setting, the
        value and what is allowed).

    Examples
    --------
    >>> import powerline_control as plc
    >>> settings = plc.PolicySettings()
    >>> settings.min_gain, settings.travel_fraction
    (0.05, 0.5)
    >>> cautious = plc.PolicySettings(min_gain=0.1)        # move only for a 10 % gain
    >>> cautious.min_gain
    0.1
    >>> plc.PolicySettings(min_gain=1.5)
    Traceback (most recent call last):
    ...
    powerline_control.errors.InputError: The 'PolicySettings.min_gain' setting must be a number \
in [0, 1) (the predicted relative drop of the span's RMS a move must bring). Got 1.5.
    """

    unsteady_limit: float = _field(0.25, "a number > 0 (a relative difference of two shapes)",
                                   0.0)
    max_wait: float = _field(3.0, "a number of seconds >= 0", 0.0, low_inclusive=True)
    max_choices: int = _field(3, "an integer >= 1 (loops tried per excitation)", 1,
                              low_inclusive=True, integer=True)
    near_optimal: float = _field(0.03, "a number in [0, 1) (a fraction of the lowest RMS)", 0.0,
                                 1.0, low_inclusive=True, high_inclusive=False)
    travel_fraction: float = _field(0.5, "a number in (0, 1] (a share of the rest of the run)",
                                    0.0, 1.0)
    min_gain: float = _field(0.05, "a number in [0, 1) (the predicted relative drop of the span's "
                             "RMS a move must bring)", 0.0, 1.0, low_inclusive=True,
                             high_inclusive=False)
    refine_gain: float = _field(0.01, "a number in [0, 1) (a predicted relative drop)", 0.0, 1.0,
                                low_inclusive=True, high_inclusive=False)
    same_loop: float = _field(0.25, "a number of loop lengths > 0", 0.0)
    worse_tolerance: float = _field(0.5, "a number >= 0 (a relative increase)", 0.0,
                                    low_inclusive=True)
    contradiction_rise: float = _field(2.0, "a number >= 1 (a ratio of measured powers)", 1.0,
                                       low_inclusive=True)
    contradiction_factor: float = _field(4.0, "a number >= 1 (a ratio of measured to predicted "
                                         "rises)", 1.0, low_inclusive=True)
    decision_tone_window: float = _field(12.0, "a number of seconds > 0", 0.0)
    tone_resolution: float = _field(2.0, "a number > 0 (mode spacings times seconds)", 0.0)
    max_tone_wait: float = _field(8.0, "a number of seconds >= 0", 0.0, low_inclusive=True)
    tone_wait_fraction: float = _field(0.25, "a number in [0, 1] (a share of the rest of the "
                                       "run)", 0.0, 1.0, low_inclusive=True)
    confirm_resolve: float = _field(0.5, "a number >= 0 (a share of the resolving record)", 0.0,
                                    low_inclusive=True)
    quiet_fraction: float = _field(0.25, "a number in [0, 1) (a share of the run)", 0.0, 1.0,
                                   low_inclusive=True, high_inclusive=False)
    min_change_hold: float = _field(1.0, "a number of seconds >= 0", 0.0, low_inclusive=True)
    grid_per_node: int = _field(4, "an integer >= 1 (candidate positions per node)", 1,
                                low_inclusive=True, integer=True)
    min_grid: int = _field(200, "an integer >= 3 (candidate positions)", 3, low_inclusive=True,
                           integer=True)
    prior_damping_floor: float = _field(1e-3, "a damping ratio > 0", 0.0)
    prior_regularization: float = _field(1e-6, "a number > 0 (relative to the mean diagonal)",
                                         0.0)
    reach_warning_loops: float = _field(0.25, "a number of loop lengths >= 0", 0.0,
                                        low_inclusive=True)
    innovation_ratio_limit: float = _field(3.0, "a number > 0 (a ratio of RMS innovations)", 0.0)
    belief_tolerance: float = _field(1e-3, "a number >= 0 (a fraction of the believed tension)",
                                     0.0, low_inclusive=True)
    trusted_share: float = _field(0.8, "a number in [0, 1] (a share of the posterior)", 0.0, 1.0,
                                  low_inclusive=True)
    less_certain: float = _field(2.0, "a number >= 1 (a ratio of standard deviations)", 1.0,
                                 low_inclusive=True)
    min_cycles: float = _field(2.0, "a number >= 0 (cycles of the fundamental)", 0.0,
                               low_inclusive=True)
    moved_record_z: float = _field(2.0, "a number > 0 (combined standard deviations)", 0.0)

    def __post_init__(self) -> None:
        for item in dataclasses.fields(self):
            object.__setattr__(self, item.name, _checked(item, getattr(self, item.name)))


def _checked(item: dataclasses.Field, value: object):
    """``value`` of the setting ``item`` as its type, or an InputError naming it."""
    meta = item.metadata
    refused = InputError(
        f"The 'PolicySettings.{item.name}' setting must be {meta['allowed']}. Got {value!r}.")
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise refused
    if meta["integer"]:
        if not isinstance(value, numbers.Integral):
            raise refused
        value = int(value)
    else:
        value = float(value)
        if value != value or value in (float("inf"), float("-inf")):
            raise refused
    low, high = meta["low"], meta["high"]
    if low is not None and (value < low or (value == low and not meta["low_inclusive"])):
        raise refused
    if high is not None and (value > high or (value == high and not meta["high_inclusive"])):
        raise refused
    return value


def checked_policy(settings: object) -> PolicySettings:
    """``settings`` as given (None: the defaults), or an InputError naming the parameter."""
    if settings is None:
        return PolicySettings()
    if not isinstance(settings, PolicySettings):
        raise InputError(f"The 'settings' parameter must be a PolicySettings or None. Got "
                         f"{type(settings).__name__}.")
    return settings
