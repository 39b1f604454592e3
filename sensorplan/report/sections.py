"""The sections of the report, one function each: the bridge and load model, the informativeness of the
candidates, the layout and its certificate, what it detects, its verification, the EI identified from
measured data and the sim-to-real gap.  Each returns (title, HTML).
"""

import html
from dataclasses import replace

import numpy as np

from .page import figure_html, fmt, table_html

__all__ = ["model_section", "informativeness_section", "design_section", "detectability_section",
           "verification_section", "identification_section", "gap_section"]


def model_section(case):
    """The bridge, its supports, the vehicle, the sensors and their influence lines."""
    from .. import plotting

    b = case.bridge
    rows = [(f"support {i}", f"{x:g}", "rigid" if np.isinf(kv) else f"{kv:.3g}",
             "pin" if kr == 0 else ("clamped" if np.isinf(kr) else f"{kr:.3g}"))
            for i, (x, kv, kr) in enumerate(zip(b.support_positions, b.vertical_springs, b.rotational_springs))]
    spans = table_html(["span", "length [m]", "EI [N m^2]"],
                       [(f"span {i + 1}", f"{s:g}", f"{np.median(case.ei[b.span_of(case.mesh.midpoints) == i]):.3g}")
                        for i, s in enumerate(b.spans)])
    supports = table_html(["support", "x [m]", "vertical spring [N/m]", "rotational spring [N m/rad]"], rows)
    veh = table_html(["axle", "offset behind front [m]", "load [kN]"],
                     [(f"axle {i + 1}", f"{d:g}", f"{p / 1e3:.4g}") for i, (d, p) in
                      enumerate(zip(case.vehicle.axle_offsets, case.vehicle.axle_loads))])
    noise = case.noise
    sens = table_html(["sensor", "x [m]", "kind", "noise std"],
                      [(n, f"{x:g}", k, f"{s * 1e6:.3g} µrad" if k == "rotation" else f"{s * 1e3:.3g} mm")
                       for n, x, k, s in zip(case.sensors.names, case.sensors.positions, case.sensors.kinds,
                                             noise.std)])
    lines = case.influence_lines()
    fig = figure_html(plotting.plot_influence_lines(lines, supports=b.support_positions),
                      "Predicted influence lines of the configured sensors",
                      "each curve is what one sensor reads as the front axle moves across the bridge at nominal EI; "
                      "a tiltmeter reads positive when the deck dips to its right.")
    text = (f"<p>{b.n_spans} span(s), total length {b.length:g} m; EI mesh of {case.n_elements} elements; "
            f"load sweep of {case.sweep.n_loads} reference-axle positions from {case.sweep.positions[0]:g} to "
            f"{case.sweep.positions[-1]:g} m; {_noise_text(noise)}.</p>")
    return "Bridge and load model", text + spans + supports + veh + sens + fig


def _noise_text(noise):
    """One phrase on the noise's correlation: in time (with its speed) or along the load position."""
    if not noise.in_time:
        return f"noise correlation length {noise.correlation_length:g} m (0 = independent)"
    return (f"noise in time: white + a correlated part of {1e6 * float(np.median(noise.correlated_std)):.3g} "
            f"(median, urad or um) over {float(np.median(noise.correlation_time_s)):.3g} s + wander of "
            f"{1e6 * float(np.median(noise.random_walk)):.3g} per sqrt(s), at a crossing speed of {noise.speed:g} m/s")


def informativeness_section(analysis):
    """The informativeness curves of the candidate positions and where each is most informative."""
    from .. import plotting

    case, blocks = analysis.case, analysis.candidates
    with np.errstate(divide="ignore"):
        std_pct = 100.0 / (case.ei[None, :] * np.sqrt(blocks.curves))  # EI parameters -> % std of EI
    peaks = table_html(["candidate x [m]", "most informative about [m]", "EI std it alone leaves there [%]"],
                       [(f"{x:g}", f"{p:.2f}", f"{v:.3g}") for x, p, v in
                        zip(blocks.sensors.positions, blocks.peaks(), std_pct.min(axis=1))])
    return ("Informativeness of candidate positions", figure_html(
        plotting.plot_informativeness(blocks, supports=case.bridge.support_positions, ei=case.ei),
        f"Informativeness of candidate {blocks.sensors.kinds[0]} sensor positions",
        "each curve is the EI standard deviation (in %) that one sensor alone would leave on each element if "
        "the rest of the bridge were known (the Cramér-Rao bound of its Fisher information): the lower a "
        "sensor's curve over an element, the better it pins down EI there.") + peaks)


