"""Detection against its physical limit, across severities and layouts.

For each embedded example and a few sensible layouts, ``verify_layouts``
runs the damage detector on local losses of 10-40 % over 2 m (10 crossings,
the case's noise, false-alarm rate 0.05, smooth nuisance) and reports, per
layout and severity, the detection rate with its Monte-Carlo standard
error, the physical limit (the mean known-location power at the Bonferroni
level, ``detection_limit``), their ratio, the false-alarm rate on the
undamaged controls, the EI band coverage on the damaged scenarios and the
coverage of the detector's 95 % loss interval.

Run:  python studies/verification/detection_vs_limit.py [--quick] [--out FILE]

Last full run (commit b7cf141, 16 locations and 8 controls per layout and
severity, seed 1): see the table it prints; the quick mode (6 locations, 4
controls) is what tests/test_studies.py runs.
"""

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import sensorplan as sp  # noqa: E402

SEVERITIES = (0.1, 0.2, 0.3, 0.4)
LAYOUTS = {
    "simply-supported": {"three evenly": (5.0, 10.0, 15.0), "thirds": (6.7, 13.3)},
    "openlab-like": {"four evenly": (4.0, 11.0, 19.0, 26.0), "case's own (11, 19)": (11.0, 19.0)},
    "three-span": {"six evenly": (3.3, 10.0, 16.7, 23.3, 30.0, 36.7), "near supports": (2.0, 10.0, 14.0, 26.0, 30.0, 38.0)},
}


def run(quick=False, seed=1, examples=None, echo=None):
    n_locations, n_controls = (6, 4) if quick else (16, 8)
    severities = (0.2, 0.4) if quick else SEVERITIES
    rows = []
    for example, layouts in LAYOUTS.items():
        if examples is not None and example not in examples:
            continue
        case = sp.example_case(example)
        for severity in severities:
            result = sp.verify_layouts(case, list(layouts.values()), names=list(layouts), n_locations=n_locations,
                                       n_controls=n_controls, severity=severity, seed=seed)
            for name, score in zip(layouts, result.layouts):
                m = score.metrics
                rows.append({"example": example, "layout": name, "severity": severity,
                             "detection": m["detection_rate"].mean, "detection_se": m["detection_rate"].se,
                             "limit": score.detection_limit, "ratio": score.detection_ratio,
                             "false_alarm": m["false_alarm_rate"].mean,
                             "damaged_coverage95": m["damaged_coverage95"].mean,
                             "loss_coverage95": m["loss_coverage95"].mean,
                             "localisation_error_m": m["localisation_error_m"].mean})
                if echo is not None:
                    echo(format_rows(rows[-1:]).splitlines()[-1])
    return rows


def format_rows(rows):
    head = (f"{'example':17s} {'layout':22s} {'loss':>5s} {'detection':>14s} {'limit':>6s} {'ratio':>6s} "
            f"{'false al.':>9s} {'cover95':>8s} {'loss cov':>8s} {'loc. err':>8s}")
    out = [head]
    for r in rows:
        ratio = "n/a" if r["ratio"] is None else f"{r['ratio']:.2f}"
        out.append(f"{r['example']:17s} {r['layout'][:22]:22s} {100 * r['severity']:4.0f}% "
                   f"{r['detection']:6.3f}±{r['detection_se']:5.3f} {r['limit']:6.3f} {ratio:>6s} "
                   f"{r['false_alarm']:9.3f} {r['damaged_coverage95']:8.3f} {r['loss_coverage95']:8.3f} "
                   f"{r['localisation_error_m']:8.2f}")
    return "\n".join(out)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="few scenarios (a smoke run)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, help="also write the table to this file")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    print(format_rows([]), flush=True)
    text = format_rows(run(args.quick, args.seed, echo=lambda line: print(line, flush=True)))
    text += f"\n({time.perf_counter() - start:.0f} s; detection over local losses; limit = known-location power " \
            "at the Bonferroni level; cover95 = EI band coverage on damaged scenarios)"
    print(text)
    if args.out:
        args.out.write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
