"""Two withheld effects at once: are both named, and nothing else (issue 18, >= 2 of 3)?

The truth has a support effect *and* a second effect from
``effects_data.generate`` (sensor offsets, thermal drift, axle loads,
load-position offsets, a sign-flipped sensor); the diagnosis gets the
nominal case.  Support effects: a settling bearing (a vertical spring of
2 x 48 EI / L^3, as ``effects_data.generate`` sets it for the single
effect; the right bearing of the single span, the middle one of the
two-span bridge, the left end of the three-span bridge) or a changed
rotational restraint (3 EI / L at a pin, as ``generate`` does; the left
support of the single span, the middle support of the two-span bridge, the
right end of the three-span bridge).  Bridges: the single span of
``validation.py`` (two axles, white noise), the openLAB-like two-span bridge
(two axles, white noise) and the three-span example (three axles, AR(1)
noise, elastic interior bearings); 8, 10 or 12 crossings by seed (the
acceptance range), three seeds.

Scored per dataset: both effects among the causes and no other cause
(strict); also, leniently, the causes named are true ones and a true effect
not named is reported as confounded with an EI change, with no unexplained
gap.

The physical limit of this score, dataset by dataset (studies/diagnosis/pairs_limit.py: the
optimal test of each effect given the other and EI): the oracle names both in 67 % of the case
layouts' datasets (the issue's 2 of 3 is its ceiling here) and 89 % with six tiltmeters; the
diagnosis reaches 0.84 and 0.91 of that, and names both in 120 of the 122 datasets where the
oracle's power is >= 0.9.

Run: python studies/diagnosis/pairs.py [--seeds N] [--first ...] [--bridges ...] [--six]

Issue 37 (picks that leave a significant gap are no longer named; the gap test whitens AR(1) residuals):
the case layouts 51/90 -> 50/90 both named and nothing else (49/75 where each is detectable alone; lenient
79 -> 78/90): three-span vertical spring + position offsets seed 0 named both with the held-out rms at 1.003 x
noise but a Ljung-Box p of 9e-5 on one sensor after them, now unexplained.  The other 89 the same.
Run before (2026-11-27, eleventh session, --six only; the code of the tenth session): the same 90
verdicts as the seventh session's --six run below (73/90 = 81 %, lenient 88/90); CPU median 2.4 s,
max 4.9 s.  The case layouts' last run: 51/90 (tenth session, docs/limitations.md).

Run before (2026-11-26, seventh session: the selection's later candidates give up below an earlier
one's evidence, swap tests at the pace of their last steps, the wider look-ahead, one mapping
product per bin map; beside another study): the same 180 verdicts and Bayes factors as the run
below; case layouts 51/90 = 57 %, lenient 79/90, CPU median 2.2 s, max 5.7 s; --six 73/90 = 81 %,
lenient 88/90, CPU median 3.4 s, max 7.4 s.
Run before (2026-11-26, sixth session: the speed changes of the force method, the line interpolant and
the diagnosis's lines, and the nominal start of a spring fit only while its starting model is
distorted; each beside another study): the same 180 verdicts and Bayes factors as the run below;
case layouts 51/90 = 57 %, lenient 79/90, CPU median 2.2 s, max 6.6 s; --six 73/90 = 81 %, lenient 88/90,
CPU median 3.0 s, max 10.4 s.
Run before (2026-11-26, fifth session: support-spring fits also from the nominal EI on a grossly distorted
base fit, and the look-ahead pick; the study beside other jobs): the same 180 verdicts as the run below;
case layouts 51/90 = 57 %, lenient 79/90, CPU median 2.7 s, max 7.7 s; --six 73/90 = 81 %, lenient 88/90,
CPU median 4.1 s, max 11.1 s.  Random bridges with any two library effects: studies/diagnosis/unseen.py.
Run before (2026-11-26, fourth session, final code: also the log-EI block mapped onto the bins once per
set of lines; the two runs side by side): the same verdicts as the run below; case layouts 51/90 =
57 %, lenient 79/90, CPU median 2.7 s, max 5.4 s; --six 73/90 = 81 %, lenient 88/90, CPU median
3.9 s, max 10.9 s, 0/90 above 15 s.
Run before (2026-11-26, fourth session: dense records fitted in whitened bins (the three-span datasets,
180 readings per crossing, in bins of 4) and the stall rule of the refits; the two runs side by side):
case layouts 51/90 = 57 % (the same 51), lenient 79/90 (three-span restraint + sign flip seed 2: the
restraint no longer listed as confounded with EI), CPU median 2.8 s, max 8.6 s; --six 73/90 = 81 %
(the same verdicts), lenient 88/90, CPU median 4.3 s, max 14.6 s (two-span settled bearing + sign
flip, 129 readings per crossing, not binned; 8.4 s on the idle machine), 0/90 above 15 s.
Run before (2026-11-26, third session, final code: also the held-out gain may sit in one fold as long
as the other folds do not lose more than 3 together; beside the validation study and the CI):
case layouts 51/90 = 57 % (the same verdicts), lenient 80/90, CPU median 4.2 s, max 9.2 s; --six
73/90 = 81 % (vertical 39/45, rotational 34/45: three-span far-end restraint + thermal drift seed
0 now names both -- log BF 9.4, fold gains -2.3, -0.8, 1.1, 6.4: the restraint shows while the
loads are near that end), lenient 88/90, CPU median 6.5 s, max 13.9 s, 0/90 above 15 s.
Run before (2026-11-26, third session: also each crossing's Jacobian on its own columns
(verdicts unchanged by it) and the entry ramp at an elastic end centred on the end instead of lying
wholly outside it; the two runs side by side): case layouts 51/90 = 57 % (vertical 37/45,
rotational 14/45), lenient 80/90, CPU median 3.5 s, max 9.4 s; --six 72/90 = 80 % (vertical
39/45, rotational 33/45), lenient 88/90, CPU median 5.7 s, max 13.7 s, 0/90 above 15 s.  Changed
verdicts: single-span settled bearing + position offsets no longer adds a third cause (seed 1 of
the case layout: support_rotational_spring; seeds 1 and 2 with six tiltmeters: axle_loads, log BF
38): the outside ramp had moved the bearing's jump out by 0.05 m and shifts and axle loads
absorbed it; nothing else changed.
Run before (2026-11-26, third session: the noise scale after each pick iterated to MacKay's fixed
point instead of one step, and a model that crawls at the new scale kept there with its ceiling;
both runs side by side with the validation study on the 2-core machine): case layouts: the same
90 verdicts, 50/90 = 56 %, lenient 79/90; CPU median 4.6 s, max 10.1 s, 0/90 above 15 s.
--six: 70/90 = 78 % (vertical 37/45, rotational 33/45: two-span restraint + thermal drift seeds 0
and 2 now name both -- after one step the noise scale stayed at 1.19 and the restraint's log BF
was 2.8, at the fixed point 0.99 and 4.4); lenient 86/90; CPU median 7.0 s, max 15.5 s, 1/90
above 15 s (two-span settled bearing + sensor gain, 12 crossings; 14.3-15.5 s for the three seeds
with three jobs on two cores, 10.3 s for seed 1 alone on the idle machine).
Run before (2026-11-26, after the piecewise-cubic lines (no new solve for shifted loads or single
axles), the column-sparse normal equations and the absolute convergence floor of the refits; the
two runs side by side with the test suite and the benchmark on the 2-core machine): the same
verdicts as the run below except one: single-span restraint + axle loads seed 2 (12 crossings)
now names the restraint (its refit, log BF 789, crawled at decrements of 0.05-0.005 and was
dropped as not converged; the verdict was "unexplained") and reports the axle loads confounded
with EI.  Case layouts: 50/90 = 56 % (vertical 36/45, rotational 14/45), lenient 79/90; CPU
median 3.7 s, max 10.7 s, 0/90 above 15 s (was max 13.8 s).  --six: 68/90 = 76 % (37/45,
31/45), lenient 86/90; CPU median 7.5 s, max 18.0 s, 2/90 above 15 s (two-span settled bearing
+ sensor gain, 12 crossings, 16.2 s; three-span restraint + sensor gain, 12 crossings, 18.0 s;
the same two took 13.9 s and 14.8 s in a run beside one other job instead of two).
Run before (2026-11-26: log gain with a discrete sign, two-pass refits, selection steps that give
up on a candidate as soon as it cannot reach the level a pick needs, Gauss-Newton skipped on the
remaining tau nodes once it has failed on one, the forward solve's reaction integrals as matrix
products; one process per support effect on the 2-core machine), both named and nothing else:
  vertical spring + second: 36/45 = 80 % (single span 12/15, two-span 12/15, three-span
  12/15); counting a missing true effect reported as confounded with EI: 44/45.
  rotational spring + second: 14/45 (single span 12/15; two-span middle support 1/15, confounded
  with EI even alone; three-span right end 1/15: its screening log BF alone is 4-7, and
  given a second effect an EI change absorbs it); lenient 34/45.
  All 90: 50/90 = 56 %; without the two-span rotational rows (an effect the layout cannot see
  alone): 49/75 = 65 %.
  The limit (restraint_limit.py): the optimal test that knows the restraint's support and value
  has non-centrality d^2 = 4.2-4.6 (two-span) and 2.9-7.7 (three-span) given a second effect:
  power 0.19-0.59 at a naming level (one-sided 0.005), 0.52-0.88 at 0.05; single span d^2 > 400.
  1/15 on each is about 0.1-0.2 of that oracle (which also knows where and how large).
  Misses: axle loads + spring 17/18 (8/9 with a settled bearing, 9/9 with a rotational restraint:
  the axle-load error is confounded with the EI level once the spring is in; reported as
  confounded); single-span position offsets + settled bearing seed 1 names an extra
  support_rotational_spring.
  CPU per dataset: vertical median 4.2 s, max 13.8 s, 0/45 above 15 s (was 3/45, max 26.7 s:
  position offsets with a settled bearing); rotational median 3.4 s, max 8.5 s.  Verdicts
  identical to the run before the three speed changes.
With --six (six tiltmeters from 0.1 L to 0.9 L on every bridge; same code, same day): vertical
  spring + second 37/45 = 82 % (single span 11/15, two-span 12/15, three-span 14/15), rotational
  restraint + second 31/45 = 69 % (single span 13/15, two-span 8/15, three-span 10/15); all 90:
  68/90 = 76 %; lenient 86/90.  So the rotational misses above are the layouts' (two or three
  tiltmeters), not the method's.  CPU median 7.8 / 6.4 s, 2/90 above 15 s (max 17.3 s: three-span
  position offsets + settled bearing, 12 crossings).  Misses: axle loads + spring 14/18; the
  restraint not named next to thermal drift (3 of 6 two- and three-span datasets) or a sensor
  gain (3 of 6); an extra axle_loads in 2 single-span position-offset datasets.
Previous run (2026-11-25 evening, before the output-order fix and the speed changes): vertical
  31/45, rotational 13/45; 6/45 above 15 s, max 27.3 s (extra sensor_gain with thermal drift,
  fixed by applying gains before additive outputs).
Earlier (2026-11-25 morning, two bridges, 60 datasets, linear gain, single-pass refits):
  vertical 21/30, rotational 13/30 (two-span middle support); 13/60 above 15 s, max 55.6 s
  (a flipped sensor with a settled bearing: the sign-flip refit crawled for 40 iterations and was
  not used).
"""