def design_section(analysis):
    """The recommended layout with its certificate, the baselines and the design figures."""
    from .. import plotting

    design = analysis.design
    cert = table_html(["quantity", "value"], [
        ("positions [m]", ", ".join(f"{x:.2f}" for x in design.layout_m)),
        (f"{design.criterion} criterion of the layout", fmt(design.value, 6)),
        ("relaxation bound (no layout can do better)", fmt(design.bound, 6)),
        ("gap", fmt(design.value - design.bound, 3)),
        ("certified efficiency (a lower bound)", f"{100 * design.efficiency:.2f} %"),
        ("method", design.method)])
    base_rows = [(b.name, "infeasible" if not b.feasible else fmt(b.value, 6),
                  "" if not b.feasible else ", ".join(f"{x:.2f}" for x in b.layout_m))
                 for b in design.baselines]
    figs = (figure_html(plotting.plot_layout(design, exclude=analysis.exclude), "Recommended layout",
                        "red markers are the recommended sensors; blue bars show how strongly the convex relaxation "
                        "wanted each candidate position; hatched zones are excluded.")
            + figure_html(plotting.plot_posterior_std(design), "Posterior uncertainty of EI along the bridge",
                          "lower is better: the red line is the uncertainty left with the recommended layout, "
                          "the dashed line with the best baseline.")
            + (figure_html(plotting.plot_criterion_curve(design), "Criterion versus number of sensors",
                           "where the curve flattens, another sensor stops paying; the gap to the bound shows how "
                           "close each layout is to the best possible.") if design.curve else ""))
    return ("Recommended layout and certificate",
            cert + "<h3>Baselines</h3>" + table_html(["baseline", "criterion", "positions [m]"], base_rows) + figs)


def detectability_section(det):
    """The detection power and the minimum detectable loss of the installed layout along the bridge."""
    from .. import plotting

    return ("What the layout will detect", figure_html(
        plotting.plot_detectability(det)[0], "Detectability of a local EI loss along the bridge",
        "top: probability of detecting the loss at each zone centre (at least 0.9 is well covered, below 0.5 "
        "a blind spot); bottom: the smallest loss detected with 90 % probability there."))


def verification_section(analysis):
    """The verification table of every verified layout, their ranking and the detection figure."""
    from .. import plotting

    verification, names = analysis.verification, analysis.verified_names
    vrows = []
    for name, score in zip(names, verification.layouts):
        m = score.metrics
        vrows.append((name, m["rmse"].text(), m["localisation_error_m"].text(empty="no detections"),
                      m["detection_rate"].text(), m["false_alarm_rate"].text(), m["coverage95"].text(),
                      m["band_width"].text()))
    caveats = verification.false_alarm_caveats()
    axes = plotting.plot_verification(verification, supports=analysis.case.bridge.support_positions)
    return ("Verification by inversion of synthetic damage",
            f"<p>{html.escape(verification.summary().splitlines()[0])}</p>"
            + table_html(["layout", "relative RMSE", "localisation error [m]", "detection rate",
                          "false-alarm rate", "95 % coverage", "band width"], vrows)
            + '<p class="note">Detection and false-alarm rates: the share of the scenarios, with the count and '
              "its Wilson 95 % interval; other columns: mean ± Monte-Carlo standard error over the scenarios.</p>"
            + "".join(f'<p class="note warn">Caveat: {html.escape(c)}.</p>' for c in caveats)
            + _ranking(verification, analysis.design, names)
            + figure_html(axes[0], "Detection and localisation per damage location",
                          "each line is one layout: higher detection probability and lower localisation "
                          "error mean the layout finds a loss at that location."))


def identification_section(analysis):
    """The EI identified from the measured data: the posterior, the fit of every sensor, the table."""
    from .. import plotting

    case, posterior = analysis.case, analysis.posterior
    kinds = dict(zip(case.sensors.names, case.sensors.kinds))
    fit_figs = "".join(figure_html(plotting.plot_fit(posterior, name, kind=kinds.get(name)),
                                   f"Data and model for {name}", "grey dots are the measurements; the orange band "
                                   "is where the model expects 95 % of them.") for name in posterior.sensor_names)
    ci = posterior.credible_interval(0.95)
    how_tau = ("mode of its hyper-posterior, integrated out" if posterior.mixture.n_components > 1
               else f"point estimate by {posterior.hyper_method}")
    erows = [(f"{a:.2f}-{b:.2f}", f"{m:.4g}", f"{lo:.4g}", f"{hi:.4g}", f"{n:.4g}") for a, b, m, lo, hi, n in
             zip(posterior.edges[:-1], posterior.edges[1:], posterior.ei_mean, ci[:, 0], ci[:, 1],
                 posterior.ei_nominal)]
    return ("Identified EI with credible bands",
            f"<p>Converged: {posterior.converged}; noise scale {posterior.noise_scale:.3f} of the "
            f"configured noise; prior smoothness tau {posterior.tau:.3g} ({how_tau}); "
            f"excluded crossings: {', '.join(posterior.excluded_crossings) or 'none'}."
            "</p>" + "".join(f'<p class="note">Warning: {html.escape(w)}</p>' for w in posterior.warnings)
            + figure_html(plotting.plot_ei_posterior(posterior, supports=case.bridge.support_positions),
                          "Identified flexural rigidity",
                          "the line is the posterior mean; dark and light bands hold the true EI "
                          "with 75 % and 95 % probability; wide bands mark what the data cannot "
                          "resolve.")
            + fit_figs + table_html(["element [m]", "EI mean", "95 % low", "95 % high", "nominal"], erows))


