"""The report's conclusion: what to install, what it detects, how it verified, the caveats, written from
the one :class:`~sensorplan.analysis.Analysis` the sections show.
"""

import html

import numpy as np

__all__ = ["conclusion_html", "better_baselines", "sufficiency_sentence"]


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


def sufficiency_sentence(analysis):
    """The report's first sentence: is the requirement met, and if not, what would meet it.

    Written from ``analysis.target`` (the fewest sensors placed for detection
    that reach the required worst-case power) and the recommended layout's
    own worst-case power; with measured data it carries the verdict's status.
    """
    target, d = analysis.target, analysis.design
    if target is None:
        head = "No requirement was assessed (detectability not computed)"
    else:
        a, det = target.answer, analysis.detectability
        need = (f"worst-case power {a.power:.2f} of detecting a {100 * det.severity:g} % EI loss over "
                f"{det.length_m:g} m anywhere on the bridge ({det.n_crossings} crossing(s), false-alarm rate "
                f"{100 * det.false_alarm_rate:g} %)")
        if a.met and a.count <= d.count:
            head = (f"Sufficient: {a.count} sensor(s) placed for detection reach the required {need} with "
                    f"{a.worst_case_power:.2f}; the recommended {d.criterion}-optimal layout of {d.count} reaches "
                    f"{analysis.recommended_power:.2f}")
        else:
            head = (f"Not sufficient: the required {need} is not reached with {d.count} sensor(s) (the recommended "
                    f"layout reaches {analysis.recommended_power:.2f})")
            head += _what_would_do(a, analysis)
    if analysis.verdict is not None:
        head += f"; the measured data's verdict is {analysis.verdict.status}"
    return head + "."


def _what_would_do(answer, analysis):
    """The counts and crossings that would meet an unmet requirement."""
    ways = []
    if answer.met:
        ways.append(f"{answer.count} sensors placed for detection would reach {answer.worst_case_power:.2f}")
    else:
        ways.append(f"no count up to {answer.count} reaches it with {analysis.detectability.n_crossings} crossing(s)")
        if answer.crossings_needed is not None:
            ways.append(f"{answer.count} sensors placed for detection would with {answer.crossings_needed} crossings")
    if analysis.crossings_needed is not None:
        ways.append(f"{analysis.crossings_needed} crossings with the recommended layout would")
    return "; " + ", ".join(ways)


def conclusion_html(analysis):
    """The conclusion: sufficiency first, then the data's verdict, the layout, what it detects, how it verified."""
    text = f"<b>{html.escape(sufficiency_sentence(analysis))}</b> "
    if analysis.verdict is not None:
        text += html.escape(analysis.verdict.summary) + " "
        if analysis.verdict.next_step:
            text += html.escape(f"Next step: {analysis.verdict.next_step}.") + " "
    return text + _layout_html(analysis)


def _layout_html(analysis):
    """What to install, what it detects, how it verified, the caveats."""
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
             f"detected {m['detection_rate'].text(empty='none (no damaged scenario)')} of the "
             f"{100 * v.severity:.0f} % losses over {v.length:g} m, raised false alarms on "
             f"{m['false_alarm_rate'].text(empty='no control')} of the undamaged controls, and its 95 % credible "
             f"bands covered the true EI at {m['coverage95'].text()} of the elements. ")
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
    caveats += list(v.false_alarm_caveats())
    caveats.append(f"the verification uses {len(rec.records)} synthetic scenarios of the configured model "
                   "(supports, vehicle, noise); a model the bridge does not follow makes every number optimistic")
    return text + "Caveats: " + "; ".join(html.escape(c) for c in caveats) + "."
