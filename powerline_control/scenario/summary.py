"""A ScenarioResult in words and numbers: report sections and the HTML report.

One unit per quantity everywhere: displacements and noise in mm in text (m in JSON, ``_m``
keys), estimation errors in per cent (``_percent`` keys), positions in m with the node index
beside them, frequencies in Hz, times in s, strain in microstrain. Figures are handed over as
functions that draw them; their captions are generated from the drawn figure
(:func:`~powerline_control.output.captions.figure_caption`), so a caption cannot contradict its
figure.

The JSON summary is :mod:`.summary_json`'s.

Test seam: ``_recipe_text`` and ``_least_damped``: the identification row's words, tested
against the model's type, its sweep and eigenvalues; ``_consistency_text``: the closed loop's
consistency row, tested on hand-built windows.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

from .._constants import NOISE_FLOOR_FRACTION
from .summary_format import _figure, _plotting, mm, percent, positions_text
from .summary_truth import calibration_rows, truth_rows

__all__ = ["result_sections", "write_result_report"]


# ----------------------------------------------------------------------------- sections

def _model_section(r) -> dict:
    import numpy as np

    sc, span, model = r.scenario, r.span, r.model
    x = np.asarray(model.node_positions)
    h = np.diff(x)
    cond = span.conductor
    mesh = (f"{model.n_elements} Hermite cubic beam elements of {h.min():.3g} m"
            if np.ptp(h) < 1e-9 * h.max() else
            f"{model.n_elements} Hermite cubic beam elements, {h.min():.3g}-{h.max():.3g} m "
            "long (graded toward the supports)")
    frequencies = model.natural_frequencies(min(5, model.n_dofs))
    speed = math.sqrt(span.tension / cond.mass_per_length)
    load = sc.forcing.load_frequency(span)
    rows = [
        ("span (nominal)", f"{span.length:g} m between supports, tension {span.tension:.4g} N",
         "The paper's laboratory span (Table 1)" if sc.span.preset == "paper_lab" else
         f"{sc.span.rts_fraction:.0%} of the conductor's rated tensile strength"
         if sc.span.tension is None else "tension from the scenario"),
        ("conductor", f"{cond.name}: {cond.mass_per_length:.4g} kg/m, EI {cond.ei:g} N m^2, "
         f"diameter {1e3 * cond.diameter:g} mm", _conductor_note(cond)),
        ("wave speed sqrt(T/m)", f"{speed:.4g} m/s",
         f"Sets the loop length: at the load's {load:.4g} Hz a standing wave's loops are "
         f"{speed / (2 * load):.3g} m long (c / 2f), {span.length * 2 * load / speed:.3g} loops "
         "over the span." if load > 0 else "Sets the loop length of a standing wave (c / 2f)."),
        ("model", f"{mesh}; {model.n_nodes} nodes, {model.n_dofs} degrees of freedom; "
         f"{model.bc[0]} / {model.bc[1]} supports",
         "A Galerkin model of the taut Euler-Bernoulli line: bending stiffness EI plus the "
         "tension's geometric stiffness."),
        ("first natural frequencies (nominal)", ", ".join(f"{f:.4g}" for f in frequencies)
         + " Hz", _nearest_mode_note(frequencies, load, model.n_dofs)),
        *truth_rows(r),
        ("load", sc.forcing.describe(span, sc.robot.wind),
         "It drives the true line in every simulated run: the records, the closed loop and its "
         "parked comparisons."),
    ]
    return {"title": "Span and model", "rows": rows}


def _conductor_note(cond) -> str:
    """Why the conductor's numbers matter, from them: the wind's Strouhal band on it."""
    from .._constants import STROUHAL

    low, high = (STROUHAL * v / cond.diameter for v in (1.0, 7.0))
    return (f"Mass and tension set the wave speed, EI the bending stiffness near the clamps; a "
            f"1-7 m/s wind sheds vortices from this {1e3 * cond.diameter:g} mm conductor at "
            f"{low:.3g}-{high:.3g} Hz (f = St V / d, St = {STROUHAL:g}).")


def _nearest_mode_note(frequencies, load: float, n_dofs: int) -> str:
    """Which listed mode the load's frequency is nearest, and how far, in words."""
    import numpy as np

    if load <= 0 or not len(frequencies):
        return f"The lowest of the model's {n_dofs} modes."
    i = int(np.argmin(np.abs(np.asarray(frequencies) - load)))
    off = 100.0 * (load / frequencies[i] - 1.0)
    where = ("above the last one listed" if load > frequencies[-1] * 1.1 else
             f"nearest mode {i + 1} ({off:+.2g} %)")
    return (f"The load's {load:.4g} Hz is {where}: the nearer a mode, the more the line "
            "responds in that mode's shape.")


