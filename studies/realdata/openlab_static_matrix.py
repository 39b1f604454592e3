"""openLAB PE 2.1 static steps: invert and diagnose on every case variant with each laser withheld in turn.

Data: Herbers, Richter, Walker, Marx (TU Dresden), DOI 10.25532/OPARA-852,
CC BY-SA 4.0 (the derived plateau table of ``openlab_pe21.py``).

For each case variant (pins, a vertical bearing spring at x = 30 m, the
frame springs of openlab_pe21.py) and nominal EI (5e8, 1e9 and 2e9 N m^2:
the effective EI of span 2 is about 5.4e8, so 1e9 is 2x and 2e9 4x too
high), with each laser withheld in turn, on load steps 1-2:

* ``invert`` (defaults: hyperparameters integrated, damage detector on) and
  ``diagnose`` (all effects) must run: no exception, no numerical failure;
  the detector says which zones are testable, or in one line that none is.
* the withheld laser is predicted from invert's posterior (400 draws of
  the posterior mixture plus the estimated noise): the 95 % band must hold
  the measured readings where the model is right (a rigid support cannot
  predict the bearing laser LWA_5, nor a model without the pier's
  stiffness the pier laser's zero reading; those rows are reported, not
  judged).

The setting is that of a user running ``sensorplan invert --elements 30``
on these data: 30 elements and the default prior ``GMRFPrior()``, with the
overall level of log EI an unknown of its own (``level_std`` 1: a factor e
at one sd).  ``--no-level`` runs the same matrix with the level held by the
elements' prior alone (std 0.5 / sqrt(30) = 0.09, the behaviour before
issue 36): that is where a nominal EI off by 2x went into the bearing
spring (k -> 1e7 N/m, the withheld LWA_5 predicted at 1.7-5.5 mm against
0.7 mm read) or into sensor gains.  ``--span-mesh`` uses the study's
one EI per span and its prior instead.

Run: python studies/realdata/openlab_static_matrix.py [--no-level] [--span-mesh] [--quick]

Measured 2026-11-27 on branch ``static2`` (commit 6e471eb plus its residual test; the rows are identical
at 6e471eb), the shared 2-core machine at load 12-15, one thread: about 80 s of CPU per matrix (52 s user,
28 s system), 120 MB peak.  Left: the default prior (``level_std`` 1); right: ``--no-level``.  "level"
is the posterior mean of log EI minus its nominal; "in band" whether the withheld laser's two readings
lie in their 95 % predictive band (n/a: pins cannot predict the bearing laser)::

    variant        EI      held  inv diag verdict           level in band | inv diag verdict           level in band
    pins           5.0e+08 LWA_1 ok  ok   model_error        0.28 NO      | ok  ok   model_error        0.16 NO
    pins           5.0e+08 LWA_2 ok  ok   model_error        0.34 yes     | ok  ok   model_error        0.16 yes
    pins           5.0e+08 LWA_3 ok  ok   model_error        0.32 yes     | ok  ok   model_error        0.14 yes
    pins           5.0e+08 LWA_4 ok  ok   model_error        0.45 NO      | ok  ok   model_error        0.18 yes
    pins           5.0e+08 LWA_5 ok  ok   model_error        0.35 n/a     | ok  ok   model_error        0.17 n/a
    pins           1.0e+09 LWA_1 ok  ok   model_error       -0.41 NO      | ok  ok   model_error       -0.21 NO
    pins           1.0e+09 LWA_2 ok  ok   model_error       -0.35 yes     | ok  ok   model_error       -0.17 yes
    pins           1.0e+09 LWA_3 ok  ok   model_error       -0.37 yes     | ok  ok   model_error       -0.16 yes
    pins           1.0e+09 LWA_4 ok  ok   model_error       -0.23 NO      | ok  ok   model_error       -0.10 NO
    pins           1.0e+09 LWA_5 ok  ok   model_error       -0.34 n/a     | ok  ok   model_error       -0.17 n/a
    pins           2.0e+09 LWA_1 ok  ok   model_error       -1.10 NO      | ok  ok   model_error       -0.05 yes
    pins           2.0e+09 LWA_2 ok  ok   model_error       -1.04 yes     | ok  ok   model_error       -0.05 yes
    pins           2.0e+09 LWA_3 ok  ok   model_error       -1.06 yes     | ok  ok   model_error       -0.04 yes
    pins           2.0e+09 LWA_4 ok  ok   model_error       -0.92 NO      | ok  ok   model_error       -0.05 NO
    pins           2.0e+09 LWA_5 ok  ok   model_error       -1.03 n/a     | ok  ok   model_error       -0.05 n/a
    bearing spring 5.0e+08 LWA_1 ok  ok   insufficient_data  0.33 NO      | ok  ok   model_error        0.19 NO
    bearing spring 5.0e+08 LWA_2 ok  ok   model_error        0.38 yes     | ok  ok   model_error        0.18 yes
    bearing spring 5.0e+08 LWA_3 ok  ok   model_error        0.37 yes     | ok  ok   model_error        0.16 yes
    bearing spring 5.0e+08 LWA_4 ok  ok   model_error        0.49 NO      | ok  ok   model_error        0.19 yes
    bearing spring 5.0e+08 LWA_5 ok  ok   model_error        0.40 yes     | ok  ok   model_error        0.18 yes
    bearing spring 1.0e+09 LWA_1 ok  ok   departure         -0.36 NO      | ok  ok   departure         -0.20 NO
    bearing spring 1.0e+09 LWA_2 ok  ok   model_error       -0.30 yes     | ok  ok   model_error       -0.15 yes
    bearing spring 1.0e+09 LWA_3 ok  ok   model_error       -0.32 yes     | ok  ok   model_error       -0.14 yes
    bearing spring 1.0e+09 LWA_4 ok  ok   model_error       -0.20 NO      | ok  ok   model_error       -0.09 NO
    bearing spring 1.0e+09 LWA_5 ok  ok   model_error       -0.28 yes     | ok  ok   model_error       -0.02 NO
    bearing spring 2.0e+09 LWA_1 ok  ok   departure         -1.05 NO      | ok  ok   model_error       -0.05 yes
    bearing spring 2.0e+09 LWA_2 ok  ok   model_error       -0.99 yes     | ok  ok   model_error       -0.05 yes
    bearing spring 2.0e+09 LWA_3 ok  ok   model_error       -1.00 yes     | ok  ok   model_error       -0.05 yes
    bearing spring 2.0e+09 LWA_4 ok  ok   model_error       -0.89 NO      | ok  ok   model_error       -0.05 NO
    bearing spring 2.0e+09 LWA_5 ok  ok   model_error       -0.97 yes     | ok  ok   model_error       -0.04 NO
    frame springs  5.0e+08 LWA_1 ok  ok   insufficient_data  0.24 yes     | ok  ok   insufficient_data  0.11 yes
    frame springs  5.0e+08 LWA_2 ok  ok   model_error        0.27 yes     | ok  ok   model_error        0.11 yes
    frame springs  5.0e+08 LWA_3 ok  ok   insufficient_data  0.23 yes     | ok  ok   insufficient_data  0.09 yes
    frame springs  5.0e+08 LWA_4 ok  ok   insufficient_data  0.32 NO      | ok  ok   insufficient_data  0.09 NO
    frame springs  5.0e+08 LWA_5 ok  ok   insufficient_data  0.29 yes     | ok  ok   model_error        0.11 yes
    frame springs  1.0e+09 LWA_1 ok  ok   departure         -0.45 yes     | ok  ok   departure         -0.23 yes
    frame springs  1.0e+09 LWA_2 ok  ok   model_error       -0.42 yes     | ok  ok   departure         -0.22 yes
    frame springs  1.0e+09 LWA_3 ok  ok   departure         -0.45 yes     | ok  ok   departure         -0.22 yes
    frame springs  1.0e+09 LWA_4 ok  ok   insufficient_data -0.37 NO      | ok  ok   insufficient_data -0.22 NO
    frame springs  1.0e+09 LWA_5 ok  ok   departure         -0.39 yes     | ok  ok   insufficient_data -0.08 NO
    frame springs  2.0e+09 LWA_1 ok  ok   departure         -1.13 yes     | ok  ok   model_error       -0.05 yes
    frame springs  2.0e+09 LWA_2 ok  ok   model_error       -1.11 yes     | ok  ok   model_error       -0.05 yes
    frame springs  2.0e+09 LWA_3 ok  ok   departure         -1.14 yes     | ok  ok   model_error       -0.04 NO
    frame springs  2.0e+09 LWA_4 ok  ok   departure         -1.06 NO      | ok  ok   model_error       -0.05 NO
    frame springs  2.0e+09 LWA_5 ok  ok   departure         -1.07 yes     | ok  ok   model_error       -0.05 NO

Acceptance ("invert and diagnose never fail"): 0 failures of 45 in either matrix (and no failure at
the issue's EI 1e9 and 5e8 for any variant and withheld laser).  The detector found no testable zone
in any row (two steps under the smooth nuisance); it says so in one line.  The level takes up the
nominal's error: about -0.35 at 1e9 and -1.05 at 2e9, i.e. an overall EI near 7e8 whatever the
nominal, where without it the level stays within 0.25 of the nominal.  It repairs the issue's case:
at the nominal 1e9 and 2e9, with the bearing spring or the frame springs and LWA_5 withheld, the
bearing laser is predicted inside its band with the level and outside without it (the error then
goes into the bearing spring, k down to 4e6 N/m).  Withheld laser inside its band: 27 of 42 judged
rows with the level, 26 of 42 without.  The misses are mostly LWA_1 (span 1, read -0.97 and -1.65 mm)
and LWA_4 (read 5.07 and 10.05 mm): with the level, pins and the bearing spring miss both at every
nominal EI (without it, 2 of 6 such rows are in band each) -- a misfit of the model there that the
level does not cause and does not resolve (left open).  The verdict is mostly model_error because
the estimated noise scale is 2-3.3 times the stated 0.2 mm (checked at 1e9: pins/LWA_1 2.6,
bearing spring/LWA_3 3.3, frame springs/LWA_2 2.1); the residual test now runs on these static
readings (alpha estimated, F) and flagged no laser in the three rows checked (smallest p 0.04).
"""

