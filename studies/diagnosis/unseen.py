"""The diagnosis on bridges it was never tuned on: random cases, one or two withheld effects (issue 18).

validation.py and pairs.py use three fixed bridges; the acceptance of issue
18 is checked on bridges nobody has seen.  This study draws each case at
random -- one to three spans of 12-35 m, EI 3e9-4e10 N m^2 per span, pinned
or elastically restrained ends, rigid or elastic interior bearings, a two- or
three-axle vehicle, two to six tiltmeters anywhere on the bridge, white or
AR(1) noise at 1/40-1/150 of the peak rotation, 8-12 crossings -- and
generates the data with ``effects_data.generate`` (a finer truth mesh, the
effect applied directly, never through the effect library):

- single: each library effect, effect-free controls, local damage (EI 30 %
  lower over a fifth of a span) and the out-of-library vibration; after the
  pairs (the earlier datasets keep their indices), shear deformation and a
  bearing that lifts off (two spans or more), both from the study's own
  Timoshenko beam (beam_fe.py);
- pairs: two library effects at once.

Scored as in validation.py (top cause right, or the true effect reported as
confounded with EI, or the case's elastic springs estimated as in invert;
a control adequate; an effect outside the library unexplained with no cause
named, leniently unexplained at all) and pairs.py (both named and nothing
else; leniently, the causes named are true and a missing one is reported as
confounded with EI, or as held by a named cause as a special case: sensor
offsets inside thermal drift).

Run: python studies/diagnosis/unseen.py [--cases N] [--pairs N] [--workers 2] [--seed S]
     [--effects E ...] [--step M] [--correlation M]
(--effects: only the single datasets of these effects; --correlation: every dataset's noise AR(1) with that
correlation length.)

Issue 37 (before -> after picks that leave a significant gap are no longer named and the systematic gap test
whitens AR(1) residuals; two workers beside other jobs):
  --seed 2026 --cases 2 --pairs 24: singles 27/30 -> 30/30 (library 20/20, controls 2/2 both; outside the
  library unexplained with no cause named 3/6 -> 6/6); pairs 19/24 and 19/24, lenient 24/24.
  --seed 3737 --cases 4 --pairs 0 (blind): 52/60 -> 60/60 (library 40/40, controls 4/4 both; outside 4/12 ->
  12/12: shear deformation 0/4 -> 4/4, lift-off 0/4 -> 4/4, vibration 4/4).
  --seed 4242 --cases 24 --effects none: controls adequate 24/24 -> 24/24.
  --seed 4343 --cases 24 --effects none --step 0.1 --correlation 1.0: controls adequate 20/24 -> 24/24 (the
  four were "unexplained": the unwhitened mean-residual test of correlated noise).
  --seed 4444 --cases 6 --effects vibration shear_deformation bearing_liftoff: 6/18 -> 18/18.

First run (2026-11-26, fifth session, --cases 4 --pairs 45, before the two changes below):
single effects 51/52 (a settled bearing on three spans named as sensor offsets with a gap: the
base EI twisted over five orders of magnitude to mimic it, and the bearing's fit from there
stopped at log BF 395 against 738 for offsets); pairs 32/45 = 71 % strict, 43/45 lenient (a
flipped sensor next to a settled end bearing: unexplained).
After (a) support-spring fits also started from the nominal EI when the base noise scale is
above 3 and the warm start does not converge, and (b) the look-ahead pick of
diagnosis/selection.py: the same run 52/52 and 33/45 = 73 %, lenient 44/45; nothing else
changed.
Last run (same day, final code, --cases 4 --pairs 90, one worker beside other jobs):
  single effects: 52/52 (every library effect 4/4 on four different bridges; controls,
  local damage 4/4 with no cause; vibration 4/4 unexplained); held-out rms after within 20 %
  of the noise 39/39 (max 1.02); CPU median 1.9 s, max 9.7 s.
  pairs: 69/90 = 77 % both named and nothing else (target >= 67 %); lenient 88/90 (the causes
  named are true, the missing one reported as confounded with EI).  Misses: a rotational
  restraint not named next to another effect (10, confounded), an axle-load error not named
  (7, confounded: only the axle ratios are identifiable once a spring is free), a settled
  bearing next to offsets or amplification (2), and two that are not lenient: dynamic
  amplification with load-dependent stiffness (nested: a per-crossing factor absorbs a
  per-crossing EI scale on a bridge without elastic springs; named as its alternative) and
  thermal drift with a settled bearing (drift named, the gap left unexplained).
  CPU median 5.3 s, max 31.1 s; 7/90 above 15 s: three spans with 5-6 tiltmeters and
  0.1 m steps with load-position offsets, load-dependent stiffness or a flipped sensor, where
  every refit forms the lines of every crossing anew (the slowest, 31 s, took 37 s on the code
  before this session; a final refit with its hyperparameters of 7.7 s of it).  So the 15 s
  target is not met on every random bridge of this size.
Then (same day: also a third pass for a leading candidate still crawling, and swap fits limited
to 15 steps): --cases 6 --pairs 0 --seed 7: 77/78 (library 59/60; six moved sensors on 0.2
micro-radian data now named, log BF 342, where the fit had been flagged at 55 iterations; the
miss: an axle-load error on two tiltmeters, log BF 1.3, left as a gap with the axle loads
listed confounded); CPU median 2.0 s, max 6.8 s.  --cases 0 --pairs 90 (a fresh sample, indices
0-89, two workers on the two cores): 78/90 = 87 % both named and nothing else, lenient 90/90;
held-out within 20 % 78/78 (max 1.07); CPU median 6.0 s, max 28.0 s, 5/90 above 15 s
(load-dependent stiffness with a flipped sensor or a changed restraint on 5-6 tiltmeters,
23-28 s; 35 s before the swap limit).
Sixth session (same day; each dataset now also times one default invert of the same data, and
the ratio is reported): after the speed changes (force method and line interpolant split where EI
enters, interpolation maps kept, the element kernel only for Jacobians, a crossing's EI factor
without a solve on bridges without elastic springs, the nominal start of a spring fit only while
its starting model is distorted): --cases 0 --pairs 90 --workers 1 (pairs.py beside it): the same
90 verdicts (78/90, lenient 90/90); CPU median 3.5 s, max 13.1 s, none above 15 s; ratio to
invert median 4.9x, max 44.9x, one above 20x (index 17: thermal drift + a settled end bearing on
one 24.6 m span with 4 tiltmeters, 9-13 s against an invert of 0.3 s; position offsets picked
first and dropped two steps later, about 50 refits); the next largest ratios 15.7x, 15.4x.
--cases 4 --pairs 0 --workers 1: the same 52/52; CPU median 1.8 s, max 8.0 s; ratio median
4.2x, max 11.0x.
Seventh session (same day; a selection step's later candidates give up below the evidence an
earlier one reached and are continued if that leader then fails the tests, swap tests give up at
the pace of their last steps, the look-ahead also past a weaker passing candidate, the effect
columns mapped onto the bins in one product; one worker, another study beside it; verdicts
compared dataset by dataset with runs of the code before):
  --cases 0 --pairs 90: the same 90 verdicts (78/90, lenient 90/90); CPU median 4.1 s, max 10.9 s;
  ratio median 4.8x, max 18.0x (index 17, which was 44.9x: 3.9 s now, thermal drift and the
  bearing picked together by the look-ahead instead of going through load-position offsets).
  --cases 4 --pairs 90: the same 142 verdicts; singles 52/52; pairs 69/90 = 77 %, lenient 88/90;
  CPU median 3.6 s, max 15.4 s, one above 15 s (index 107: three spans, six tiltmeters, 0.1 m
  steps, 12 crossings, load-position offsets + a changed restraint: 21.5-23.7 s before this
  session's changes; invert of the same data takes 22 s itself); ratio median 4.6x, max 22.8x
  (index 108, 5.4 s against an invert of 0.24 s; 15.4x in the run before).
  --seed 11 --cases 2 --pairs 60 (a fresh sample, run before and after the changes): the same 86
  verdicts; singles 26/26; pairs 53/60 = 88 %, lenient 59/60 -> 60/60 once a true effect held by a
  named cause counts (sensor offsets + thermal drift: drift named, offsets reported under
  `includes`); CPU max 16.9 s -> 13.1-13.9 s (sensor offsets + a flipped sensor on three spans),
  none above 15 s; ratio median 4.4-4.7x, max 15.9-19.8x.
Eighth session (2026-11-27; the final refit's Levenberg-Marquardt fallback learns the residuals'
own curvature, NL2SOL, and starts where Gauss-Newton got to; the log-EI blocks of every binned
crossing mapped onto the bins in one product; two workers on the two cores):
  --cases 4 --pairs 90: the same 142 verdicts; singles 52/52 (CPU median 2.4 s, max 6.4 s, ratio
  median 4.7x, max 9.2x); pairs 69/90 = 77 %, lenient 88/90, held-out within 20 % 69/69 (max
  1.08); CPU median 3.7 s, max 15.1 s, one above 15 s (index 107 again: its final refit 5.9 ->
  2.2 s; alone on the machine 12-16 s, the machine's speed drifting); ratio median 4.6x, max
  16.5x, none above 20x (index 108, 22.8x in the run before: 13.4x, 4.1 s).
Ninth session (2026-11-27; the log-EI block of binned crossings never formed, its share of the
normal equations taken from its factors, sensorplan/diagnosis/factored.py; a spring's columns in
one pass):
  --seed 31 --cases 4 --pairs 60 (a fresh sample; one worker; run on the code before the session
  and again after, with other jobs beside it): the same 112 verdicts; singles 52/52 (library
  40/40, controls, local damage and vibration 4/4 each), held-out within 20 % 38/38 (max 1.09),
  CPU median 1.8-2.0 s, max 9.2 s, ratio max 9.5-10.1x; pairs 43/60 = 72 % both named and nothing
  else, lenient 59/60, held-out within 20 % 43/43 (max 1.05), CPU median 3.9-4.6 s, max
  10.7-11.4 s, none above 15 s; ratio median 4.1-4.3x, max 11.3-15.1x.
  --cases 4 --pairs 90 (two workers): the same 142 verdicts; singles CPU median 2.5 s, max 6.8 s;
  pairs CPU median 3.9 s, max 12.3 s, none above 15 s (index 107: 15.1 s in the run before;
  8.5-12.6 s alone as the machine's speed drifted); ratio median 4.1x, max 14.0x.  Index 107
  recorded every 0.05 m instead (same bridge and effects): 14-20 s, invert of the same data
  28-62 s -- what is done per reading doubles; the 15 s target is not met there.
Tenth session (2026-11-27; the effects' columns written in place, per sensor, as products or
column by column; the data gains once per dataset; Nielsen's damping in Levenberg-Marquardt; the
screening continues candidates given up below a leader that fails the tests; --step):
  --cases 4 --pairs 90 (two workers): the same 142 verdicts as the session before; singles CPU
  median 2.2 s, max 6.1 s, ratio max 9.0x; pairs 69/90, CPU median 3.5 s, max 10.0 s (index 107:
  10.0 s), none above 15 s; ratio median 4.3x, max 17.6x (index 108: invert 0.23 s).
  --step 0.05 (the same datasets recorded every 0.05 m), on the code before the session: singles
  51/52, pairs 69/90; pairs CPU median 5.4 s, max 19.4 s, six above 15 s (three spans or two,
  six tiltmeters; invert of the same data up to 44 s); ratio max 13.1x.  With Nielsen's damping
  (before the screening change): pairs 68/90 (index 84, a settled bearing given up below a dynamic
  amplification that failed the held-out test, now 'unexplained'), CPU median 4.7 s, max 14.9 s,
  none above 15 s; ratio max 12.5x.  The screening change gives index 84 back its two causes.
  On the final code: the same 142 verdicts as on the code before the session (singles 51/52,
  pairs 69/90, held-out within 20 % 69/69); pairs CPU median 4.0 s, max 14.4 s (indices 66, 107
  and 115 at 13.7-14.4 s: no margin), none above 15 s; ratio median 2.7x, max 11.6x.
Eleventh session (2026-11-27; the spring columns formed on the bins as a product, the swap pass
not refitting a model the last pick beat in its own step; two workers):
  --cases 4 --pairs 90: the same 142 verdicts; singles CPU median 2.2 s, max 5.5 s, ratio max
  11.6x; pairs 69/90, CPU median 3.1 s, max 8.9 s; ratio median 4.2x, max 15.8x.
  --step 0.05 --kind pairs: the same 90 verdicts (69/90); CPU median 3.6 s, max 11.3 s (indices
  107, 115, 66: 14.3, 14.4, 13.7 -> 11.3, 10.3, 9.8 s); ratio median 2.3x, max 9.3x.
  --step 0.05 --cases 0 --pairs 45 --seed 404 (a fresh dense sample): 36/45 both named, lenient
  42/45, held-out within 20 % 36/36; on the code before the session CPU median 3.6 s, max 17.3 s
  (index 21: a settled bearing and a changed restraint, three spans, five tiltmeters, 1406
  readings per crossing; one above 15 s); after, the same verdicts, median 3.8 s, max 13.4 s,
  none above 15 s; ratio max 7.7x.  Alone, best of three: index 21 11.8 -> 9.4 s, index 27
  12.7 -> 8.7 s.  The unseen random pairs are also scored against the optimal test's limit in
  pairs_limit.py (--unseen 90: oracle 83 %, diagnosis 77 %).
"""