import os
import sys

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parents[1]))  # this checkout's sensorplan

import sensorplan as sp  # noqa: E402
from effects_data import generate  # noqa: E402
from validation import make_case  # noqa: E402

VERTICAL = "vertical_support_spring"
ROTATIONAL = "support_rotational_spring"
FIRST = (VERTICAL, ROTATIONAL)
SECOND = ("sensor_offset", "thermal_drift", "axle_loads", "position_offset", "sensor_gain")
BRIDGES = {"single-span": -1, "two-span": 1, "three-span": 0}  # the support that settles (vertical spring)
# the support whose rotational restraint changes.  The two-span bridge's end supports are elastic in the
# case (the base fit estimates them, as invert does); at its middle support a restraint is mimicked by a
# stiffer EI over the support: confounded with EI even alone (screening log BF -4 to 3), a limit of its
# two tiltmeters, scored apart (CONFOUNDED_ALONE)
ROTATES = {"single-span": 0, "two-span": 1, "three-span": 3}
CONFOUNDED_ALONE = {("two-span", "support_rotational_spring")}


def six_tiltmeters(case):
    """``case`` with six tiltmeters evenly from 0.1 L to 0.9 L (the top of the issue's 2-6 sensor range)."""
    length = case.bridge.length
    std = float(case.noise.std[0])
    names = [f"T{i + 1}" for i in range(6)]
    sensors = sp.SensorLayout(np.linspace(0.1 * length, 0.9 * length, 6), "rotation", names, [std] * 6)
    return case.with_sensors(sensors, sp.NoiseModel([std] * 6, case.noise.correlation_length))