import argparse
import dataclasses
import importlib.util
import math
import sys
import traceback
import warnings
from pathlib import Path

import numpy as np

import sensorplan as sp
from sensorplan.diagnosis.diagnose import diagnose


def _load(name, file):
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(file))
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up by name
        spec.loader.exec_module(module)
    return sys.modules[name]


pe21 = _load("openlab_pe21", "openlab_pe21.py")
calibration = _load("openlab_null_calibration", "openlab_null_calibration.py")

VARIANTS = calibration.VARIANTS
NOMINAL_EI = (5.0e8, 1.0e9, 2.0e9)  # N m^2
STEPS = (1, 2)
N_DRAWS = 400
N_ELEMENTS = 30


def plateaus():
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
    from realdata_table import plateaus_from_table

    return plateaus_from_table(pe21)


@dataclasses.dataclass(frozen=True)
class Row:
    variant: str
    ei: float
    withheld: str
    invert_ok: bool
    diagnose_ok: bool
    verdict: str
    diagnosis: str
    testable: str
    level: float  # posterior mean of log EI minus its nominal, averaged over the elements
    springs: dict
    measured: tuple  # withheld laser per step [m]
    band: tuple  # ((low, high) per step) [m]
    inside: bool
    gains: tuple  # sensor gains named by diagnose
    error: str = ""