import os
import sys

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parents[1]))  # this checkout's sensorplan

import sensorplan as sp  # noqa: E402
from effects_data import EFFECT_NAMES, OUT_OF_LIBRARY, generate  # noqa: E402

CONTROLS = ("none", "local_damage", "vibration")
OUTSIDE = tuple(e for e in OUT_OF_LIBRARY if e not in CONTROLS)  # drawn after the pairs (their indices kept)
SPRINGS = ("support_rotational_spring", "vertical_support_spring")


def random_case(rng, step=None, *, min_spans=1, correlation=None):
    """A random bridge, vehicle, layout and noise model (the nominal model the diagnosis gets).

    ``step``: the load step [m] instead of the one drawn (the same draws otherwise); ``min_spans``: at
    least this many spans (a bearing that lifts off needs a continuous bridge); ``correlation``: the noise's
    AR(1) correlation length [m] instead of the one drawn.
    """
    n_spans = max(int(rng.integers(1, 4)), min_spans)
    main = rng.uniform(12.0, 35.0)
    spans = [main] if n_spans == 1 else [main * rng.uniform(0.6, 1.0) for _ in range(n_spans)]
    spans = [round(s, 1) for s in spans]
    ei0 = float(np.exp(rng.uniform(np.log(3e9), np.log(4e10))))
    ei = [ei0 * rng.uniform(0.8, 1.25) for _ in spans]
    rot = [0.0] * (n_spans + 1)
    vert = [np.inf] * (n_spans + 1)
    for end in (0, n_spans):
        if rng.random() < 0.4:  # an end restrained by its abutment, estimated with EI (as invert does)
            rot[end] = ei0 / spans[min(end, n_spans - 1)] * rng.uniform(1.0, 5.0)
    for k in range(1, n_spans):
        if rng.random() < 0.4:  # an elastic interior bearing
            vert[k] = 48 * ei0 / spans[k] ** 3 * rng.uniform(10.0, 40.0)
    bridge = sp.Bridge(spans, rot, vert)
    length = bridge.length
    n_elements = int(np.clip(round(length / 0.8), 20, 60))
    n_axles = int(rng.integers(2, 4))
    offsets = np.concatenate([[0.0], np.cumsum(rng.uniform(1.3, 4.5, n_axles - 1))])
    loads = rng.uniform(20e3, 120e3, n_axles)
    vehicle = sp.Vehicle(tuple(np.round(offsets, 2)), tuple(np.round(loads, -2)))
    n_sensors = int(rng.integers(2, 7))
    while True:
        pos = np.sort(rng.uniform(0.03, 0.97, n_sensors)) * length
        supports = np.concatenate([[0.0], np.cumsum(spans)])
        if np.all(np.diff(pos) > 1.0) and np.min(np.abs(pos[:, None] - supports[None, :])) > 0.5:
            break
    names = [f"T{i + 1}" for i in range(n_sensors)]
    drawn = float(rng.choice([0.1, 0.2, 0.25]))  # drawn in any case: the draws after it stay the same
    step = drawn if step is None else float(step)
    sweep = sp.LoadSweep.from_range(0.0, length + vehicle.length, step)
    mesh = sp.Mesh.uniform(bridge, n_elements)
    trial = sp.Case(bridge, mesh, ei, vehicle, sp.SensorLayout(np.round(pos, 2), "rotation", names, [1e-6] * n_sensors),
                    sweep=sweep)
    peak = np.abs(trial.influence_lines(trial.ei).predictions).max(axis=1)
    std = float(np.median(peak)) / rng.uniform(40.0, 150.0)
    std = float(np.clip(std, 2e-7, 5e-4))
    corr = 0.0 if rng.random() < 0.5 else float(rng.uniform(0.3, 1.0))
    corr = corr if correlation is None else float(correlation)
    sensors = sp.SensorLayout(np.round(pos, 2), "rotation", names, [std] * n_sensors)
    return sp.Case(bridge, mesh, ei, vehicle, sensors, sp.NoiseModel([std] * n_sensors, corr), sweep=sweep,
                   name="random")


