"""Self-contained HTML report: model, informativeness, layout, verification, identification, gap.

Figures are embedded as base64 PNG, styles inline, no network needed to
view the file.  Every figure carries a one-sentence reading guide.
"""

import base64
import hashlib
import html
import io
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

__all__ = ["build_report", "render_report", "Report", "provenance"]

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:980px;margin:2em auto;
color:#1d1d1f;line-height:1.45;padding:0 1em}
h1{font-size:1.7em;margin-bottom:.2em}h2{border-bottom:2px solid #ddd;padding-bottom:.2em;margin-top:1.8em}
table{border-collapse:collapse;margin:.6em 0 1em;font-size:.92em}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}th{background:#f3f3f3}
td.l,th.l{text-align:left}figure{margin:1em 0}figure img{max-width:100%;border:1px solid #eee}
figcaption{font-size:.9em;color:#444}figcaption b{color:#1d1d1f}.note{color:#555;font-size:.9em}
.verdict{background:#f6f8ff;border-left:4px solid #4a6cf7;padding:.5em .8em}
.conclusion{background:#f4faf4;border-left:4px solid #2e8b57;padding:.6em .9em;font-size:1.02em}
.warn{color:#a33}
@media print{body{max-width:none;margin:0;padding:0;font-size:10pt;color:#000}nav{display:none}
h2{page-break-after:avoid;break-after:avoid}figure,table{page-break-inside:avoid;break-inside:avoid}
section{page-break-before:auto}figure img{max-width:100%;border:none}a{color:#000;text-decoration:none}
.conclusion,.verdict{background:none}}
"""

_SCRIPT = """window.addEventListener('load',function(){var im=document.images,ok=0;
for(var i=0;i<im.length;i++){if(im[i].complete&&im[i].naturalWidth>0){ok++;}}
document.body.setAttribute('data-images-loaded',ok+'/'+im.length);});"""


@dataclass(frozen=True, eq=False)
class Report:
    """The HTML text and the results it was built from."""

    html: str
    sections: tuple
    design: object = None
    verification: object = None
    posterior: object = None
    diagnosis: object = None
    figures: tuple = field(default_factory=tuple)


def _png(ax_or_fig):
    fig = getattr(ax_or_fig, "figure", ax_or_fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _figure(ax, title, guide):
    return (f'<figure><img alt="{html.escape(title)}" src="data:image/png;base64,{_png(ax)}">'
            f"<figcaption><b>{html.escape(title)}.</b> Reading guide: {html.escape(guide)}</figcaption></figure>")


def _table(header, rows, left=1):
    head = "".join(f'<th class="{"l" if i < left else ""}">{html.escape(str(h))}</th>' for i, h in enumerate(header))
    body = "".join("<tr>" + "".join(f'<td class="{"l" if i < left else ""}">{html.escape(str(c))}</td>'
                                    for i, c in enumerate(row)) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _fmt(x, digits=4):
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "n/a"
    return f"{x:.{digits}g}"


def _positions(xs):
    return ", ".join(f"{x:.2f}" for x in xs)


def _stretches(stretches):
    return "; ".join(f"{a:.1f}-{b:.1f} m" if b > a else f"{a:.1f} m" for a, b in stretches) or "nowhere"


def better_baselines(analysis):
    """Baselines that verified better than the recommended layout, with the reason.

    Better: a higher detection rate of the local losses, or the same detection
    rate (within two combined Monte-Carlo standard errors) and a lower
    relative RMSE; both beyond two combined standard errors.
    """
    scores = dict(zip(analysis.verified_names, analysis.verification.layouts))
    rec = scores["recommended"].metrics
    out = []
    for name, score in scores.items():
        if name == "recommended":
            continue
        m = score.metrics
        err = {k: 2.0 * float(np.hypot(m[k].se, rec[k].se)) for k in ("detection_rate", "rmse")}
        if m["detection_rate"].mean > rec["detection_rate"].mean + err["detection_rate"]:
            out.append((name, f"detection {m['detection_rate'].mean:.2f} against {rec['detection_rate'].mean:.2f}"))
        elif (abs(m["detection_rate"].mean - rec["detection_rate"].mean) <= err["detection_rate"]
              and m["rmse"].mean < rec["rmse"].mean - err["rmse"]):
            out.append((name, f"relative EI error {m['rmse'].mean:.3f} against {rec['rmse'].mean:.3f} at the "
                              "same detection rate"))
    return out


def _conclusion(analysis):
    """One paragraph: what to install, what it detects, how it verified, the caveats."""
    d, v = analysis.design, analysis.verification
    rec = dict(zip(analysis.verified_names, v.layouts))["recommended"]
    m = rec.metrics
    text = (f"Install {d.count} {d.kind} sensor(s) at x = {_positions(d.layout_m)} m "
            f"({d.criterion}-optimal layout, certified efficiency at least {100 * d.efficiency:.1f} % of the best "
            "possible")
    text += f"; existing sensors at {_positions(d.fixed_m)} m" if d.fixed_m else ""
    text += (f"; no sensor in the excluded zones {_stretches(analysis.exclude)}" if analysis.exclude else "") + "). "
    det = analysis.detectability
    if det is not None:
        loss = det.min_detectable_loss_array
        finite = loss[np.isfinite(loss)]
        where = (f"for zone centres in {_stretches(det.covered)}" if det.covered
                 else "at no zone centre of the bridge")
        text += (f"With {det.n_crossings} crossing(s) it detects a {100 * det.severity:g} % EI loss over "
                 f"{det.length_m:g} m with at least 90 % probability {where} (false-alarm rate "
                 f"{100 * det.false_alarm_rate:g} %); blind spots (probability below 50 %): "
                 f"{_stretches(det.blind_spots)}")
        text += (f"; the smallest loss it detects with 90 % probability is {100 * finite.min():.0f} % "
                 f"(median over the bridge {100 * np.median(finite):.0f} %). " if finite.size else ". ")
    text += (f"In the verification by inversion of synthetic damage ({v.n_crossings} crossings per scenario) it "
             f"detected {m['detection_rate'].mean:.2f} ± {m['detection_rate'].se:.2f} of the "
             f"{100 * v.severity:.0f} % losses over {v.length:g} m at a false-alarm rate of "
             f"{m['false_alarm_rate'].mean:.2f}, and its 95 % credible bands covered the true EI at "
             f"{m['coverage95'].mean:.2f} ± {m['coverage95'].se:.2f} of the elements. ")
    better = better_baselines(analysis)
    if better:
        text += ('<b class="warn">A baseline verified better than the recommended layout: ' + "; ".join(
            f"{html.escape(n)} ({html.escape(r)})" for n, r in better) + "; consider installing it instead "
            "(the design criterion and the verification measure different things).</b> ")
    caveats = []
    if not m["detection_rate"].mean >= 0.5:
        caveats.append(f"this layout is unlikely to detect a local {100 * v.severity:.0f} % loss over {v.length:g} m "
                       "(verified detection below 0.5): more sensors or crossings are needed for that")
    if m["coverage95"].mean < 0.9:
        caveats.append("the credible bands are too narrow (coverage below 0.90)")
    if d.efficiency < 0.95:
        caveats.append(f"the layout is certified only to {100 * d.efficiency:.0f} % of the best possible")
    caveats.append(f"the verification uses {len(rec.records)} synthetic scenarios of the configured model "
                   "(supports, vehicle, noise); a model the bridge does not follow makes every number optimistic")
    if analysis.diagnosis is not None:
        caveats.append(f"gap diagnosis of the measured data: {analysis.diagnosis.verdict}")
    return text + "Caveats: " + "; ".join(html.escape(c) for c in caveats) + "."


def provenance(options, inputs, command_line, *, example=None):
    """What a report was made from: version, date, command line, options, SHA-256 of the input files."""
    from . import __version__

    hashes = {name: {"path": str(path), "sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest()}
              for name, path in inputs.items()}
    if example:
        from importlib import resources

        text = resources.files("sensorplan.examples").joinpath(f"{example}.toml").read_bytes()
        hashes["config"] = {"path": f"example {example}", "sha256": hashlib.sha256(text).hexdigest()}
    return {"sensorplan_version": __version__, "date": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "command_line": " ".join(command_line), "options": options, "inputs": hashes}


def _provenance_section(record):
    rows = [("sensorplan version", record["sensorplan_version"]), ("date (UTC)", record["date"]),
            ("command line", record["command_line"])]
    rows += [(f"{name}: {entry['path']}", f"sha256 {entry['sha256']}") for name, entry in record["inputs"].items()]
    opts = _table(["option", "value"], [(k, "" if v is None else str(v)) for k, v in record["options"].items()])
    return ("Provenance", _table(["item", "value"], rows) + "<h3>All options</h3>" + opts
            + '<p class="note">design.json beside this report holds the inputs of the design; '
              "<code>sensorplan</code> with its <code>recommend_argv</code> reproduces the layout.</p>")


def _model_section(case):
    from . import plotting

    b = case.bridge
    rows = [(f"support {i}", f"{x:g}", "rigid" if np.isinf(kv) else f"{kv:.3g}",
             "pin" if kr == 0 else ("clamped" if np.isinf(kr) else f"{kr:.3g}"))
            for i, (x, kv, kr) in enumerate(zip(b.support_positions, b.vertical_springs, b.rotational_springs))]
    spans = _table(["span", "length [m]", "EI [N m^2]"],
                   [(f"span {i + 1}", f"{s:g}", f"{np.median(case.ei[b.span_of(case.mesh.midpoints) == i]):.3g}")
                    for i, s in enumerate(b.spans)])
    supports = _table(["support", "x [m]", "vertical spring [N/m]", "rotational spring [N m/rad]"], rows)
    veh = _table(["axle", "offset behind front [m]", "load [kN]"],
                 [(f"axle {i + 1}", f"{d:g}", f"{p / 1e3:.4g}") for i, (d, p) in
                  enumerate(zip(case.vehicle.axle_offsets, case.vehicle.axle_loads))])
    noise = case.noise
    sens = _table(["sensor", "x [m]", "kind", "noise std"],
                  [(n, f"{x:g}", k, f"{s * 1e6:.3g} µrad" if k == "rotation" else f"{s * 1e3:.3g} mm")
                   for n, x, k, s in zip(case.sensors.names, case.sensors.positions, case.sensors.kinds, noise.std)])
    lines = case.influence_lines()
    fig = _figure(plotting.plot_influence_lines(lines, supports=b.support_positions),
                  "Predicted influence lines of the configured sensors",
                  "each curve is what one sensor reads as the front axle moves across the bridge at nominal EI; "
                  "a tiltmeter reads positive when the deck dips to its right.")
    text = (f"<p>{b.n_spans} span(s), total length {b.length:g} m; EI mesh of {case.n_elements} elements; "
            f"load sweep of {case.sweep.n_loads} reference-axle positions from {case.sweep.positions[0]:g} to "
            f"{case.sweep.positions[-1]:g} m; noise correlation length {noise.correlation_length:g} m "
            f"(0 = independent).</p>")
    return "Bridge and load model", text + spans + supports + veh + sens + fig


def build_report(case, **options):
    """:func:`render_report` of :func:`sensorplan.analysis.analyse` (``options`` go to ``analyse``)."""
    from .analysis import analyse

    return render_report(analyse(case, **options))


def render_report(analysis, *, provenance=None):
    """Render an :class:`~sensorplan.analysis.Analysis` as one self-contained HTML page.

    ``provenance`` (from :func:`provenance`) adds the provenance section.
    """
    from . import plotting

    case, design, verification = analysis.case, analysis.design, analysis.verification
    supports = case.bridge.support_positions
    sections = [("Conclusion", f'<p class="conclusion">{_conclusion(analysis)}</p>'), _model_section(case)]
    blocks = analysis.candidates
    with np.errstate(divide="ignore"):
        std_pct = 100.0 / (case.ei[None, :] * np.sqrt(blocks.curves))  # EI parameters -> % std of EI
    peaks = _table(["candidate x [m]", "most informative about [m]", "EI std it alone leaves there [%]"],
                   [(f"{x:g}", f"{p:.2f}", f"{v:.3g}") for x, p, v in
                    zip(blocks.sensors.positions, blocks.peaks(), std_pct.min(axis=1))])
    sections.append(("Informativeness of candidate positions", _figure(
        plotting.plot_informativeness(blocks, supports=supports, ei=case.ei),
        f"Informativeness of candidate {blocks.sensors.kinds[0]} sensor positions",
        "each curve is the EI standard deviation (in %) that one sensor alone would leave on each element if "
        "the rest of the bridge were known (the Cramér-Rao bound of its Fisher information): the lower a "
        "sensor's curve over an element, the better it pins down EI there.") + peaks))

    cert = _table(["quantity", "value"], [
        ("positions [m]", ", ".join(f"{x:.2f}" for x in design.layout_m)),
        (f"{design.criterion} criterion of the layout", _fmt(design.value, 6)),
        ("relaxation bound (no layout can do better)", _fmt(design.bound, 6)),
        ("gap", _fmt(design.value - design.bound, 3)),
        ("certified efficiency (a lower bound)", f"{100 * design.efficiency:.2f} %"),
        ("method", design.method)])
    base_rows = [(b.name, "infeasible" if not b.feasible else _fmt(b.value, 6),
                  "" if not b.feasible else ", ".join(f"{x:.2f}" for x in b.layout_m))
                 for b in design.baselines]
    figs = (_figure(plotting.plot_layout(design, exclude=analysis.exclude), "Recommended layout",
                    "red markers are the recommended sensors; blue bars show how strongly the convex relaxation "
                    "wanted each candidate position; hatched zones are excluded.")
            + _figure(plotting.plot_posterior_std(design), "Posterior uncertainty of EI along the bridge",
                      "lower is better: the red line is the uncertainty left with the recommended layout, "
                      "the dashed line with the best baseline.")
            + (_figure(plotting.plot_criterion_curve(design), "Criterion versus number of sensors",
                       "where the curve flattens, another sensor stops paying; the gap to the bound shows how "
                       "close each layout is to the best possible.") if design.curve else ""))
    sections.append(("Recommended layout and certificate",
                     cert + "<h3>Baselines</h3>" + _table(["baseline", "criterion", "positions [m]"], base_rows)
                     + figs))

    det = analysis.detectability
    if det is not None:
        sections.append(("What the layout will detect", _figure(
            plotting.plot_detectability(det)[0], "Detectability of a local EI loss along the bridge",
            "top: probability of detecting the loss at each zone centre (at least 0.9 is well covered, below 0.5 "
            "a blind spot); bottom: the smallest loss detected with 90 % probability there.")))
    names = analysis.verified_names
    vrows = []
    for name, score in zip(names, verification.layouts):
        m = score.metrics
        vrows.append((name, *(f"{m[k].mean:.3f} ± {m[k].se:.3f}" for k in
                              ("rmse", "localisation_error_m", "detection_rate", "false_alarm_rate",
                               "coverage95", "band_width"))))
    axes = plotting.plot_verification(verification, supports=supports)
    sections.append(("Verification by inversion of synthetic damage",
                     f"<p>{html.escape(verification.summary().splitlines()[0])}</p>"
                     + _table(["layout", "relative RMSE", "localisation error [m]", "detection rate",
                               "false-alarm rate", "95 % coverage", "band width"], vrows)
                     + '<p class="note">mean ± Monte-Carlo standard error.</p>'
                     + _ranking(verification, design, names)
                     + _figure(axes[0], "Detection and localisation per damage location",
                               "each line is one layout: higher detection probability and lower localisation "
                               "error mean the layout finds a loss at that location.")))

    posterior, diagnosis = analysis.posterior, analysis.diagnosis
    if posterior is not None:
        kinds = dict(zip(case.sensors.names, case.sensors.kinds))
        fit_figs = "".join(_figure(plotting.plot_fit(posterior, name, kind=kinds.get(name)), f"Data and model for {name}",
                                   "grey dots are the measurements; the orange band is where the model "
                                   "expects 95 % of them.") for name in posterior.sensor_names)
        ci = posterior.credible_interval(0.95)
        how_tau = ("mode of its hyper-posterior, integrated out" if posterior.mixture.n_components > 1
                   else f"point estimate by {posterior.hyper_method}")
        erows = [(f"{a:.2f}-{b:.2f}", f"{m:.4g}", f"{lo:.4g}", f"{hi:.4g}", f"{n:.4g}") for a, b, m, lo, hi, n in
                 zip(posterior.edges[:-1], posterior.edges[1:], posterior.ei_mean, ci[:, 0], ci[:, 1],
                     posterior.ei_nominal)]
        sections.append(("Identified EI with credible bands",
                         f"<p>Converged: {posterior.converged}; noise scale {posterior.noise_scale:.3f} of the "
                         f"configured noise; prior smoothness tau {posterior.tau:.3g} ({how_tau}); "
                         f"excluded crossings: {', '.join(posterior.excluded_crossings) or 'none'}."
                         "</p>" + "".join(f'<p class="note">Warning: {html.escape(w)}</p>' for w in posterior.warnings)
                         + _figure(plotting.plot_ei_posterior(posterior, supports=supports),
                                         "Identified flexural rigidity",
                                         "the line is the posterior mean; dark and light bands hold the true EI "
                                         "with 75 % and 95 % probability; wide bands mark what the data cannot "
                                         "resolve.")
                         + fit_figs + _table(["element [m]", "EI mean", "95 % low", "95 % high", "nominal"], erows)))
        drows = [(e.name, f"{e.log_bayes_factor:.2f}",
                  "n/a" if e.heldout_score_gain is None else f"{e.heldout_score_gain:.2f}",
                  _fmt(e.rms_after, 3), _fmt(e.heldout_rms_after, 3), f"{100 * e.max_ei_shift:.1f} %")
                 for e in diagnosis.effects]
        g = diagnosis.gap
        sections.append(("Sim-to-real gap diagnosis",
                         f'<p class="verdict">Verdict: {html.escape(diagnosis.verdict)}</p>'
                         f"<p>Residual rms {g.rms_residual:.3g}, systematic part {g.systematic_rms:.3g}, "
                         f"noise {g.noise_rms:.3g} (p = {g.p_value:.2g}).</p>"
                         + _table(["effect", "log Bayes factor", "held-out gain", "rms after", "held-out rms",
                                   "max EI shift"], drows)
                         + _figure(plotting.plot_residual_map(diagnosis), "Where the model and the data disagree",
                                   "red and blue stripes are load positions where a sensor reads systematically "
                                   "above or below the model, in noise standard deviations.")
                         + _figure(plotting.plot_shrinkage(diagnosis), "How far the gap shrinks",
                                   "bars well below the dashed line and close to the dotted noise floor identify "
                                   "an effect that explains the gap.")
                         + _figure(plotting.plot_ei_before_after(diagnosis, supports=supports),
                                   "EI before and after modelling the gap",
                                   "the difference between the lines is the bias the unmodelled effect was "
                                   "causing in the identified EI.")))
    if provenance is not None:
        sections.append(_provenance_section(provenance))
    return Report(_render(case, sections), tuple(title for title, _ in sections), design, verification,
                  posterior, diagnosis)



def _ranking(verification, design, names):
    """The layouts ranked by verification, and a plain note when a baseline verifies better."""
    from .verification.ranking import rank_layouts

    if "recommended" not in names:
        return ""
    values = {"recommended": design.value} | {b.name: b.value for b in design.baselines}
    ranking = rank_layouts(replace(verification, names=tuple(names)), criterion=design.criterion, values=values)
    rows = [(str(e.rank), e.name, _fmt(e.detection_rate, 3), _fmt(e.detection_limit, 3),
             _fmt(e.localisation_error_m, 2), _fmt(e.coverage95, 3), _fmt(e.criterion, 6)) for e in ranking.entries]
    notes = [line.strip() for line in ranking.summary().splitlines()[len(ranking.entries) + 1:]]
    return ("<h3>Ranking by verification</h3>"
            + _table(["rank", "layout", "detection rate", "detection limit", "localisation error [m]",
                      "95 % coverage", f"{design.criterion} criterion"], rows)
            + "".join(f'<p class="verdict">{html.escape(n)}</p>' for n in notes))


def _render(case, sections):
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    toc = "".join(f'<li><a href="#s{i}">{html.escape(t)}</a></li>' for i, (t, _) in enumerate(sections))
    body = "".join(f'<section id="s{i}"><h2>{html.escape(t)}</h2>{content}</section>'
                   for i, (t, content) in enumerate(sections))
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>sensorplan report: '
            f"{html.escape(case.name)}</title><style>{_CSS}</style><script>{_SCRIPT}</script></head><body>"
            f"<h1>sensorplan report: {html.escape(case.name)}</h1>"
            f'<p class="note">Generated {stamp} by sensorplan. Units: m, N, N m^2; tilt in µrad, '
            "deflection in mm.</p>"
            f"<nav><ol>{toc}</ol></nav>{body}</body></html>")
