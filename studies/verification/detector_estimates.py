"""The detector's estimates on losses it should find: detection, centre and loss interval.

Acceptance check of issue 14: on losses whose known-location power under the
smooth nuisance is >= 0.95, detection >= 90 %, centre within 1.5 m, and the
loss's 95 % interval covers the truth in >= 80 % of the detected cases.

Scenarios: the embedded examples with the layouts of
``detection_vs_limit.py`` (each sensor with the median noise of the case's
sensors, the case's noise correlation), losses of 20, 30 and 40 % over 1, 2
and 3 m, 10 crossings.  For each (example, layout, severity, length) the
detectability map (``sensorplan.detectability``, step 0.25 m) gives the
centres whose power is >= 0.95; ``--per-config`` of them are drawn at random
(explicit seed) and shifted by a random fraction of the map step, so that
zone edges fall anywhere inside the inversion elements.  Each truth is
simulated on the finer, differently aligned truth mesh of the verification
(no inverse crime) and tested by ``detect_damage`` (false-alarm rate 0.05,
smooth nuisance).  Reported: the number of datasets, the detection rate,
the share of detections whose centre is within 1.5 m, the share whose 95 %
loss interval covers the true loss, per example and overall (with binomial
standard errors).

Run:  python studies/verification/detector_estimates.py [--per-config N] [--seed S]

Last run (``--per-config 3``, seed 7, commit "detection/scan: centre = the
most probable window"; 128 datasets; binomial standard errors, the counts
in brackets; "centre" and "loss covered" over the detected cases):

    group                               n          detected   centre <= 1.5 m      loss covered
    simply-supported                   54 0.981±0.018 ( 54) 0.981±0.019 ( 53) 0.943±0.032 ( 53)
    openlab-like                       24 0.792±0.083 ( 24) 0.842±0.084 ( 19) 1.000±0.000 ( 19)
    three-span                         50 0.880±0.046 ( 50) 0.864±0.052 ( 44) 0.955±0.031 ( 44)
    length 1 m                         38 0.868±0.055 ( 38) 0.879±0.057 ( 33) 1.000±0.000 ( 33)
    length 2 m                         45 0.867±0.051 ( 45) 0.897±0.049 ( 39) 0.974±0.025 ( 39)
    length 3 m                         45 0.978±0.022 ( 45) 0.955±0.031 ( 44) 0.909±0.043 ( 44)
    loss 20 %                          38 0.842±0.059 ( 38) 0.906±0.052 ( 32) 0.969±0.031 ( 32)
    loss 30 %                          45 0.933±0.037 ( 45) 0.881±0.050 ( 42) 1.000±0.000 ( 42)
    loss 40 %                          45 0.933±0.037 ( 45) 0.952±0.033 ( 42) 0.905±0.045 ( 42)
    all                               128 0.906±0.026 (128) 0.914±0.026 (116) 0.957±0.019 (116)

A second sample (2026-11-25, ``--per-config 3 --seed 8``, log-normal hyperprior; the detector is
not affected by it; 128 datasets, 287 s): detected 0.914 +- 0.025, centre within 1.5 m in
0.932 +- 0.023 of the detections, loss covered in 0.889 +- 0.029 (openlab-like detected 0.792,
simply-supported 0.981, three-span 0.900).

Reading it: detection 0.91 (target 0.9) and loss-interval coverage 0.96
(target 0.8) hold overall; the centre is within 1.5 m in 0.91 of the
detections, not in all.  The misses are not noise in the estimate: in each
of the 10 cases the projected signatures of the true zone and of a zone
6-10 m away are nearly collinear after the smooth nuisance is projected off
(with three or four sensors), the data favour the wrong one or split
between them, and the 95 % centre interval spans both.  Detection is lowest
on openlab-like (0.79): a known-location power of 0.95 (d = 3.29) is only
Phi(3.29 - 3.0) = 0.6 against the scan's threshold of about 3.0, the price
of not knowing where the loss is; most selected centres are far above 0.95.
With the same priors but the estimates on the scan's coarser zones (edges
on a quarter-length grid, lengths by sqrt(2)), a partial run with the same
seed covered the true loss in 38 of 45 detections (0.84): when the data are
strong, a zone that does not match the true edges gives a sharp but biased
loss.  (The previous estimator, a half-normal prior on r and every zone the
same prior mass, so that short lengths carried most of it, covered
0.75-1.00 per row of detection_vs_limit.py.)
"""

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import sensorplan as sp  # noqa: E402
from detection_vs_limit import LAYOUTS  # noqa: E402
from sensorplan.verification.scenarios import Scenario, truth_mesh  # noqa: E402

