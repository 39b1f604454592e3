"""The report's conclusion: what to install, what it detects, how it verified, the caveats, written from
the one :class:`~sensorplan.analysis.Analysis` the sections show.
"""

import html

import numpy as np

__all__ = ["conclusion_html", "better_baselines"]


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


def conclusion_html(analysis):
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