def _records_section(r) -> dict:
    import numpy as np

    rec, sim = r.records, r.scenario.simulation
    snap = rec.test
    tail = snap.true_displacement[:, -snap.t.size // 4:]
    rms = float(np.sqrt(np.mean(snap.true_displacement**2)))
    crest = float(np.abs(tail).max() / max(np.sqrt(np.mean(tail**2)), 1e-300))
    use = ("the first {:.0%} identify the model, the rest test it" if rec.shaker is None else
           "the last {:.0%} test the estimator (trained on the identification run below)")
    share = rec.n_train / snap.t.size if rec.shaker is None else 1 - rec.n_train / snap.t.size
    held = snap.t.size - rec.n_train if rec.shaker is None else \
        int(round(share * snap.t.size))
    rows = [("record", f"{snap.t.size} samples at dt = {snap.dt:g} s ({sim.duration:g} s); "
             + use.format(share),
             f"Every estimation error below is measured on the {held} held-out samples "
             f"({held * snap.dt:.3g} s) the model never saw.")]
    if rec.shaker is not None:
        rows.append(("identification run",
                     f"the scenario's load plus a broadband shaker ({rec.shaker.std:g} N std, "
                     f"up to {rec.shaker.bandwidth:g} Hz, at {rec.shaker_position:.4g} m), "
                     f"{rec.n_train} samples (its own noise): it trains the estimator"
                     if hasattr(rec.shaker, "std") else
                     f"the scenario's load plus a broadband shaker at "
                     f"{rec.shaker_position:.4g} m, {rec.n_train} samples: it trains the "
                     "estimator",
                     "The shaker excites the modes the scenario's load barely shows, so that the "
                     "model knows them when a load drives them."))
    rows += [
        ("modes kept", f"{snap.n_modes} of {r.true_model.n_dofs}",
         "Every mode of the model: nothing truncated." if snap.n_modes >= r.true_model.n_dofs
         else f"The simulation keeps the {snap.n_modes} lowest modes and the quasi-static part "
         "of the rest, which the loads here barely drive."),
        ("RMS / peak displacement (last quarter)",
         f"{mm(np.sqrt(np.mean(tail**2)))} / {mm(np.abs(tail).max())}",
         f"Over the whole span and the last quarter of the record; the peak is {crest:.3g} x "
         "the RMS (one standing wave's is 2 x: half its mean square is in space, half in "
         "time)."),
        ("sensor noise std", f"{mm(snap.noise_std)} "
         f"({percent(snap.noise_std / rms) if rms > 0 else '0 %'} of the RMS displacement)",
         f"Added to every measured sample (simulation.noise_fraction = {sim.noise_fraction:g}): "
         "the estimator never sees the true displacement."),
        ("simulation time", f"{rec.simulation_s:.2f} s",
         "Wall-clock time of the simulations above; every stage's time is in the JSON "
         "summary's elapsed_s."),
    ]
    if rec.measured is not None:
        m = rec.measured
        rows.append(("measured record", f"{m.values.shape[1]} samples at {1 / m.dt:g} Hz, "
                     f"{m.values.shape[0]} channels at " + positions_text(m.positions)
                     + f"; {int(m.n_missing)} missing samples", f"from {m.source}"))
    return {"title": "Simulated data", "rows": rows}


def _recipe_text(design) -> str:
    from ..identify import OscillatorModel

    m = design.model
    if isinstance(m, OscillatorModel):  # its type, not its alpha or delays, says what it is
        return (f"{m.describe()}, one undamped oscillator per spectral line of the record, "
                f"plus {m.n_unseen} white states for unexcited directions; {m.n_states} states "
                f"in all, trained on {design.n_train} samples")
    return (f"time-delay DMD, {m.delays} delays ({m.delays * m.dt * 1e3:.3g} ms of history), "
            f"{m.n_states} states, Tikhonov alpha {m.alpha_relative:.3g} relative "
            f"({alpha_choice(design)}), trained on {design.n_train} samples")


def _recipe_note(design) -> str:
    """Why the identified model has the shape it has, from its own sizes."""
    from ..identify import OscillatorModel

    m = design.model
    if isinstance(m, OscillatorModel):
        return (f"The record is narrowband: its {len(m.line_frequencies)} spectral lines explain "
                "it, so one oscillator per line is the model; a load that drives other modes is "
                "beyond what it learnt.")
    if m.delays > 1:
        return (f"A line is second order: displacements alone are not a state; {m.delays} "
                f"delayed snapshots carry its velocity too, in {m.n_states} states.")
    return (f"One snapshot per state ({m.n_states} states): the displacements alone, as in the "
            "paper; a line is second order, so delays usually fit it better.")


def _given_alpha_text(given, design) -> str:
    """What became of the scenario's own alpha: the recipe starts its sweep there and widens."""
    alpha = getattr(design.model, "alpha_relative", None)
    if given == "auto" or alpha is None or math.isclose(float(given), float(alpha)):
        return ""
    return (f"; the scenario's alpha = {float(given):.3g} was only where the sweep started: the "
            f"held-out error was lower at {float(alpha):.3g}, which the recipe used")


def alpha_at_sweep_cap(design) -> bool:
    """Whether the recipe's alpha is the last (largest) of its held-out sweep (AlphaSweep): the
    held-out error was lowest at the sweep's top, so it may still have been falling beyond."""
    import numpy as np

    sweep = getattr(design, "alpha_sweep", None)
    errors = np.asarray([] if sweep is None else sweep.held_out_error, dtype=float)
    finite = np.where(np.isfinite(errors), errors, np.nan)
    return bool(errors.size > 1 and np.isfinite(errors).any()
                and int(np.nanargmin(finite)) == errors.size - 1)


def alpha_choice(design) -> str:
    """How alpha was chosen, in words: on held-out data, and whether at the sweep's cap."""
    if not alpha_at_sweep_cap(design):
        return "chosen on held-out data"
    alphas = design.alpha_sweep.alphas
    return (f"chosen on held-out data, but it sits at the cap of the sweep ({len(alphas)} "
            f"alphas up to {float(alphas[-1]):.3g} relative): the held-out error was lowest "
            "there and may still have been falling")


def _identification_section(r) -> dict:
    ident = r.identification
    d, plain = ident.design, ident.plain
    report = d.model.stability_report(warn=False)
    radius, plain_radius = float(d.model.spectral_radius), float(plain.spectral_radius)
    rows = [
        ("recipe", "the package's recipe (design_estimator): " + _recipe_text(d)
         + _given_alpha_text(r.scenario.identification.alpha, d), _recipe_note(d)),
        ("spectral radius / unstable eigenvalues",
         f"{radius:.6f} / {int(report.n_unstable)}",
         "Largest |eigenvalue| of the identified one-step map. Below 1 the model is stable: "
         "a Kalman filter and python-control's dlqe accept it."),
        ("plain DMD (alpha = 0, one delay)", f"spectral radius {plain_radius:.6f}"
         + (" (ill-conditioned: it inverts round-off)" if ident.plain_ill_conditioned else ""),
         "The unregularised fit (the paper's eq. 11) on the same training data."),
        ("sensor noise std (the filter's R)", mm(float(d.noise_std)), d.noise_origin),
    ]
    if ident.record_model is not None:
        rm = ident.record_model
        freqs = _least_damped(rm)
        rows.append(("the measured record's own model",
                     f"DMD on its {rm.n_nodes} channels ({rm.delays} delays): spectral radius "
                     f"{float(rm.spectral_radius):.6f}; least-damped frequencies "
                     + ", ".join(f"{f:.4g}" for f in freqs) + " Hz",
                     "Fitted on the record's longest stretch without a missing sample; compare "
                     "its frequencies with the model's natural frequencies above."))
    smaller = ("plain DMD" if plain_radius < radius else "the recipe's model")
    compare = (f"Spectral radius: plain DMD {plain_radius:.6f}, the recipe's model "
               f"{radius:.6f} ({smaller} has the smaller one).")
    draw = functools.partial(_eigenvalue_figure, plain.eigenvalues, d.model.eigenvalues)
    return {"title": "Identification", "rows": rows,
            "intro": "The recipe fits a linear one-step map to the training record: time-delay "
            "Dynamic Mode Decomposition with Tikhonov regularisation (the regularisation trades "
            "fit for conditioning; it does not by itself move every eigenvalue inward), or, "
            "for a narrowband record whose spectral lines explain it, one oscillator per line.",
            "figures": [_figure("eigenvalues", draw,
                                "Eigenvalues of plain DMD and of the recipe's model (drawn "
                                "larger, on top), with the unit circle. " + compare,
                                "points outside the circle: those modes grow without bound")]}


def _least_damped(model, n: int = 3) -> list:
    """The damped frequencies (Hz, > 0, distinct) of the n eigenvalues nearest the unit circle."""
    import numpy as np

    order = np.argsort(-np.abs(np.asarray(model.eigenvalues)))
    found = []
    for f in np.asarray(model.damped_frequencies)[order]:
        if f > 0 and all(abs(f - g) > 1e-6 * max(f, 1.0) for g in found):
            found.append(float(f))
        if len(found) == n:
            break
    return found


def _eigenvalue_figure(plain, model):
    return _plotting().plot_eigenvalues({"plain DMD (alpha = 0)": plain,
                                         "the recipe's model": model},
                                        emphasis="the recipe's model")


def _estimation_section(r) -> dict:
    import numpy as np

    snap, n_train = r.records.test, r.records.n_train
    layouts = r.layouts
    chosen = layouts["chosen"]
    rows = []
    for name, layout in layouts.items():
        rows.append((f"error at unmeasured nodes: {name}",
                     f"{layout.error_unmeasured_percent:.3g} % of the RMS displacement, "
                     + positions_text(layout.positions, layout.nodes),
                     "RMS over the nodes without a sensor of (estimate - truth), divided by the "
                     "RMS displacement over the span, on data the model never saw."
                     if name == "chosen" else layout.note))
    best = best_baseline(layouts)
    if best is not None:
        best_name, ratio = best
        verdict = (f"the chosen layout's error is {ratio:.3g} x lower than the best "
                   f"baseline's ({best_name})" if ratio >= 1 else
                   f"the best baseline ({best_name}) beats the chosen layout: its error is "
                   f"{1 / ratio:.3g} x lower")
        rows.append(("chosen against the best baseline", verdict,
                     "Against the best of the baselines above, not the worst. The layout is "
                     "chosen by the filter's predicted steady-state error; this is the error "
                     "measured on held-out data."))
    if r.records.measured is not None and "measured" in getattr(r, "_extra", {}):
        pass
    x = np.asarray(snap.x)
    unmeasured = [i for i in np.linspace(0, x.size - 1, 5).astype(int)[1:-1]
                  if i not in chosen.nodes][:3] or [x.size // 2]
    held = slice(n_train, None)
    estimate_draw = functools.partial(_plotting().plot_estimate, snap.t[held],
                                      snap.true_displacement[:, held], chosen.estimate.field,
                                      [int(i) for i in unmeasured], x)
    along = {n: lay.error_along_span for n, lay in layouts.items()}
    along_draw = functools.partial(_plotting().plot_error_along_span, x, along,
                                   list(chosen.positions), chosen="chosen")
    errors = {n: lay.error_unmeasured_percent for n, lay in layouts.items()}
    positions = {n: list(lay.positions) for n, lay in layouts.items()}
    layout_draw = functools.partial(_plotting().plot_layouts, errors, positions, float(x[-1]))
    figures = [
        _figure("estimate", estimate_draw,
                "The chosen layout's Kalman estimate against the true displacement at nodes "
                "without a sensor, on held-out data.",
                "the estimate sitting on the truth after the first few periods"),
        _figure("error_along_span", along_draw,
                "RMS estimation error at every node, % of the RMS displacement over the span, "
                "for each layout (the chosen one thicker, on top); the chosen sensors marked.",
                "where each layout loses track of the line"),
        _figure("layouts", layout_draw,
                "The chosen layout against the baselines: error at the unmeasured nodes (% of "
                "the RMS displacement) and where each layout puts its sensors (m).",
                "the chosen layout's bar against the best baseline's"),
    ]
    return {"title": "Estimation (Kalman filter on held-out data)", "rows": rows,
            "intro": "A steady-state Kalman filter on the identified model reconstructs the "
            "displacement of every node from the few measured ones. Every layout uses the same "
            "model and noise model; only the measured nodes differ.", "figures": figures}


def best_baseline(layouts) -> tuple[str, float] | None:
    """The baseline layout with the lowest held-out error, and that error over the chosen
    layout's (> 1: the chosen layout is better); None without a baseline.

    Parameters
    ----------
    layouts : mapping of str to Layout
        A result's layouts, "chosen" among them.

    Returns
    -------
    (str, float) or None

    Examples
    --------
    >>> from types import SimpleNamespace as L
    >>> best_baseline({"chosen": L(error_unmeasured_percent=2.0),
    ...                "even": L(error_unmeasured_percent=5.0),
    ...                "first": L(error_unmeasured_percent=9.0)})
    ('even', 2.5)
    """
    chosen = layouts["chosen"].error_unmeasured_percent
    others = {n: lay.error_unmeasured_percent for n, lay in layouts.items() if n != "chosen"}
    if not others:
        return None
    name = min(others, key=others.get)
    return name, others[name] / max(chosen, 1e-300)


def _measured_section(r) -> dict:
    import numpy as np

    m = r.measured
    rec = m.record
    x = np.asarray(r.true_model.node_positions)   # the records' mesh (the line simulated)
    consistency = getattr(m.estimate, "consistency", None)
    verdict = ("no complete window" if consistency is None else
               "consistent" if consistency.consistent else "INCONSISTENT")
    field = np.asarray(m.estimate.field)
    envelope = np.nanmax(np.abs(field[:, field.shape[1] // 2:]), axis=1)
    rows = [
        ("record", f"{rec.values.shape[1]} samples at {1 / rec.dt:.6g} Hz from {rec.source}; "
         f"{rec.n_missing} missing samples (the filter predicts through them)",
         f"{rec.values.shape[1] * rec.dt:.3g} s of record; "
         f"{100 * rec.n_missing / max(rec.values.size, 1):.2g} % of its samples are missing."),
        ("channels", positions_text(rec.positions) + "; measured at "
         + positions_text([x[i] for i in m.nodes], m.nodes)
         + (("; not used: the channels on a support at " + positions_text(
             rec.support_positions) + " (the line does not move there)")
            if getattr(rec, "support_positions", ()) else ""),
         "Each channel feeds the filter at the model node nearest its position."),
        ("filter consistency", verdict + " (windowed NIS)",
         "Without the true field, the innovations tell whether the model explains the record: "
         "an inconsistent filter's error bars are not to be trusted."),
        ("largest estimated amplitude", f"{mm(float(envelope.max()))} at "
         f"{x[int(np.argmax(envelope))]:.4g} m", "Over the second half of the record."),
    ]
    draw = functools.partial(_plotting().plot_envelope, x, {"estimated amplitude": envelope},
                             {"sensors": [float(x[i]) for i in m.nodes]})
    return {"title": "Measured record (the designed filter on it)", "rows": rows,
            "figures": [_figure("measured_envelope", draw,
                                "Amplitude along the span estimated from the measured record "
                                "(largest |y| over its second half), with the sensors.",
                                "where the estimated loops peak")]}


_COMPARISON_WORDS = {
    "no_robot": "no robot on the line",
    "near_clamp": "robot parked near a clamp",
    "start": "robot parked where it started",
    "best": "robot parked at the best position",
    "closed_loop": "robot where the closed loop ended",
}


def _where_it_ended(result, final: float) -> str:
    import numpy as np

    targets = np.asarray(result.target, dtype=float)
    targets = targets[np.isfinite(targets)]
    text = ("The robot steers to the parked position predicted to leave the line vibrating "
            "least, from the sensors' and its own measurements, and undoes a move after which "
            "the sensors measure more vibration.")
    if targets.size:
        text += f" Its last target was {targets[-1]:.4g} m."
    best = getattr(result, "best_position", float("nan"))
    loop = getattr(result, "loop_length", float("nan"))
    if np.isfinite(best) and np.isfinite(loop) and loop > 0:
        text += (f" The best parked position found by a steady-state scan is {best:.4g} m, "
                 f"{abs(final - best) / loop:.2g} loop lengths ({loop:.3g} m) from where it "
                 "ended.")
    if not getattr(result, "settled", True):
        text += (" It had not settled when the run ended, so the numbers are over the last "
                 "second; a longer robot.closed_loop lets it arrive.")
    return text


def _plan_agreement(plan, result, final: float) -> str:
    if plan is None:
        return "no plan stage in this run"
    apart = abs(plan.choice.position - final) / result.loop_length
    verdict = "agree" if apart <= 0.25 else "differ"
    return (f"{verdict}: the plan's target {plan.choice.position:.4g} m, the closed loop ended "
            f"at {final:.4g} m ({apart:.2g} loop lengths apart)"
            + ("" if verdict == "agree" else
               "; the closed loop judged from its own run (see its decisions)"))


def consistency_by_phase(result) -> dict:
    """The closed loop's windowed NIS verdicts, counted in each phase of the run.

    The filter's model is identified with the robot parked at its start, so windows while the
    robot moves (it damps the line differently at every position) are expected to reject; a
    window above its bound while parked at the start says the model does not fit the line, and
    after the robot settled elsewhere, that it does not fit the line the robot changed. A
    window *below* its bound says the opposite: the filter is pessimistic (its
    innovations are smaller than it predicts), which is no sign of a wrong estimate; the two are
    counted apart.

    Parameters
    ----------
    result : ClosedLoopResult
        A closed-loop run.

    Returns
    -------
    dict
        ``{phase: (windows above, windows below, windows tested)}`` for "calibration" (parked at
        the start), "moving" and "settled" (the settled window); empty when no window was
        tested.

    Examples
    --------
    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> test = SimpleNamespace(window=100, window_start=np.arange(10) * 100,
    ...                        tested=np.arange(10) > 0, rejected=np.array([2, 5]),
    ...                        above=np.arange(10) == 5)
    >>> run = SimpleNamespace(estimator_consistency=test, t=np.arange(1000) * 0.01,
    ...                       calibration_time=3.0, settled_window=(7.0, 9.99))
    >>> consistency_by_phase(run)
    {'calibration': (0, 1, 2), 'moving': (1, 0, 4), 'settled': (0, 0, 3)}
    """
    import numpy as np

    test = result.estimator_consistency
    if test is None:
        return {}
    dt = float(result.t[1] - result.t[0])
    ends = dt * (np.asarray(test.window_start) + test.window - 1)   # a window's last sample
    starts = dt * np.asarray(test.window_start)
    tested = np.asarray(test.tested, dtype=bool)
    above = np.asarray(test.above, dtype=bool)
    below = np.zeros(tested.size, bool)
    below[np.asarray(test.rejected, dtype=int)] = True
    below &= ~above
    settle_start = float(result.settled_window[0])
    phases = {"calibration": ends <= result.calibration_time,
              "settled": starts >= max(settle_start, result.calibration_time)}
    phases["moving"] = ~phases["calibration"] & ~phases["settled"]
    return {name: (int(np.sum(above & phases[name])), int(np.sum(below & phases[name])),
                   int(np.sum(tested & phases[name])))
            for name in ("calibration", "moving", "settled")}


def _consistency_text(result, noise_fraction: float) -> str:
    test = result.estimator_consistency
    if test is None:
        return "no complete window"
    updates = "".join(f"; the estimator rebuilt at {when:.3g} s ({_REBUILT[why]})"
                      for when, why in getattr(result, "estimator_updates", ()))
    noiseless = ("; the sensors are noiseless (simulation.noise_fraction = 0): the filter "
                 f"assumes a noise of {NOISE_FLOOR_FRACTION:g} of its record's RMS, and the "
                 "test weighs the model's error against that" if noise_fraction == 0 else "")
    phases = {name: counts for name, counts in consistency_by_phase(result).items() if counts[2]}
    above = ", ".join(f"{name} {n_above} of {n}" for name, (n_above, _, n) in phases.items())
    below = ", ".join(f"{name} {n_below} of {n}" for name, (_, n_below, n) in phases.items())
    import numpy as np

    from ..estimate.consistency import allowed_rejections

    moved_above = sum(phases[name][0] for name in ("moving", "settled") if name in phases)
    parked_above, _, parked = phases.get("calibration", (0, 0, 0))
    moved = float(np.ptp(result.robot_position)) > 0
    # Said only when the model fits while the robot is parked at its start (no more windows
    # above than chance allows there): otherwise it does not fit the line at all.
    # The robot_input model carries the robot wherever it is: it does not explain a misfit.
    robot_in_model = getattr(result, "estimator", "recipe") == "robot_input"
    cause = ("; the model fits while the robot is parked at its start, where it was "
             "identified: the robot damps the line differently elsewhere"
             if moved_above and moved and parked and parked_above <= allowed_rejections(parked)
             and not robot_in_model
             else "")
    return (("consistent" if test.consistent else "INCONSISTENT")
            + f" over the run (windowed NIS); windows above their bound (larger innovations "
            f"than the model predicts): {above}; below it (the filter pessimistic): {below}"
            + cause + updates + noiseless)


#: Why the closed loop's estimator was rebuilt (``ClosedLoopResult.estimator_updates``), in words.
_REBUILT = {"line": "on the calibrated line", "tone": "at the load's new tone"}


def _consistency_note(result) -> str:
    """What the estimator's consistency test says, for the estimator the run used."""
    if getattr(result, "estimator", "recipe") == "robot_input":
        return ("The filter's model is the line the controller believes, with the robot's "
                "measured force as an input wherever it is, and is rebuilt when the belief or "
                "the load's tone moves: windows above their bound say the line or its load "
                "changed in a way the model does not follow (for a while after a wind change, "
                "as expected). The robot's targeting does not use that estimate.")
    return ("The filter's model was identified with the robot parked at its start: windows "
            "above their bound there say the model does not fit the line; after the robot "
            "moved they may also say that it changed the line (it damps it differently at "
            "every position), and are expected while it moves. The robot's targeting does not "
            "use that estimate.")


def _reduction_row(result) -> tuple:
    """How many times less the line vibrates where the robot ended than at its start: in the
    steady state of the self-limiting wind when the run itself was in that wind and was judged
    there (its own window is the amplitude on its way), else the run's own comparison."""
    window = float(result.vibration_reduction)
    if not getattr(result, "steady_verdict", False):
        return ("vibration reduction", f"{window:.2f}x",
                "RMS displacement over the span with the robot parked where it started, "
                "divided by the same with the robot where the closed loop left it (> 1: moving "
                "helps).")
    return ("vibration reduction", f"{result.aeolian_steady.start_reduction:.2f}x",
            "Steady antinode amplitude in the self-limiting wind with the robot parked where "
            "it started, divided by the same where the closed loop left it (> 1: moving "
            f"helps). The RMS rows of the run's own window say {window:.2f}x: the amplitude "
            "on its way, which with the robot settles over minutes, longer than the run.")


def _closed_loop_section(r) -> dict:
    import numpy as np

    cl = r.closed_loop
    result, tuning = cl.result, cl.tuning
    robot = tuning.robot
    final = float(result.robot_position[-1])
    steady = result.comparison("closed_loop").steady
    x = np.asarray(result.x)
    rows = [
        ("robot", f"body {robot.body_mass:g} kg + absorber {robot.suspended_mass:g} kg, "
         f"absorber tuned ({tuning.how}) to mode {tuning.mode} ({tuning.mode_frequency:.4g} Hz), "
         f"the mode nearest the load's {tuning.load_frequency:.4g} Hz, for its antinode at "
         f"{tuning.antinode:.4g} m; starts at {robot.position:g} m",
         f"A tuned absorber takes the most power from the line near its tuning: the load's "
         f"{tuning.load_frequency:.4g} Hz is "
         f"{100 * (tuning.load_frequency / tuning.mode_frequency - 1):+.2g} % from mode "
         f"{tuning.mode}'s {tuning.mode_frequency:.4g} Hz."),
        ("sensors", positions_text([x[i] for i in cl.sensors], cl.sensors) + "; "
         + cl.sensors_how, "The sensors the controller and its estimator read; the robot's own "
         "accelerometer adds where it stands."),
        *calibration_rows(result),
        ("where it ended", f"{final:.4g} m", _where_it_ended(result, final)),
        ("plan and closed loop", _plan_agreement(r.plan, result, final),
         "The plan stage applies the closed loop's own targeting rule to the estimated field; "
         "the closed loop decides from its own sensors while it runs."),
        ("RMS displacement, steady state" if steady else "RMS displacement, settled window",
         f"{mm(result.rms_closed_loop)} parked where it ended vs {mm(result.rms_baseline)} "
         "parked at its start",
         "The exact steady state under the load with the robot parked there." if steady else
         "Over the settled window (the load is not one sine)."),
        _reduction_row(result),
        ("decisions", "; ".join(f"{t:.3g} s: {what}" for t, what in result.decisions)
         or "none", "What the robot decided, and when."),
        ("estimator consistency",
         _consistency_text(result, r.scenario.simulation.noise_fraction),
         _consistency_note(result)),
        ("planner steps", f"{len(result.statuses)} ({result.statuses.count('safe_stop')} "
         "safe stops)", _steps_note(result)),
        ("real-time factor", f"{float(result.real_time_factor):.2f}",
         "Simulated seconds per CPU second of the loop (process time, whatever else the "
         "machine runs): above 1 the loop runs faster than the line moves, as a controller on "
         "the robot must."),
    ]
    window = getattr(result, "settled_window", None)
    if window is not None and window[1] > window[0]:
        rows.insert(3, ("settled window", f"{window[0]:.3g}-{window[1]:.3g} s"
                        + ("" if getattr(result, "settled", True) else
                           " (the robot did not settle: the last second)"),
                        "The window RMS (beside each steady state below) is over this window, "
                        "after the robot last arrived."))
    self_limiting = getattr(result, "wind", "fixed_lift") == "self_limiting"
    if self_limiting:
        rows.insert(1, ("wind", "self-limiting (robot.wind)",
                        "The closed loop's line is driven by the energy balance's physics: the "
                        "wind's power at the locked mode's current amplitude and the "
                        "conductor's self-damping (the severity section's curve and law), "
                        "starting at the balance's amplitude; the records of the stages above "
                        "are the fixed lift's."))
    for comparison in getattr(result, "comparisons", ()):
        if not np.isfinite(comparison.rms):
            continue   # no steady-state scan under this load: no best position to compare
        label = _COMPARISON_WORDS.get(comparison.name, comparison.name)
        where = "" if not np.isfinite(comparison.position) else \
            f" at {comparison.position:.4g} m"
        note = f"peak {mm(comparison.peak)}"
        if self_limiting:   # the amplitude the energy balance and severity speak of
            note += f"; antinode amplitude {mm(comparison.amplitude)}"
        if comparison.steady:
            note += (f"; settled window {mm(comparison.window_rms)}"
                     + (" (still ringing)" if comparison.transient else ""))
        rows.append((f"RMS: {label}", f"{mm(comparison.rms)}{where}", note))
    if getattr(result, "aeolian_steady", None) is not None:
        rows.append(_closed_loop_wind(r, result))
    elif r.severity is not None:
        rows.append(_not_the_wind(r))
    figures = [
        _figure("closed_loop", functools.partial(_plotting().plot_closed_loop, result),
                "The closed loop against time: the robot's position and its target, and the "
                "RMS displacement over the span, robot moving against parked.",
                "the moving curve falling below the parked one once the robot arrives"),
        _figure("closed_loop_path", functools.partial(_closed_loop_path, result),
                "The robot's path in the closed loop over the line's vibration envelope (an "
                "inset zooms on the path when it is short against the span).",
                "the path settling where the envelope is largest near it, and staying there"),
    ]
    return {"title": "Closed loop (robot seeking the best parked position)", "rows": rows,
            "figures": figures}


def _closed_loop_wind(r, result) -> tuple:
    """The closed loop's row in the self-limiting wind, beside the severity section's check
    (on the nominal span, ``r.span``: the severity study changes its conductor's data, never its
    tension)."""
    from .summary_severity import closed_loop_wind_row

    runs = None if r.severity is None else r.severity.time_domain
    return closed_loop_wind_row(result.aeolian_steady, result.span, runs, r.span,
                                getattr(result, "wind", "fixed_lift"))


def _not_the_wind(r) -> tuple:
    """Why the closed loop's reduction is not the severity section's, when the closed loop was
    not judged in the self-limiting wind."""
    return ("against the severity section", "not comparable: " + r.closed_loop.unjudged,
            "The closed loop's RMS rows are under the scenario's own load on the line's modal "
            "damping; the severity section's amplitudes are where the wind's power balances the "
            "conductor's self-damping at each wind speed, with the robot at the antinode. With "
            "aeolian forcing and the time-domain check on, the closed loop's final position is "
            "judged in that self-limiting wind as well.")


def _steps_note(result) -> str:
    """How often the motion planner ran, and what a safe stop is, from the run."""
    steps = len(result.statuses)
    if not steps:
        return "The loop took no control step."
    every = (float(result.t[-1]) - result.calibration_time) / steps
    return (f"One motion decision every {every:.3g} s after the calibration; a safe stop is a "
            "step whose plan failed or ran out of time, so the robot braked at a_max.")


def _closed_loop_path(result):
    return _plotting().plot_closed_loop_path(result)


def _failure_section(r) -> dict:
    f = r.failure
    return {"title": f"Stage failed: {f.stage}",
            "rows": [("error", f"{f.kind}: {f.message}",
                      "The stages above finished; their results are kept. The stages after "
                      "this one did not run.")]}


#: Each section's id in the report (its link target), by the stage it shows: the summary at the
#: top of the report links to these.
SECTION_IDS = {"model": "span", "records": "data", "identification": "identification",
               "sensors": "sensor-placement", "layouts": "estimation",
               "measured": "measured-record", "plan": "plan", "closed_loop": "closed-loop",
               "severity": "severity", "fatigue": "fatigue", "failure": "failure"}


def result_sections(result) -> list:
    """The report's sections of a :class:`ScenarioResult`, in the order the stages ran.

    Parameters
    ----------
    result : ScenarioResult
        The result.

    Returns
    -------
    list of dict
        Each with "title", "id" (:data:`SECTION_IDS`), "rows" ((label, value, explanation)
        tuples), optionally "intro", "notes" and "figures" (mappings with "name", "draw",
        "purpose", "look_for").

    Examples
    --------
    >>> from powerline_control.scenario.pipeline import run_scenario
    >>> [s["title"] for s in result_sections(run_scenario(stages=("model",)))]
    ['Span and model']
    """
    from .summary_plan import plan_section
    from .summary_sensors import sensors_section
    from .summary_severity import fatigue_section, severity_section

    builders = [("model", _model_section), ("records", _records_section),
                ("identification", _identification_section),
                ("identification", sensors_section), ("layouts", _estimation_section),
                ("measured", _measured_section),
                ("plan", plan_section), ("closed_loop", _closed_loop_section),
                ("severity", severity_section), ("fatigue", fatigue_section)]
    sections = []
    for attribute, build in builders:
        if getattr(result, attribute, None) is not None:
            if build is sensors_section and "sensors" not in result.stages \
                    and not result.identification.sensors_given:
                continue
            key = "sensors" if build is sensors_section else attribute
            sections.append({**build(result), "id": SECTION_IDS[key]})
    if result.failure is not None:
        sections.append({**_failure_section(result), "id": SECTION_IDS["failure"]})
    return sections


# ----------------------------------------------------------------------------- the report

def draw_sections(sections: list) -> list:
    """Draw each section's figures and caption them from what they draw.

    Parameters
    ----------
    sections : list of dict
        As :func:`result_sections` returns.

    Returns
    -------
    list of dict
        The same sections, each figure with "figure" (matplotlib) and "caption".

    Examples
    --------
    >>> draw_sections([{"title": "T", "rows": []}])[0]["figures"]
    []
    """
    from ..output.captions import figure_caption

    out = []
    for section in sections:
        figures = []
        for spec in section.get("figures", ()):
            fig = spec["draw"]()
            figures.append({"name": spec["name"], "figure": fig,
                            "caption": figure_caption(fig, spec["purpose"], spec["look_for"])})
        out.append({**section, "figures": figures})
    return out


def write_result_report(result, path: Path, *, version: str | None = None) -> Path:
    """Write the HTML report of a :class:`ScenarioResult` (one self-contained file): its
    verdict first (:meth:`ScenarioResult.verdict`), then a section per stage.

    Parameters
    ----------
    result : ScenarioResult
        The result.
    path : Path
        The HTML file.
    version : str or None
        Package version shown (default: this package's).

    Returns
    -------
    Path

    Examples
    --------
    See :meth:`ScenarioResult.report`.
    """
    from .. import __version__
    from ..output.report import write_report
    sections = draw_sections(result_sections(result))
    scenario = result.scenario
    return write_report(path, f"powerline_control: {scenario.name}", sections,
                        __version__ if version is None else version,
                        scenario_name=scenario.name,
                        scenario_description=scenario.scenario.description,
                        summary=result.verdict().to_report())