def predict_withheld(case, result, withheld, forces, rng):
    """95 % predictive band [m] of the withheld laser per step, from draws of invert's posterior mixture."""
    mix = result.mixture
    n = result.n_elements
    x = pe21.LASER_X[pe21.LASERS.index(withheld)]
    sensor = sp.SensorLayout([x], kinds="deflection")
    comp = rng.choice(mix.weights.size, size=N_DRAWS, p=mix.weights / mix.weights.sum())
    values = np.empty((N_DRAWS, forces.size))
    for k, c in enumerate(comp):
        theta = rng.multivariate_normal(mix.thetas[c], mix.covariances[c])
        bridge = case.bridge
        if result.n_springs:
            bridge = bridge.with_spring_stiffness(np.exp(theta[n:]))
        line = sp.influence_lines(bridge, case.mesh, np.exp(theta[:n]), sensor, case.vehicle, [pe21.LOAD_X])
        noise = result.noise_scale * pe21.NOISE_STD * rng.standard_normal(forces.size)
        values[k] = line.predictions[0, 0] * forces / pe21.NOMINAL_LOAD + noise
    return tuple(map(tuple, np.quantile(values, [0.025, 0.975], axis=0).T))


def run_one(plats, variant, ei, withheld, prior, *, effects=None, elements=N_ELEMENTS):
    """One cell of the matrix (exceptions are caught and reported: the acceptance is that there are none)."""
    chosen = [p for p in plats if p.step in STEPS]
    kept = tuple(n for n in pe21.LASERS if n != withheld)
    case = pe21.make_case(ei=ei, **VARIANTS[variant])
    if elements:
        case = case.with_mesh(sp.Mesh.uniform(case.bridge, elements))
    data = pe21.make_crossings(chosen).sensor_subset(kept)
    forces = np.array([p.force for p in chosen])
    measured = tuple(float(p.deflection[pe21.LASERS.index(withheld)]) for p in chosen)
    blank = dict(verdict="-", diagnosis="-", testable="-", level=math.nan, springs={}, band=(), inside=False,
                 gains=())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sp.SensorplanWarning)
        try:
            result = sp.invert(case, data, prior=prior)
        except Exception:  # noqa: BLE001 - the matrix records any failure
            return Row(variant, ei, withheld, False, False, measured=measured, error=traceback.format_exc(-1),
                       **blank)
        d = result.damage
        blank.update(verdict=result.verdict.status, testable=(
            "none" if d is None or not d.testable else ", ".join(f"{a:.0f}-{b:.0f}" for a, b in d.testable_stretches)),
            level=float(np.mean(result.theta[:result.n_elements] - np.log(result.ei_nominal))),
            springs={k: v["map"] for k, v in result.springs().items()})
        band = predict_withheld(case, result, withheld, forces, np.random.default_rng(0))
        blank.update(band=band, inside=all(lo <= m <= hi for m, (lo, hi) in zip(measured, band)))
        try:
            diag = diagnose(case, data, prior=prior, effects=effects)
        except Exception:  # noqa: BLE001
            return Row(variant, ei, withheld, True, False, measured=measured, error=traceback.format_exc(-1), **blank)
    blank.update(diagnosis=diag.verdict.status if diag.verdict else "-",
                 gains=tuple(c for c in diag.causes if "gain" in c))
    return Row(variant, ei, withheld, True, True, measured=measured, **blank)