def describe_case(case):
    b = case.bridge
    return (f"{'+'.join(f'{s:g}' for s in b.spans)} m, {case.vehicle.n_axles} axles, {case.sensors.n_sensors} tilt, "
            f"{'AR(1)' if case.noise.correlation_length else 'white'}, step {case.sweep.positions[1]:g} m, "
            f"rot {sum(0 < r < np.inf for r in b.rotational_springs)} vert {sum(v < np.inf for v in b.vertical_springs)}")


def dataset(index, effects, seed, step=None, correlation=None, *, noise_free=False):
    """(case, crossings) of dataset ``index``: a random case and 8-12 crossings with ``effects`` withheld.

    ``step``, ``correlation``: the load step and the noise's correlation length instead of those drawn;
    ``noise_free``: the same draws without the noise (pairs_limit.py's oracle).
    """
    ss = np.random.SeedSequence((seed, index))
    case_rng, data_rng = (np.random.default_rng(s) for s in ss.spawn(2))
    case = random_case(case_rng, step, min_spans=2 if "bearing_liftoff" in effects else 1, correlation=correlation)
    n_cr = int(case_rng.integers(8, 13))
    ei = None
    true = tuple(e for e in effects if e in EFFECT_NAMES or e in OUT_OF_LIBRARY)
    if "local_damage" in effects:
        span = case.bridge.spans[0]
        ei_case = case.ei_at
        ei = lambda x: np.where((x > 0.3 * span) & (x < 0.5 * span), 0.7, 1.0) * ei_case(x)  # noqa: E731
    return case, generate(case, true or None, data_rng, n_cr, ei=ei, noise_free=noise_free)


