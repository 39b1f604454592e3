"""Which criterion's layout verifies best: D, A, E, Ds (and detect, when registered) by verification.

For the three embedded bridges and a four-span bridge (its TOML is below),
``recommend`` gives the layout of each design criterion (same count, 0.5 m
grid; Ds treats the elastic springs as nuisance parameters, and on a bridge
without springs it is D), and ``verify_layouts`` scores all of them on the
same scenarios and seeds: local losses of 25 % over 2 m scanned along the
bridge, span softenings and undamaged controls, 10 crossings each, the
case's noise, the detector at a 5 % false-alarm rate with the smooth
nuisance.  Reported per layout: the detection rate of the local losses
(± Monte-Carlo standard error), its physical limit (known-location power at
the Bonferroni level, no Monte-Carlo error), the localisation error of the
detected losses, the EI band coverage (coverage95, nominal 0.95) and the
rmse of EI, then the criterion whose layout ranks first by verification
(``sensorplan.verification.ranking``: detection rate, then limit).

Run:  nice python studies/design/criteria_vs_verification.py [--quick] [--out FILE]

Last full run (branch mixedkinds at ff1634a + this script; 12 locations, 4 controls, seed 1; 364 s on a loaded 2-core
machine; ``detect`` was not registered on main then; rows reordered to the script's order, the numbers do
not depend on it: every layout sees the same scenarios and seeds):

    bridge            crit       detection  limit  loc. err [m]    coverage95          rmse  layout [m]
    simply-supported  D*      1.000±0.000  1.000   0.14± 0.02  0.991±0.005  0.024±0.005  0, 10, 20
    simply-supported  A       1.000±0.000  1.000   0.18± 0.03  0.997±0.003  0.022±0.004  0, 2, 20
    simply-supported  E       1.000±0.000  1.000   0.16± 0.03  0.988±0.009  0.028±0.009  0, 17.5, 19.5
    simply-supported  Ds      1.000±0.000  1.000   0.14± 0.02  0.991±0.005  0.024±0.005  0, 10, 20
    simply-supported  even    1.000±0.000  1.000   0.27± 0.08  1.000±0.000  0.032±0.007  3.5, 10, 16.5
    openlab-like      D       0.167±0.112  0.135   4.50± 3.37  0.976±0.008  0.056±0.006  2, 13, 16, 28.5
    openlab-like      A       0.250±0.131  0.148   6.01± 2.52  0.976±0.009  0.054±0.005  1.5, 13, 16.5, 29
    openlab-like      E       0.250±0.131  0.176   0.35± 0.22  0.983±0.009  0.048±0.005  1.5, 6, 17, 29
    openlab-like      Ds*     0.250±0.131  0.289   0.82± 0.35  0.983±0.006  0.052±0.005  6, 13, 16, 24
    openlab-like      even    0.083±0.083  0.169   0.46±  nan  0.978±0.010  0.051±0.005  3.5, 11.5, 18.5, 26.5
    three-span        D       0.167±0.112  0.121   0.33± 0.12  0.976±0.009  0.034±0.005  0, 13, 27, 40
    three-span        A       0.167±0.112  0.121   0.33± 0.12  0.976±0.009  0.034±0.005  0, 13, 27, 40
    three-span        E*      0.250±0.131  0.091   6.54± 3.14  0.992±0.004  0.034±0.005  0, 12.5, 27.5, 40
    three-span        Ds      0.167±0.112  0.121   0.33± 0.12  0.976±0.009  0.034±0.005  0, 13, 27, 40
    three-span        even    0.167±0.112  0.104   8.92± 7.54  0.983±0.008  0.044±0.005  5, 15, 25, 35
    four-span         D*      0.500±0.151  0.347   5.55± 3.84  0.996±0.002  0.022±0.003  0, 11, 24, 37, 48
    four-span         A       0.500±0.151  0.347   5.55± 3.84  0.996±0.002  0.022±0.003  0, 11, 24, 37, 48
    four-span         E       0.500±0.151  0.347   5.55± 3.84  0.996±0.002  0.022±0.003  0, 11, 24, 37, 48
    four-span         Ds      0.500±0.151  0.347   5.55± 3.84  0.996±0.002  0.022±0.003  0, 11, 24, 37, 48
    four-span         even    0.167±0.112  0.233   4.42± 4.30  0.989±0.005  0.034±0.004  5, 14.5, 24, 33.5, 43

Reading it:

* With 12 local losses per bridge the detection rates of the criteria's
  layouts differ by less than one standard error (±0.11-0.15) on every
  bridge but the simple span, where everything is detected.  The detection
  limit (known-location power, no Monte-Carlo error) separates them: on
  openlab-like, whose ends are elastic springs, the Ds layout's limit is
  0.289 against 0.135 for D (and 0.169 evenly spaced); on three-span E has
  the highest detection rate (0.25 vs 0.17, within noise) but the lowest
  limit (0.091 vs 0.121 for D, A and Ds); on four-span all four criteria
  choose the same layout, whose limit (0.347) and detection rate (0.50 vs
  0.17) beat evenly spaced sensors.
* The identification metrics follow the criteria's purpose: the A layout
  has the lowest rmse of EI on the simple span (0.022), D/A/Ds tie on
  three- and four-span, and every layout's 95 % bands cover 0.98-1.00.
* None of D, A, E and Ds asks where a 25 % loss over 2 m would be seen:
  their limits stay at 0.09-0.35 on the continuous bridges.  For detection,
  rank layouts by verification (``recommend --verify``) or design for it.
* Localisation errors are over the few detected losses, hence their large
  standard errors (nan: one detection).
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import sensorplan as sp  # noqa: E402
from sensorplan.design.criteria import CRITERIA  # noqa: E402
from sensorplan.io.config import load_case  # noqa: E402
from sensorplan.verification.ranking import rank_layouts  # noqa: E402

FOUR_SPAN = """
[case]
name = "four-span"

