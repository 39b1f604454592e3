"""Two withheld effects at once: are both named, and nothing else (issue 18, >= 2 of 3)?

The truth has a support effect *and* a second effect from
``effects_data.generate`` (sensor offsets, thermal drift, axle loads,
load-position offsets, a sign-flipped sensor); the diagnosis gets the
nominal case.  Support effects: a settling bearing (a vertical spring of
2 x 48 EI / L^3, as ``effects_data.generate`` sets it for the single
effect; the right bearing of the single span, the middle one of the
two-span bridge) or a changed rotational restraint (3 EI / L at a pin, as
``generate`` does; the left support of the single span, the middle support
of the two-span bridge).  Bridges: the single span of ``validation.py``
(two axles) and the openLAB-like two-span bridge; 8, 10 or 12 crossings by
seed (the acceptance range), white noise, three seeds.

Scored per dataset: both effects among the causes and no other cause
(strict); also, leniently, the causes named are true ones and a true effect
not named is reported as confounded with an EI change, with no unexplained
gap.

Run: python studies/diagnosis/pairs.py [--seeds N] [--first ...] [--bridges ...]

Last run (2026-11-25, stepwise selection with the ambiguity rule; two processes, one per
support effect, on a shared 2-core machine):
  vertical spring + second: both named and nothing else 21/30 = 70 % (single span 12/15,
  two-span 9/15); lenient 26/30.  Same protocol with the previous forward selection + swap:
  15/30 (single span 12/15, two-span 3/15: an extra sensor_gain with offsets or drift 6/6).
  rotational spring + second: 13/30 = 43 % (single span 12/15, two-span 1/15); lenient
  27/30.  Previous: 9/30.  On the two-span bridge a rotational restraint at the middle support
  is not detectable with the two tiltmeters (screening log BF -1 to 1 even alone): it is
  reported as confounded with EI in 12/15.
  All 60: 34/60 = 57 % strict (previous 24/60), 53/60 lenient.
  Misses (vertical): axle loads + spring 4/6 (the axle-load error is confounded with EI: given
  the spring its log BF is -3 to 0; named when it is not, 12 crossings single span); single-span
  position offset + spring seed 2 (an extra axle_loads, final fit not converged); two-span drift +
  spring seed 2 (an extra sensor_gain); two-span sign flip + spring seeds 1, 2 (position offsets
  or axle loads absorb the flip first).
  CPU per dataset: vertical median 11.4 s, max 55.6 s (two-span sign flip + spring); rotational
  median 9.5 s, max 20.2 s; 13 of the 60 above 15 s (NOT met for pairs; the single-effect
  datasets of validation.py and bench_diagnose.py are all below 12 s).
Previous record (2026-11-24, 6 crossings, vertical spring only, two seeds): 12/20.
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
BRIDGES = {"single-span": -1, "two-span": 1}  # the support that settles (vertical spring)
ROTATES = {"single-span": 0, "two-span": 1}  # the support whose rotational restraint changes


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


def run_one(bridge, first, second, seed):
    case = make_case(bridge)
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
    args = ap.parse_args(argv)
    rows = []
    for first in args.first:
        for bridge in args.bridges:
            for second in SECOND:
                for seed in range(args.seeds):
                    d, cpu = run_one(bridge, first, second, seed)
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
    print(f"\nboth effects named and nothing else: {k}/{len(rows)} = {100 * k / len(rows):.0f} % (target >= 67 %); "
          f"cpu median {np.median([r[6] for r in rows]):.1f} s, max {max(r[6] for r in rows):.1f} s")


if __name__ == "__main__":
    main()
