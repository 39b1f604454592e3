"""The console summary of a diagnosis, in engineering units.

Owns: the diagnosis's printed form.  May import: the foundations.
"""

import numpy as np

from .units import in_unit

__all__ = ["summary_lines"]


def summary_lines(d):
    """The printed diagnosis: the verdict's sentence and next step first, then the gap, the effects, the causes."""
    g, v = d.gap, d.verdict
    lines = [f"Verdict ({v.status}): {v.summary}"] + ([f"  next step: {v.next_step}"] if v.next_step else [])
    lines.append(f"Sim-to-real gap: {'significant' if g.significant else 'not significant'} (p = {g.p_value:.2g})")
    for name, s in d.shrinkage.items():
        v = g.by_sensor[name]
        lines.append(f"  {name}: residual rms {in_unit(v.rms_residual, s.kind)}, systematic "
                     f"{in_unit(v.systematic_rms, s.kind)}, noise {in_unit(v.noise_rms, s.kind)}")
    if g.worst_positions_m:
        lines.append("  gap concentrates at load positions [m]: " + ", ".join(f"{x:.2f}" for x in g.worst_positions_m))
    if d.springs_estimated:
        lines.append("  springs: the case's elastic springs are estimated with EI (as invert does by default)")
        lines += [f"    {f.text}" for f in d.springs]
    else:
        lines.append("  springs: held at the case's values (none elastic, or estimate_springs=False)")
    if d.binning:
        b = d.binning
        lines.append(f"  fitted in bins of {b.size} consecutive readings ({b.width_m:.2f} m; {b.rows} "
                     f"readings in {b.bins} whitened bins): the bins keep >= {100 * b.keep:.0f} % of the "
                     "information on EI")
    for name, reason in d.not_offered.items():
        lines.append(f"  not offered: {name} ({reason})")
    return lines + _effect_lines(d) + _cause_lines(d) + _closing_lines(d)


def _effect_lines(d):
    """The table of the candidate effects, each fitted alone."""
    lines = [f"  {'effect':26s} {'log BF':>8s} {'held-out gain':>14s} {'max EI shift':>13s}"]
    for e in d.effects:
        gain = "n/a" if e.heldout_score_gain is None else f"{e.heldout_score_gain:.1f}"
        bf = "n/a" if not np.isfinite(e.log_bayes_factor) else f"{e.log_bayes_factor:.1f}"
        flag = ("" if e.converged else "  (stopped: far below the best; not used)" if e.abandoned
                else "  (not converged: not used)")
        lines.append(f"  {e.name:26s} {bf:>8s} {gain:>14s} {100 * e.max_ei_shift:12.1f}%{flag}")
    return lines


def _cause_lines(d):
    """Each cause with its findings and alternatives, the residuals before and after, the corrected EI."""
    lines = []
    for k, name in enumerate(d.causes):
        lines.append(f"  cause {k + 1}: {name}")
        lines += [f"    {f.text}" for f in d.findings.get(name, ())] or ["    (no single parameter stands out)"]
        if d.alternatives.get(name):
            lines.append("    explains the gap about as well: " + ", ".join(d.alternatives[name]))
        if d.includes.get(name):
            lines.append(f"    includes {', '.join(d.includes[name])} as a special case (the data cannot tell them "
                         f"apart once {name} is in)")
    if d.causes:
        lines.append("  residual rms per sensor, before -> after the selected effects (held out in brackets):")
        for name, s in d.shrinkage.items():
            held = ""
            if s.heldout_rms_before is not None and s.heldout_rms_after is not None:
                held = f" ({in_unit(s.heldout_rms_before, s.kind)} -> {in_unit(s.heldout_rms_after, s.kind)})"
            lines.append(f"    {name}: {in_unit(s.rms_before, s.kind)} -> {in_unit(s.rms_after, s.kind)}{held}")
        if d.ei_final_band:
            lo, hi = (np.asarray(b) for b in d.ei_final_band)
            lines.append(f"  EI after correction: {np.min(d.ei_final):.3g} to {np.max(d.ei_final):.3g} N·m², "
                         f"95 % bands {np.min(lo):.3g} to {np.max(hi):.3g} N·m² (noise scale {d.noise_scale:.2f})")
    return lines


def _closing_lines(d):
    """Partial effects, the confounded ones, convergence and the statement."""
    g, lines = d.gap, []
    if d.partial:
        verbs = "reduces the gap but leaves it" if len(d.partial) == 1 else "reduce the gap but leave it"
        p = "" if d.partial_gap is None else f", p = {d.partial_gap.p_value:.2g}"
        lines.append(f"  not causes: {', '.join(d.partial)} {verbs} significant{p} (the cause is outside the "
                     "library)")
        if d.partial_shrinkage:
            lines.append(f"    residual rms per sensor, before -> with {', '.join(d.partial)}: " + ", ".join(
                f"{n} {in_unit(s.rms_before, s.kind)} -> {in_unit(s.rms_after, s.kind)}"
                for n, s in d.partial_shrinkage.items()))
    if d.confounded and not g.significant and not d.causes:
        # nothing to explain: which effects an EI change could mimic is no finding here (it is in to_dict())
        lines.append(f"  no significant gap, so confounded alternatives are not listed ({len(d.confounded)} effects "
                     "an EI change could mimic; see the JSON)")
    for c in (d.confounded if g.significant or d.causes else ()):
        where = "" if c.separating_sensor_m is None else (
            f"; a sensor at {c.separating_sensor_m:.2f} m would separate them")
        lines.append(f"  confounded: {c.name} can be mimicked by an EI change "
                     f"({100 * c.information_kept:.0f} % of its information survives){where}")
    if not d.converged:
        lines.append("  WARNING: the base or final fit did not converge; treat the verdict with caution")
    lines.append(f"  statement: {d.statement}")
    return lines