[bridge]
spans = [10.0, 14.0, 14.0, 10.0]     # m
ei = 1.2e10                          # N*m^2
elements = 48
rotational_springs = [0.0, 0.0, 0.0, 0.0, 0.0]
vertical_springs = [inf, 3.0e9, inf, 3.0e9, inf]   # N/m: elastomeric bearings at two piers

[vehicle]
axle_offsets = [0.0, 3.0]            # m
axle_loads = [60.0e3, 60.0e3]        # N

[sensors]
positions = [5.0, 17.0, 31.0, 43.0]
kinds = ["rotation", "rotation", "rotation", "rotation"]
noise_std_urad = 3.0

[loads]
start = 0.0
stop = 51.0
step = 0.25
"""

BRIDGES = {"simply-supported": 3, "openlab-like": 4, "three-span": 4, "four-span": 5}  # sensors per layout


def bridge_case(name):
    if name != "four-span":
        return sp.example_case(name)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "four-span.toml"
        path.write_text(FOUR_SPAN, encoding="utf-8")
        return load_case(path)


def criteria():
    return [c for c in ("D", "A", "E", "Ds", "detect") if c in CRITERIA]  # detect: once it is registered


def run(quick=False, seed=1, bridges=None, echo=None):
    n_locations, n_controls = (2, 2) if quick else (12, 4)
    rows = []
    for name, count in BRIDGES.items():
        if bridges is not None and name not in bridges:
            continue
        case = bridge_case(name)
        springs = bool(case.bridge.spring_parameters)
        layouts = {}
        for crit in criteria():
            design = sp.recommend(case, count, crit, springs=springs and crit == "Ds", curve_max=0, n_random=20,
                                  kind="rotation")
            layouts[crit] = design.layout_m
            if crit == "D":  # the reference everyone would try first
                even = design.baseline("equally_spaced").layout_m
        layouts["even"] = even
        result = sp.verify_layouts(case, list(layouts.values()), names=list(layouts), n_locations=n_locations,
                                   n_controls=n_controls, seed=seed)
        ranking = rank_layouts(result, reference=criteria()[0], criterion=criteria()[0])
        best = ranking.entries[0].name
        for crit, score in zip(layouts, result.layouts):
            m = score.metrics
            rows.append({"bridge": name, "criterion": crit, "layout": layouts[crit],
                         "detection": m["detection_rate"].mean, "detection_se": m["detection_rate"].se,
                         "limit": score.detection_limit, "loc": m["localisation_error_m"].mean,
                         "loc_se": m["localisation_error_m"].se, "coverage": m["coverage95"].mean,
                         "coverage_se": m["coverage95"].se, "rmse": m["rmse"].mean, "rmse_se": m["rmse"].se,
                         "first": crit == best})
            if echo is not None:
                echo(format_rows(rows[-1:]).splitlines()[-1])
    return rows


def format_rows(rows):
    head = (f"{'bridge':17s} {'crit':6s} {'detection':>13s} {'limit':>6s} {'loc. err [m]':>13s} "
            f"{'coverage95':>13s} {'rmse':>13s}  layout [m]")
    out = [head]
    for r in rows:
        out.append(f"{r['bridge']:17s} {r['criterion'] + ('*' if r['first'] else ''):6s} "
                   f"{r['detection']:6.3f}±{r['detection_se']:5.3f} {r['limit']:6.3f} "
                   f"{r['loc']:6.2f}±{r['loc_se']:5.2f} {r['coverage']:6.3f}±{r['coverage_se']:5.3f} "
                   f"{r['rmse']:6.3f}±{r['rmse_se']:5.3f}  " + ", ".join(f"{x:g}" for x in r["layout"]))
    return "\n".join(out)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="few scenarios, one bridge (a smoke run)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, help="also write the table to this file")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    print(format_rows([]), flush=True)
    rows = run(args.quick, args.seed, bridges=["simply-supported"] if args.quick else None,
               echo=lambda line: print(line, flush=True))
    text = format_rows(rows) + (f"\n({time.perf_counter() - start:.0f} s; * = first by verification on its bridge; "
                                "mean ± Monte-Carlo standard error)")
    print(text)
    if args.out:
        args.out.write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