def n_crossings(seed):
    """8, 10, 12 crossings (the acceptance range of issue 18) by seed."""
    return 8 + 2 * (seed % 3)


def settled(case, support):
    vert = list(case.bridge.vertical_springs)
    span = case.bridge.spans[min(max(support, 0), len(case.bridge.spans) - 1)]
    vert[support] = 2.0 * 48 * float(np.median(case.ei)) / span**3
    return replace(case, bridge=sp.Bridge(case.bridge.spans, case.bridge.rotational_springs, tuple(vert)))


def rotated(case, support):
    """Rotational restraint at ``support`` changed as ``effects_data.generate`` changes it."""
    rot = list(case.bridge.rotational_springs)
    ei0 = float(np.median(case.ei))
    span = case.bridge.spans[min(support, len(case.bridge.spans) - 1)]
    rot[support] = 3.0 * ei0 / span if rot[support] == 0 else 0.3 * rot[support]
    return replace(case, bridge=sp.Bridge(case.bridge.spans, tuple(rot), case.bridge.vertical_springs))


def run_one(bridge, first, second, seed, six=False):
    case = six_tiltmeters(make_case(bridge)) if six else make_case(bridge)
    truth = settled(case, BRIDGES[bridge]) if first == VERTICAL else rotated(case, ROTATES[bridge])
    rng = np.random.SeedSequence((list(BRIDGES).index(bridge), SECOND.index(second), seed, 2 + FIRST.index(first)))
    data = generate(truth, second, rng, n_crossings(seed))
    t0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = sp.diagnose(case, data)
    cpu = time.process_time() - t0
    return d, cpu


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first", choices=FIRST, nargs="*", default=list(FIRST))
    ap.add_argument("--bridges", choices=list(BRIDGES), nargs="*", default=list(BRIDGES))
    ap.add_argument("--six", action="store_true", help="six tiltmeters from 0.1 L to 0.9 L instead of the case's")
    args = ap.parse_args(argv)
    rows = []
    for first in args.first:
        for bridge in args.bridges:
            for second in SECOND:
                for seed in range(args.seeds):
                    d, cpu = run_one(bridge, first, second, seed, six=args.six)
                    both = set(d.causes) == {first, second}
                    conf = {c.name for c in d.confounded}
                    # lenient: the causes named are true ones, and a true effect not named is reported as
                    # confounded with an EI change (a plausible EI change absorbs it), no unexplained gap
                    lenient = both or (set(d.causes) <= {first, second} and not d.unexplained
                                       and {first, second} - set(d.causes) <= conf)
                    rows.append((bridge, first, second, seed, both, d.causes, cpu, lenient))
                    bfs = " ".join(f"{e.name[:10]}={e.log_bayes_factor:.0f}" for e in d.effects[:4])
                    conf = ",".join(c[:10] for c in conf)
                    print(f"  {bridge:11s} {first[:8]} + {second:15s} seed {seed} ({n_crossings(seed)} cr): causes "
                          f"{', '.join(d.causes) or '-'} -> {'both' if both else 'NOT'} (cpu {cpu:.1f} s) "
                          f"[{bfs}] conf [{conf}] {'unexpl' if d.unexplained else ''}", flush=True)
    for first in args.first:
        for bridge in args.bridges:
            sub = [r for r in rows if r[1] == first and r[0] == bridge]
            print(f"{first} + second on {bridge}: both named and nothing else {sum(r[4] for r in sub)}/{len(sub)}, "
                  f"or the other one confounded with EI {sum(r[7] for r in sub)}/{len(sub)}")
    k = sum(r[4] for r in rows)
    print(f"with the missing one reported confounded with EI: {sum(r[7] for r in rows)}/{len(rows)}")
    fair = rows if args.six else [r for r in rows if (r[0], r[1]) not in CONFOUNDED_ALONE]
    if len(fair) < len(rows):
        kf = sum(r[4] for r in fair)
        print(f"both named and nothing else where each effect is detectable alone: {kf}/{len(fair)} = "
              f"{100 * kf / max(len(fair), 1):.0f} %")
    over = sum(r[6] > 15.0 for r in rows)
    print(f"cpu above 15 s: {over}/{len(rows)}")
    print(f"\nboth effects named and nothing else: {k}/{len(rows)} = {100 * k / len(rows):.0f} % (target >= 67 %); "
          f"cpu median {np.median([r[6] for r in rows]):.1f} s, max {max(r[6] for r in rows):.1f} s")


if __name__ == "__main__":
    main()