def gap_section(analysis):
    """The sim-to-real gap diagnosis of the measured data: verdict, effects and figures."""
    from .. import plotting

    diagnosis, supports = analysis.diagnosis, analysis.case.bridge.support_positions
    drows = [(e.name, f"{e.log_bayes_factor:.2f}",
              "n/a" if e.heldout_score_gain is None else f"{e.heldout_score_gain:.2f}",
              fmt(e.rms_after, 3), fmt(e.heldout_rms_after, 3), f"{100 * e.max_ei_shift:.1f} %")
             for e in diagnosis.effects]
    g = diagnosis.gap
    return ("Sim-to-real gap diagnosis",
            f'<p class="verdict">Verdict ({diagnosis.verdict.status}): {html.escape(diagnosis.verdict.summary)} '
            f"Diagnosis: {html.escape(diagnosis.statement)}</p>"
            f"<p>Residual rms {g.rms_residual:.3g}, systematic part {g.systematic_rms:.3g}, "
            f"noise {g.noise_rms:.3g} (p = {g.p_value:.2g}).</p>"
            + table_html(["effect", "log Bayes factor", "held-out gain", "rms after", "held-out rms",
                          "max EI shift"], drows)
            + figure_html(plotting.plot_residual_map(diagnosis), "Where the model and the data disagree",
                          "red and blue stripes are load positions where a sensor reads systematically "
                          "above or below the model, in noise standard deviations.")
            + figure_html(plotting.plot_shrinkage(diagnosis), "How far the gap shrinks",
                          "bars well below the dashed line and close to the dotted noise floor identify "
                          "an effect that explains the gap.")
            + figure_html(plotting.plot_ei_before_after(diagnosis, supports=supports),
                          "EI before and after modelling the gap",
                          "the difference between the lines is the bias the unmodelled effect was "
                          "causing in the identified EI."))


def _ranking(verification, design, names):
    """The layouts ranked by verification, and a plain note when a baseline verifies better."""
    from ..verification.ranking import rank_layouts

    if "recommended" not in names:
        return ""
    values = {"recommended": design.value} | {b.name: b.value for b in design.baselines}
    ranking = rank_layouts(replace(verification, names=tuple(names)), criterion=design.criterion, values=values)
    rows = [(str(e.rank), e.name, e.detection_text(), fmt(e.detection_limit, 3),
             fmt(e.localisation_error_m, 2), fmt(e.coverage95, 3), fmt(e.criterion, 6)) for e in ranking.entries]
    return ("<h3>Ranking by verification</h3>"
            + table_html(["rank", "layout", "detection rate", "detection limit", "localisation error [m]",
                          "95 % coverage", f"{design.criterion} criterion"], rows)
            + f'<p class="verdict">{html.escape(_ranking_note(ranking, design.criterion))}</p>')


def _ranking_note(ranking, criterion):
    """One note on the ranking: which layouts verify better than the recommended one, and on what."""
    above = [e for e in ranking.entries if e.name in ranking.verifies_better]
    if not above:
        return f"The {criterion}-optimal layout verifies best."
    clear = [e for e in above if e.better_on]
    if not clear:
        return (f"{len(above)} layout(s) rank above the {criterion}-optimal one only on ties broken in their favour "
                f"({', '.join(e.name for e in above)}): the verification cannot tell them apart.")
    named = "; ".join(f"{e.name} (better on {', '.join(e.better_on)})" for e in clear)
    ties = [e.name for e in above if not e.better_on]
    tied = f" {', '.join(ties)} rank above it only on ties broken in their favour." if ties else ""
    return (f"{len(clear)} layout(s) verify better than the {criterion}-optimal one beyond their Monte-Carlo "
            f"error: {named}.{tied} The design criterion and the verification measure different things; for "
            f"detection, prefer `--criterion detect` or `--target-power`.")