def run_one(job):
    kind, index, effects, seed, *drawn = job  # and the load step and correlation length replacing the drawn ones
    t0 = time.process_time()
    try:
        case, data = dataset(index, effects, seed, *drawn)
        n_cr = len(data.crossings)
        t0 = time.process_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = sp.diagnose(case, data)
            cpu = time.process_time() - t0
            t1 = time.process_time()  # one default invert of the same data: the reference of issue 18's ratio
            sp.invert(case, data)
            invert_cpu = time.process_time() - t1
    except Exception as exc:  # keep the study going; the record says what failed
        return {"kind": kind, "index": index, "effects": effects, "case": "",
                "error": f"{type(exc).__name__}: {exc}", "cpu": time.process_time() - t0}
    causes = tuple(d.causes)
    conf = {c.name for c in d.confounded}
    springs_differ = any(f.differs for f in d.springs)
    lib = [e for e in effects if e in EFFECT_NAMES]
    if kind == "single" and lib:
        e = lib[0]
        right = (causes[:1] == (e,) or (not causes and not d.unexplained and e in conf)
                 or (not causes and e in SPRINGS and springs_differ))
    elif kind == "single" and effects[0] in OUT_OF_LIBRARY:
        # out of the library: unexplained, and no library effect named as a cause
        right = d.unexplained and not causes
    elif kind == "single":
        # the effect-free control: adequate (no cause, no gap left); local damage: no cause
        right = not causes and (effects[0] == "local_damage" or not d.unexplained)
    else:
        right = set(causes) == set(lib)
    # leniently also a true effect that a named cause holds as a special case (sensor offsets inside thermal drift);
    # an out-of-library effect flagged unexplained, if partly explained by library effects
    included = {n for held in d.includes.values() for n in held}
    lenient = right or (kind == "pairs" and set(causes) <= set(lib) and not d.unexplained
                        and set(lib) - set(causes) <= conf | included
                        | ({e for e in SPRINGS} if springs_differ else set())) or (
        kind == "single" and effects[0] in OUT_OF_LIBRARY and d.unexplained)
    return {"kind": kind, "index": index, "effects": effects, "case": describe_case(case), "crossings": n_cr,
            "causes": causes, "confounded": sorted(conf), "unexplained": bool(d.unexplained),
            "springs_differ": springs_differ, "right": bool(right), "lenient": bool(lenient), "cpu": cpu,
            "invert_cpu": invert_cpu,
            "heldout": float("nan") if d.heldout_ratio_after is None else d.heldout_ratio_after,
            "bfs": " ".join(f"{e.name[:10]}={e.log_bayes_factor:.0f}" for e in d.effects[:4]), "error": ""}