def model_is_right(variant, withheld):
    """Whether the variant can predict the withheld laser at all (see the module docstring)."""
    return not (variant == "pins" and withheld == "LWA_5")


def main(level=True, quick=False, span_mesh=False):
    prior = pe21.PRIOR if span_mesh else sp.GMRFPrior()
    prior = prior if level else dataclasses.replace(prior, level_std=0.0)
    elements = None if span_mesh else N_ELEMENTS
    plats = plateaus()
    print(f"openLAB PE 2.1 static steps {STEPS}: invert and diagnose with each laser withheld; prior {prior}")
    print(f"  {'variant':>14s} {'EI':>7s} {'held':>5s} {'inv':>4s} {'diag':>4s} {'verdict':>17s} "
          f"{'diagnosis':>17s} {'level':>6s} {'springs (MAP)':>40s} {'measured [mm]':>13s} {'95 % band [mm]':>27s} "
          f"in  testable zones")
    rows = []
    for variant in VARIANTS:
        for ei in NOMINAL_EI[1:2] if quick else NOMINAL_EI:
            for withheld in pe21.LASERS:
                r = run_one(plats, variant, ei, withheld, prior, effects=["vertical_support_spring"] if quick else None,
                            elements=elements)
                rows.append(r)
                springs = " ".join(f"{k[:4]}{k[-1]}={v:.2g}" for k, v in r.springs.items())
                band = " ".join(f"{1e3 * lo:.2f}..{1e3 * hi:.2f}" for lo, hi in r.band)
                flag = ("yes" if r.inside else "NO") if model_is_right(variant, withheld) else "(n/a)"
                print(f"  {variant:>14s} {ei:7.1e} {withheld:>5s} {'ok' if r.invert_ok else 'FAIL':>4s} "
                      f"{'ok' if r.diagnose_ok else 'FAIL':>4s} {r.verdict:>17s} {r.diagnosis:>17s} {r.level:6.2f} "
                      f"{springs:>40s} {' '.join(f'{1e3 * m:.2f}' for m in r.measured):>13s} {band:>27s} {flag:>5s}  "
                      f"{r.testable}" + (f"  gains named: {', '.join(r.gains)}" if r.gains else ""), flush=True)
                if r.error:
                    print("    " + r.error.strip().replace("\n", "\n    "))
    judged = [r for r in rows if model_is_right(r.variant, r.withheld)]
    print(f"  failures: invert {sum(not r.invert_ok for r in rows)}, diagnose {sum(not r.diagnose_ok for r in rows)} "
          f"of {len(rows)}; withheld laser inside its 95 % band in {sum(r.inside for r in judged)} of {len(judged)} "
          f"rows where the model can predict it")
    return rows


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-level", action="store_true", help="the prior without the overall level of log EI")
    parser.add_argument("--quick", action="store_true", help="EI 1e9 only and one candidate effect in diagnose")
    parser.add_argument("--span-mesh", action="store_true", help="one EI per span and openlab_pe21.py's prior")
    args = parser.parse_args()
    main(level=not args.no_level, quick=args.quick, span_mesh=args.span_mesh)
