"""Two withheld effects at once: are both named, and nothing else (issue 18, >= 2 of 3)?

The truth has a settling bearing (a vertical spring of 2 x 48 EI / L^3 at a
rigid support, as ``effects_data.generate`` sets it for the single effect)
*and* a second effect from ``effects_data.generate`` (sensor offsets,
thermal drift, axle loads, load-position offsets, a sign-flipped sensor);
the diagnosis gets the nominal case.  Bridges: the single span of
``validation.py`` (two axles) with the right bearing settling, and the
openLAB-like two-span bridge with the middle bearing settling; 6 crossings,
white noise, two seeds.

Scored per dataset: both effects among the causes and no other cause.

Run: python studies/diagnosis/pairs.py [--seeds N]

Last run (2026-11-24, with the swap pass): both named and nothing else in 12/20
= 60 % (target >= 67 %: NOT met); CPU median 4.2 s, max 7.5 s.  Right: every
single-span pair but axle loads (sensor offset, drift, position offset, sign
flip, both seeds), two-span position offset and sign flip.  Missed: axle loads
with the spring (4/4: the spring is named, the axle loads are confounded with
EI and not added); two-span offsets + spring (2/2: offsets only, the 2
tiltmeters cannot separate the settlement from the offsets); two-span drift +
spring (2/2: drift, spring and an extra sensor_gain).
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

SPRING = "vertical_support_spring"
SECOND = ("sensor_offset", "thermal_drift", "axle_loads", "position_offset", "sensor_gain")
BRIDGES = {"single-span": -1, "two-span": 1}  # the support that settles


def settled(case, support):
    vert = list(case.bridge.vertical_springs)
    span = case.bridge.spans[min(max(support, 0), len(case.bridge.spans) - 1)]
    vert[support] = 2.0 * 48 * float(np.median(case.ei)) / span**3
    return replace(case, bridge=sp.Bridge(case.bridge.spans, case.bridge.rotational_springs, tuple(vert)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    args = ap.parse_args(argv)
    rows = []
    for bridge, support in BRIDGES.items():
        case = make_case(bridge)
        truth = settled(case, support)
        for second in SECOND:
            for seed in range(args.seeds):
                rng = np.random.SeedSequence((list(BRIDGES).index(bridge), SECOND.index(second), seed, 2))
                data = generate(truth, second, rng, 6)
                t0 = time.process_time()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    d = sp.diagnose(case, data)
                cpu = time.process_time() - t0
                both = set(d.causes) == {SPRING, second}
                rows.append((bridge, second, seed, both, d.causes, cpu))
                print(f"  {bridge:12s} {SPRING} + {second:15s} seed {seed}: causes {', '.join(d.causes) or '-'}"
                      f" -> {'both, nothing else' if both else 'NOT'} (cpu {cpu:.1f} s)", flush=True)
    k = sum(r[3] for r in rows)
    print(f"\nboth effects named and nothing else: {k}/{len(rows)} = {100 * k / len(rows):.0f} % (target >= 67 %); "
          f"cpu median {np.median([r[5] for r in rows]):.1f} s, max {max(r[5] for r in rows):.1f} s")


if __name__ == "__main__":
    main()