def jobs(n_cases, n_pairs, seed):
    """(kind, index, effects, seed) of every dataset: singles, pairs, then the singles outside the library
    that came later (after the pairs, so that the earlier datasets keep their indices and draws)."""
    rng = np.random.default_rng(seed)
    out = []
    index = 0
    singles = list(EFFECT_NAMES) + list(CONTROLS)
    for _ in range(n_cases):
        for e in singles:
            out.append(("single", index, (e,), seed))
            index += 1
    for _ in range(n_pairs):
        a, b = rng.choice(len(EFFECT_NAMES), 2, replace=False)
        out.append(("pairs", index, (EFFECT_NAMES[a], EFFECT_NAMES[b]), seed))
        index += 1
    for _ in range(n_cases):
        for e in OUTSIDE:
            out.append(("single", index, (e,), seed))
            index += 1
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=4, help="random bridges per single effect")
    ap.add_argument("--pairs", type=int, default=45, help="random two-effect datasets")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--kind", choices=("single", "pairs", "both"), default="both")
    ap.add_argument("--step", type=float, default=None,
                    help="load step [m] of every dataset instead of the drawn 0.1-0.25 m (a dense record: 0.05)")
    ap.add_argument("--correlation", type=float, default=None,
                    help="AR(1) correlation length [m] of every dataset's noise instead of the drawn 0 or 0.3-1 m")
    ap.add_argument("--effects", nargs="*", default=None, help="only the single-effect datasets of these effects")
    args = ap.parse_args(argv)
    todo = jobs(args.cases, args.pairs, args.seed)
    if args.effects is not None:
        todo = [j for j in todo if j[0] == "single" and j[2][0] in args.effects]
    if args.step is not None or args.correlation is not None:
        todo = [job + (args.step, args.correlation) for job in todo]
    if args.kind != "both":
        todo = [j for j in todo if j[0] == args.kind]
    recs = []
    with ProcessPoolExecutor(args.workers) as pool:
        for r in pool.map(run_one, todo):
            recs.append(r)
            if r["error"]:
                print(f"  {r['index']:3d} {'+'.join(r['effects'])}: ERROR {r['error']} [{r['case']}]", flush=True)
                continue
            print(f"  {r['index']:3d} {'+'.join(r['effects']):45s} -> {', '.join(r['causes']) or '-'}"
                  f"{' unexpl' if r['unexplained'] else ''} {'ok' if r['right'] else ('lenient' if r['lenient'] else 'MISS')}"
                  f" (cpu {r['cpu']:.1f} s, {r['cpu'] / r['invert_cpu']:.1f}x invert, held-out {r['heldout']:.2f})"
                  f" [{r['bfs']}] conf {r['confounded']} "
                  f"[{r['case']}, {r['crossings']} cr]", flush=True)
    for kind in ("single", "pairs"):
        sub = [r for r in recs if r["kind"] == kind]
        if not sub:
            continue
        ok = [r for r in sub if not r["error"]]
        print(f"\n{kind}: right {sum(r['right'] for r in ok)}/{len(sub)}, lenient {sum(r['lenient'] for r in ok)}/"
              f"{len(sub)}, errors {len(sub) - len(ok)}")
        if kind == "single":
            for e in list(EFFECT_NAMES) + list(CONTROLS) + list(OUTSIDE):
                s = [r for r in ok if r["effects"] == (e,)]
                if s:
                    print(f"  {e:27s} {sum(r['right'] for r in s)}/{len(s)}")
            lib = [r for r in ok if r["effects"][0] in EFFECT_NAMES]
            print(f"  library effects: {sum(r['right'] for r in lib)}/{len(lib)}")
            controls = [r for r in ok if r["effects"] == ("none",)]
            print(f"  controls adequate: {sum(r['right'] for r in controls)}/{len(controls)}")
            outside = [r for r in ok if r["effects"][0] in OUT_OF_LIBRARY]
            print(f"  out of the library unexplained with no cause named: {sum(r['right'] for r in outside)}/"
                  f"{len(outside)} (flagged unexplained at all: {sum(r['unexplained'] for r in outside)})")
        cpu = [r["cpu"] for r in ok]
        if cpu:
            print(f"  cpu median {np.median(cpu):.1f} s, max {max(cpu):.1f} s, above 15 s {sum(c > 15 for c in cpu)}")
            ratio = [r["cpu"] / r["invert_cpu"] for r in ok]
            print(f"  ratio to one invert of the same data: median {np.median(ratio):.1f}x, max {max(ratio):.1f}x, "
                  f"above 20x {sum(x > 20 for x in ratio)}")
        fit = [r["heldout"] for r in ok if r["causes"] and r["right"]]
        if fit:
            print(f"  held-out ratio after (right verdicts with causes): within 1.2 {sum(h <= 1.2 for h in fit)}/"
                  f"{len(fit)}, max {max(fit):.2f}")


if __name__ == "__main__":
    main()