SEVERITIES = (0.2, 0.3, 0.4)
LENGTHS = (1.0, 2.0, 3.0)
STEP = 0.25
N_CROSSINGS = 10


def layout_case(case, positions):
    std = case.noise_std_for("rotation")
    sensors = sp.SensorLayout.candidates(list(positions), "rotation", noise_std=[std] * len(positions))
    return replace(case, sensors=sensors, noise=sp.NoiseModel(sensors.noise_std, case.noise.correlation_length))


def run(per_config=2, seed=7, echo=None):
    rng = np.random.default_rng(seed)
    rows = []
    for example, layouts in LAYOUTS.items():
        base = sp.example_case(example)
        fine_mesh = truth_mesh(base)
        for name, positions in layouts.items():
            case = layout_case(base, positions)
            fine = case.with_mesh(fine_mesh)
            for severity in SEVERITIES:
                for length in LENGTHS:
                    limit = sp.detectability(case, severity=severity, length=length, n_crossings=N_CROSSINGS,
                                             step=STEP)
                    strong = np.asarray(limit.centres_m)[np.asarray(limit.power) >= 0.95]
                    if strong.size == 0:
                        continue
                    for c in rng.choice(strong, size=min(per_config, strong.size), replace=False):
                        c = float(np.clip(c + rng.uniform(-0.5, 0.5) * STEP, length / 2, case.bridge.length
                                          - length / 2))
                        scenario = Scenario("local", c - length / 2, c + length / 2, severity)
                        data = sp.simulate_crossings(fine, N_CROSSINGS, noise=True, rng=rng,
                                                     ei=scenario.truth(fine_mesh, fine.ei))
                        d = sp.detect_damage(case, data, rng=rng, n_null=4000)
                        row = {"example": example, "layout": name, "severity": severity, "length": length,
                               "centre": c, "detected": bool(d.detected), "centre_ok": None, "covered": None}
                        if d.detected:
                            row["centre_ok"] = abs(d.centre_m - c) <= 1.5
                            row["covered"] = d.loss_ci95[0] <= severity <= d.loss_ci95[1]
                            row.update(est_centre=d.centre_m, est_length=d.length_m, loss=d.loss,
                                       loss_ci95=d.loss_ci95)
                        rows.append(row)
                        if echo is not None:
                            echo(row)
    return rows


def _rate(values):
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return "   n/a        "
    p = float(values.mean())
    return f"{p:5.3f}±{math.sqrt(p * (1 - p) / values.size):5.3f} ({values.size:3d})"


def summarise(rows):
    out = [f"{'group':32s} {'n':>4s} {'detected':>17s} {'centre <= 1.5 m':>17s} {'loss covered':>17s}"]
    groups = [(ex, [r for r in rows if r["example"] == ex]) for ex in LAYOUTS]
    groups += [(f"length {ln:g} m", [r for r in rows if r["length"] == ln]) for ln in LENGTHS]
    groups += [(f"loss {100 * s:.0f} %", [r for r in rows if r["severity"] == s]) for s in SEVERITIES]
    groups.append(("all", rows))
    for label, group in groups:
        det = [r for r in group if r["detected"]]
        out.append(f"{label:32s} {len(group):4d} {_rate([r['detected'] for r in group]):>17s} "
                   f"{_rate([r['centre_ok'] for r in det]):>17s} {_rate([r['covered'] for r in det]):>17s}")
    return "\n".join(out)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-config", type=int, default=2, help="centres drawn per example/layout/loss/length")
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args(argv)
    start = time.perf_counter()

    def echo(r):
        extra = ""
        if r["detected"]:
            lo, hi = r["loss_ci95"]
            extra = (f" est. centre {r['est_centre']:6.2f} length {r['est_length']:4.2f} loss {r['loss']:.2f} "
                     f"[{lo:.2f}, {hi:.2f}]{'' if r['covered'] else '  MISSED'}")
        print(f"{r['example']:17s} {r['layout'][:20]:20s} {100 * r['severity']:3.0f}% {r['length']:3.1f} m "
              f"at {r['centre']:6.2f}: {'detected' if r['detected'] else 'not detected'}{extra}", flush=True)

    rows = run(args.per_config, args.seed, echo)
    print(summarise(rows))
    print(f"({time.perf_counter() - start:.0f} s, seed {args.seed}, {args.per_config} per configuration)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
