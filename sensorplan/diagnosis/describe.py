"""What an identified effect means in engineering terms: where, value, 95 % interval, unit.

Turns an effect's parameter block (MAP and standard deviation) into
findings such as "vertical spring at support 2 (x = 20.0 m): 5.0e8 N/m,
95 % interval 3.1e8-8.0e8 N/m".  Only parameters the data moved away from
their prior (or pinned down well beyond it) are stated.

Owns: the engineering statement of effects.  May import: the foundations.
"""

import math

import numpy as np

from .effects_more import LOAD_REFERENCE

__all__ = []

Z95 = 1.959963984540054
UNITS = {"rotation": (1e6, "µrad"), "deflection": (1e3, "mm")}


def finding(where, value, low, high, unit, fmt=".3g"):
    """One finding as a dict (SI-free: the values are in ``unit``)."""
    return {"where": where, "value": float(value), "low": float(low), "high": float(high), "unit": unit,
            "text": f"{where}: {value:{fmt}} {unit}, 95 % interval {low:{fmt}} to {high:{fmt}} {unit}"}


def informed(mean, std, prior_mean, prior_std):
    """Parameters the data informed: moved by > 2 posterior std from the prior mean, and std < 0.7 prior std."""
    return (np.abs(mean - prior_mean) > 2.0 * std) & (std < 0.7 * prior_std)


def describe(effect, problem, mean, std):
    """Findings (list of dicts) of ``effect`` with parameter MAP ``mean`` and std ``std``."""
    name = effect.name
    ok = informed(mean, std, effect.mean, effect.std)
    out = []
    if name in ("support_rotational_spring", "vertical_support_spring", "case_springs"):
        xs = problem.case.bridge.support_positions
        for j, pname in enumerate(effect.names):
            kind = "rotational" if "rot" in pname else "vertical"
            i = int(pname.rsplit("_", 1)[1])
            if ok[j] or name == "case_springs":
                unit = "N·m/rad" if kind == "rotational" else "N/m"
                f = finding(f"{kind} spring at support {i} (x = {xs[i]:.1f} m)", math.exp(mean[j]),
                            math.exp(mean[j] - Z95 * std[j]), math.exp(mean[j] + Z95 * std[j]), unit, ".2e")
                if name == "case_springs":
                    nominal = math.exp(effect.mean[j])
                    f["case_value"] = nominal
                    f["differs"] = bool(not f["low"] <= nominal <= f["high"])
                    f["text"] += f" (case: {nominal:.2e} {unit}{'; differs' if f['differs'] else ''})"
                out.append(f)
    elif name in ("sensor_offset", "thermal_drift"):
        step = 2 if name == "thermal_drift" else 1
        for i, sname in enumerate(problem.sensor_names):
            scale, unit = UNITS[problem.sensors.kinds[i]]
            idx = np.array([c * problem.n_sensors * step + i * step + (step - 1) for c in range(problem.n_crossings)])
            if not ok[idx].any():
                continue
            k = idx[int(np.argmax(np.abs(mean[idx])))]
            c = int(np.where(idx == k)[0][0])
            what = "drift along the crossing" if step == 2 else "offset"
            out.append(finding(f"{what} of {sname}, largest in crossing {problem.labels[c]} "
                               f"({int(ok[idx].sum())} of {idx.size} crossings affected)", scale * mean[k],
                               scale * (mean[k] - Z95 * std[k]), scale * (mean[k] + Z95 * std[k]), unit))
    elif name == "position_offset":
        shifts = np.arange(problem.n_crossings)
        if ok[shifts].any():
            k = int(np.argmax(np.abs(mean[shifts]) * ok[shifts]))
            out.append(finding(f"load position shift, largest in crossing {problem.labels[k]} "
                               f"({int(ok[shifts].sum())} of {shifts.size} crossings affected)", mean[k],
                               mean[k] - Z95 * std[k], mean[k] + Z95 * std[k], "m", ".2f"))
        if ok[-1]:
            out.append(finding("position scale (speed) error", 100 * mean[-1], 100 * (mean[-1] - Z95 * std[-1]),
                               100 * (mean[-1] + Z95 * std[-1]), "%", ".2f"))
    elif name == "axle_loads":
        for a in range(effect.n_params):
            if ok[a]:
                out.append(finding(f"load of axle {a + 1}", 100 * math.expm1(mean[a]),
                                   100 * math.expm1(mean[a] - Z95 * std[a]), 100 * math.expm1(mean[a] + Z95 * std[a]),
                                   "% vs nominal", ".1f"))
    elif name == "sensor_position":
        for i, sname in enumerate(problem.sensor_names):
            if ok[i]:
                x = problem.sensors.positions[i]
                out.append(finding(f"position of {sname} (recorded x = {x:.2f} m)", mean[i], mean[i] - Z95 * std[i],
                                   mean[i] + Z95 * std[i], "m shift", ".2f"))
    elif name == "dynamic_amplification":
        if ok.any():
            k = int(np.argmax(np.abs(mean) * ok))
            out.append(finding(f"response amplification, largest in crossing {problem.labels[k]} "
                               f"({int(ok.sum())} of {ok.size} crossings affected)", 100 * mean[k],
                               100 * (mean[k] - Z95 * std[k]), 100 * (mean[k] + Z95 * std[k]), "%", ".1f"))
    elif name == "sensor_gain":
        for i, sname in enumerate(problem.sensor_names):
            flipped = effect.sign[i] < 0
            if ok[i] or flipped:
                note = " (mounted the wrong way round)" if flipped else ""
                ends = effect.sign[i] * np.exp([mean[i] - Z95 * std[i], mean[i] + Z95 * std[i]])
                out.append(finding(f"gain of {sname}{note}", effect.sign[i] * math.exp(mean[i]), ends.min(),
                                   ends.max(), "", ".3f"))
    elif name == "load_dependent_stiffness":
        if ok[0]:
            ref = LOAD_REFERENCE / 1e3
            out.append(finding(f"EI change per {ref:.0f} kN of load level", 100 * math.expm1(mean[0]),
                               100 * math.expm1(mean[0] - Z95 * std[0]), 100 * math.expm1(mean[0] + Z95 * std[0]),
                               "%", ".1f"))
    return out


def in_unit(value, kind):
    """A residual [rad or m] in the sensor's engineering unit, as text."""
    scale, unit = UNITS[kind]
    return f"{scale * value:.3g} {unit}"
