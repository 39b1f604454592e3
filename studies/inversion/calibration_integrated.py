"""Calibration of the credible bands: hyperparameters integrated out versus evidence maximisation.

Well-specified simulation: EI(x) and the spring stiffnesses are drawn from
the prior the inversion uses (the default ``GMRFPrior()``: first-order GMRF
on log EI, smoothness_std 0.1, marginal_std 0.5, spring_std 1), and the data
are simulated with the noise model the inversion assumes.  No inverse crime:
log EI is drawn on the finer, differently aligned truth mesh of the
verification (``truth_mesh``: 4 k + 1 elements in a span of k), from the
discretisation of the same continuous prior,

    Q_fine = k_r tau h_c sum_j (eta_j+1 - eta_j)^2 / dx_j + k_m sum_j eta_j^2 h_j / (h_c marginal_std^2),

(h_c the inversion element length, dx_j the distance of the fine element
midpoints; k_r = k_m = 1 is the plain discretisation, whose element averages
are smoother than the inversion's GMRF: their differences have 0.8 of its
std; k_r and k_m are set so that the element averages have the GMRF's mean
marginal std and mean difference std), and the truth of an inversion
element is the EI equivalent to the fine field (average compliance,
``element_average_ei``).

Cases, on the embedded ``openlab-like`` example (two 15 m spans, rotational
end springs 2e9 and 1e9 N m/rad, which are estimated jointly: 30 elements +
2 springs; tiltmeters PE1, PE2 at 11 and 19 m; a two-axle 48 kN vehicle;
129 positions per crossing):

* ``white``: noise 5 urad, independent, 5 crossings;
* ``ar1``: noise 5 urad, AR(1) along the crossing with correlation length
  0.5 m (lag-one correlation 0.61 at the 0.25 m step), 5 crossings;
* ``low-signal``: noise 10 urad, independent, one crossing.

Every replicate is inverted twice, ``hyper="integrated"`` (the default) and
``hyper="evidence"`` (the point estimate it replaces), with the same data.
Reported per case and method: the average over replicates of the fraction
of elements whose truth lies in the 95 % and 75 % bands (targets 0.92-0.98
and 0.70-0.80), the replicates whose tau reaches a hard end of its range
(integrated: hyper-posterior mass > 1e-3 at an end node cut by the bounds
1e-8, 1e14; evidence: the estimate on those bounds), the replicates whose tau
runs away to a flat field (evidence: tau > 1e8; integrated: more than half of
the hyper-posterior mass above 1e8), the replicates with a fit warning
(noise scale, tau at the bound, systematic residuals; none should fire here),
and the mean time per inversion.

Default hyperprior (log-normal on the smoothness std, median 0.1, log std 0.5), with the damage
detector and the local-loss hypotheses, full mode, 200 replicates per case, seed 20250101,
``--methods integrated`` (2026-11-25, two studies and two other jobs on a 2-core machine):

    case        method         cov95    (se)   cov75    (se)  at bound  flat  warned  nodes  s/inv
    white       integrated     0.963   0.004   0.756   0.010         0     0       0  300.0   0.78
    ar1         integrated     0.965   0.003   0.761   0.009         0     0       1  300.0   0.84
    low-signal  integrated     0.966   0.004   0.753   0.009         0     0       1  237.3   0.50

and with ``--draw-smoothness`` (the truth's smoothness std drawn from the log-normal hyperprior):
white 0.957 / 0.763, ar1 0.949 / 0.739, low-signal 0.956 / 0.747 (95 % / 75 %), tau at a grid end
in 0 replicates.  Misspecification (``--truth-smoothness``, 60 replicates, white): a truth three
times rougher (0.3) is covered 0.822 / 0.557 (PC prior: 0.898 / 0.634), three times smoother (0.03)
0.999 / 0.929 (PC: 0.997 / 0.861).  Tried and not kept (code removed; 95 % / 75 %, 200
replicates unless noted): a Student-t (3 dof) on log sigma: low signal 0.975 (60 replicates),
rough truth 0.863 -- too close to 0.98; PC below the median joined continuously to the log-normal
above it: low signal 0.935 / 0.659, white 0.927 / 0.681 (70 % of the mass on the smooth side:
under-covers); log-normal above and a Cauchy below (joined at the median): low signal
0.960 / 0.728, white 0.949 / 0.727 but tau at the upper grid end in 9 of 200 white replicates;
a Student-t (3 dof) below instead of the Cauchy: low signal 0.963 / 0.744, white 0.957 / 0.748,
ar1 0.962 / 0.753, never at a grid end -- calibrated, and its bands on the undamaged three-span
example are narrower (-19..+27 % against -25..+38 %), but not by enough to justify a
two-piece prior.  The price of the log-normal is on bridges much smoother than the configured
smoothness: the undamaged openlab-like example's 95 % bands are 40 % of EI wide on average
(PC: 29 %), the three-span's -25..+38 % (PC: -10..+11 %).

With the PC hyperprior (``--hyperprior pc``, the previous default), the damage detector and the local-loss hypotheses in the posterior (``detect=True``, the
default; each hypothesis a step of log EI over one of the detector's zones with a half-normal prior
on its size, zones the data do not see left with the undamaged component), full mode, 200
replicates per case, seed 20250101, ``--methods integrated``, commit "detection/scan: the scan in
the element space" (two studies sharing a loaded 2-core machine):

    case        method         cov95    (se)   cov75    (se)  at bound  flat  warned  nodes  s/inv
    white       integrated     0.954   0.007   0.742   0.013         0     0       4  298.6   1.46
    ar1         integrated     0.974   0.003   0.753   0.010         0     0       1  300.0   1.82
    low-signal  integrated     0.984   0.003   0.752   0.010         0     0       1  298.8   1.70

The earlier local-loss hypotheses (the GMRF with its penalty released at a zone's two edges, an
improper release that cost little evidence) kept a posterior probability of 0.3-0.6 on these
undamaged truths and gave 0.929 / 0.709 (white) in quick mode; with the proper step prior the
hypotheses carry a posterior probability of about 0.26 (white, 40 replicates) and 0.07 (low signal,
20 replicates) on the same truths, they change the coverage by about a standard error or less
against the table below (which was measured without them), and the low-signal 95 % band, 0.984, is what the hyperparameter mixture
alone gives (see the note under the table).  ("nodes" counts mixture components, hypotheses
included; the mixture keeps at most 300.)

Results without the damage hypotheses (full mode, 200 replicates per case, seed 20250101, commit "Nodes and the start MAP by
Gauss-Newton with an Armijo line search"; mean coverage +- standard error; times on a busy 2-core
machine):

    case        method         cov95    (se)   cov75    (se)  at bound  flat  warned  nodes  s/inv
    white       integrated     0.962   0.005   0.746   0.013         0     0       0   23.9   0.27
    white       evidence       0.833   0.017   0.665   0.019         1    25       1    1.0   0.33
    ar1         integrated     0.972   0.003   0.751   0.011         0     0       1   28.1   0.13
    ar1         evidence       0.811   0.015   0.647   0.019         2    55       3    1.0   0.18
    low-signal  integrated     0.984   0.003   0.749   0.010         0     0       1   29.2   0.12
    low-signal  evidence       0.779   0.016   0.614   0.021        10   102      11    1.0   0.16

* Integrated: both bands on target (0.92-0.98, 0.70-0.80) except the 95 % band with one crossing
  (0.984): there the data hardly inform tau, and the mixture over the hyperprior's range of
  smoothness has heavier tails than a truth drawn at exactly the median smoothness (its 75 % band
  is on target).  tau never reaches a grid end.  The two warnings are residual tests at
  p = 3e-4 (the same replicates warn under both methods): 2 in 600 inversions against 0.6 expected
  at the family-wise level 1e-3.
* Evidence maximisation covers 0.78-0.83 instead of 0.95; tau runs away above 1e8 (a flat field)
  in 13 %, 28 % and 51 % of the replicates, and onto a hard bound (1e14, or 1e-8 with one
  crossing: a rough field) in up to 5 %; those are also its warnings (tau at the bound).

With ``--draw-smoothness`` (the truth's smoothness std drawn from the hyperprior too, so that the
simulation is exactly the model the integrated method assumes) the integrated coverage is the
nominal one within about a standard error:

    case        method         cov95    (se)   cov75    (se)  at bound  flat  warned  nodes  s/inv
    white       integrated     0.956   0.006   0.767   0.013         0     0       0   23.5   0.20
    white       evidence       0.850   0.016   0.684   0.018         2    38       2    1.0   0.28
    ar1         integrated     0.953   0.007   0.767   0.014         0     0       1   28.0   0.20
    ar1         evidence       0.841   0.016   0.666   0.020         2    68       3    1.0   0.26
    low-signal  integrated     0.954   0.005   0.751   0.013         0     0       0   29.0   0.18
    low-signal  evidence       0.826   0.015   0.676   0.020        11    80      11    1.0   0.26

Run: python studies/inversion/calibration_integrated.py [--quick] [--replicates N] [--seed S]
[--cases ...] [--draw-smoothness] [--methods ...] [--hyperprior lognormal|pc] [--smoothness-log-std S]
[--truth-smoothness S] [--out DIR]
(``--quick``: 40 replicates per case; ``--draw-smoothness`` draws the truth's smoothness std from
the hyperprior as well, the fully Bayesian check; ``--out`` writes the per-replicate numbers as JSON.)
"""

import os
import sys

if "numpy" not in sys.modules:  # run as a script: one BLAS thread (small matrices; threads only slow them)
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this repository's sensorplan

import sensorplan as sp  # noqa: E402
from sensorplan import SensorplanWarning  # noqa: E402
from sensorplan.inference.inversion import invert  # noqa: E402
from sensorplan.io.config import example_case  # noqa: E402
from sensorplan.model.simulate import simulate_crossings  # noqa: E402
from sensorplan.verification.scenarios import element_average_ei, truth_mesh  # noqa: E402

SEED = 20250101
FULL_REPLICATES = 200
QUICK_REPLICATES = 40
PRIOR = sp.GMRFPrior(level_std=0.0)  # the truths are drawn without a separate level (well specified)
# The noise in time of the real Munich inclinometer INC01 (issue #36: 21 urad white per sample, about
# 9 urad correlated over 3 s, +-20-50 urad of minute-scale wander), scaled to the example's 5 urad white
# noise, at a crawl of 1 m/s (3 s = 3 m of load position).
TIME = dict(correlated_std=5e-6 * 9 / 21, correlation_time_s=3.0, random_walk=5e-6 * 2.5 / 21, speed=1.0)
CASES = {  # name: (noise std [rad], correlation length [m], crossings[, time model, inverted as])
    "white": (5e-6, 0.0, 5),
    "ar1": (5e-6, 0.5, 5),
    "low-signal": (10e-6, 0.0, 1),
    "time": (5e-6, 0.0, 5, TIME, "time"),
    "time-as-white": (5e-6, 0.0, 5, TIME, "white"),  # the same data inverted as if the noise were white
}
DEFAULT_CASES = ["white", "ar1", "low-signal", "time"]  # time-as-white: the misspecified comparison, on request
METHODS = ("integrated", "evidence")
FLAT_TAU = 1e8
TARGET_95 = (0.92, 0.98)
TARGET_75 = (0.70, 0.80)


def make_case(std, correlation_length, time=None):
    base = example_case("openlab-like")
    noise = sp.NoiseModel(np.full(base.sensors.n_sensors, std), correlation_length, **(time or {}))
    return dataclasses.replace(base, noise=noise)


def fine_precision(case, fine_mesh, prior, roughness=1.0, marginal=1.0):
    """Precision of log EI on the fine mesh: the discretised continuous form of the inversion's GMRF.

    ``roughness`` and ``marginal`` multiply its two terms (see :func:`matched_fine_precision`).
    """
    h_c = float(np.mean(case.mesh.lengths))
    h_f = fine_mesh.lengths
    dx = np.diff(fine_mesh.midpoints)
    n = fine_mesh.n_elements
    d = np.zeros((n - 1, n))
    d[np.arange(n - 1), np.arange(n - 1)] = -1.0
    d[np.arange(n - 1), np.arange(1, n)] = 1.0
    return (roughness * prior.tau * h_c * (d.T * (1.0 / dx)) @ d
            + marginal * np.diag(h_f / (h_c * prior.marginal_std**2)))


def coarse_moments(case, covariance):
    """Mean marginal std and mean std of one difference of log EI on the inversion mesh."""
    d = np.diff(np.eye(case.n_elements), axis=0)
    return (float(np.mean(np.sqrt(np.diag(covariance)))),
            float(np.mean(np.sqrt(np.diag(d @ covariance @ d.T)))))


def matched_fine_precision(case, fine_mesh, prior):
    """Fine-mesh precision whose element averages have the inversion prior's marginal and difference stds.

    Averaging over an element smooths the field (for a random walk the std of
    a difference of element averages is sqrt(2/3) of that of point values), so
    the two terms of :func:`fine_precision` are rescaled by a fixed-point
    iteration until the averaged field matches the inversion's GMRF in those
    two second moments.
    """
    lo = np.maximum(case.mesh.edges[:-1, None], fine_mesh.edges[None, :-1])
    hi = np.minimum(case.mesh.edges[1:, None], fine_mesh.edges[None, 1:])
    average = np.clip(hi - lo, 0.0, None) / case.mesh.lengths[:, None]
    target = coarse_moments(case, np.linalg.inv(prior.precision(case.n_elements)))
    roughness = marginal = 1.0
    for _ in range(50):
        precision = fine_precision(case, fine_mesh, prior, roughness, marginal)
        implied = coarse_moments(case, average @ np.linalg.inv(precision) @ average.T)
        marginal *= (implied[0] / target[0]) ** 2
        roughness *= (implied[1] / target[1]) ** 2
        if max(abs(implied[0] / target[0] - 1.0), abs(implied[1] / target[1] - 1.0)) < 1e-6:
            break
    return precision


def draw_truth(case, fine_mesh, chol_cov, rng):
    """EI on the fine mesh, its element averages on the inversion mesh, and the spring stiffnesses."""
    fine = case.with_mesh(fine_mesh)
    eta = np.log(fine.ei) + chol_cov @ rng.standard_normal(fine_mesh.n_elements)
    ei_fine = np.exp(eta)
    springs = case.bridge.spring_stiffness() * np.exp(PRIOR.spring_std * rng.standard_normal(
        len(case.bridge.spring_names)))
    return ei_fine, element_average_ei(fine_mesh, ei_fine, case.mesh), springs


def score(result, truth, seconds):
    ci95 = result.credible_interval(0.95)
    ci75 = result.credible_interval(0.75)
    mix = result.mixture
    flat = (float(mix.weights[mix.taus > FLAT_TAU].sum()) > 0.5 if result.hyper_method == "integrated"
            else result.tau > FLAT_TAU)
    return {"coverage95": float(np.mean((truth >= ci95[:, 0]) & (truth <= ci95[:, 1]))),
            "coverage75": float(np.mean((truth >= ci75[:, 0]) & (truth <= ci75[:, 1]))),
            "at_bound": bool(result.tau_mass_at_bound > 1e-3), "flat": bool(flat),
            "warned": bool(result.warnings), "tau": float(result.tau), "noise_scale": float(result.noise_scale),
            "n_components": int(mix.n_components), "seconds": seconds}


def run_case(name, n_replicates, seed, draw_smoothness=False, methods=METHODS, hyperprior=None,
             truth_smoothness=None):
    std, corr, n_crossings, *model = CASES[name]
    case = make_case(std, corr, model[0] if model else None)
    inverted = make_case(std, corr) if model and model[1] == "white" else case
    fine_mesh = truth_mesh(case)
    truth_prior = PRIOR if truth_smoothness is None else dataclasses.replace(PRIOR, smoothness_std=truth_smoothness)
    chol_cov = np.linalg.cholesky(np.linalg.inv(matched_fine_precision(case, fine_mesh, truth_prior)))
    fine = case.with_mesh(fine_mesh)
    records = {m: [] for m in methods}
    children = np.random.SeedSequence([seed, list(CASES).index(name)]).spawn(n_replicates)
    hyperprior = (sp.HyperPrior() if hyperprior is None else hyperprior).for_prior(PRIOR)
    for child in children:
        rng = np.random.default_rng(child)
        if draw_smoothness:  # the smoothness std from the hyperprior too: the fully Bayesian check
            prior = dataclasses.replace(PRIOR, smoothness_std=float(hyperprior.sample_smoothness(rng)))
            chol_cov = np.linalg.cholesky(np.linalg.inv(matched_fine_precision(case, fine_mesh, prior)))
        ei_fine, truth, springs = draw_truth(case, fine_mesh, chol_cov, rng)
        data = simulate_crossings(fine, n_crossings, noise=True, rng=rng, ei=ei_fine,
                                  bridge=case.bridge.with_spring_stiffness(springs))
        for method in methods:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", SensorplanWarning)
                t0 = time.perf_counter()
                result = invert(inverted, data, prior=PRIOR, hyper=method, hyperprior=hyperprior, screen=False,
                                check_scale=False)
                seconds = time.perf_counter() - t0
            records[method].append(score(result, truth, seconds))
    return records


def summarise(records):
    out = {}
    for method, rows in records.items():
        c95 = np.array([r["coverage95"] for r in rows])
        c75 = np.array([r["coverage75"] for r in rows])
        out[method] = {
            "n": len(rows), "coverage95": float(c95.mean()), "se95": float(c95.std(ddof=1) / np.sqrt(c95.size)),
            "coverage75": float(c75.mean()), "se75": float(c75.std(ddof=1) / np.sqrt(c75.size)),
            "at_bound": int(sum(r["at_bound"] for r in rows)), "flat": int(sum(r["flat"] for r in rows)),
            "warned": int(sum(r["warned"] for r in rows)),
            "seconds": float(np.mean([r["seconds"] for r in rows])),
            "components": float(np.mean([r["n_components"] for r in rows])),
        }
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_REPLICATES} replicates per case")
    parser.add_argument("--replicates", type=int, help="replicates per case (overrides --quick)")
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=DEFAULT_CASES)
    parser.add_argument("--draw-smoothness", action="store_true",
                        help="draw the truth's smoothness std from the hyperprior too (fully Bayesian check)")
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS),
                        help="hyperparameter methods compared (default both)")
    parser.add_argument("--smoothness-log-std", type=float,
                        help="log std of the log-normal hyperprior (default: the package's, 0.5)")
    parser.add_argument("--hyperprior", choices=("lognormal", "pc"), default="lognormal",
                        help="family of the smoothness hyperprior (default lognormal, the package's default)")
    parser.add_argument("--truth-smoothness", type=float,
                        help="misspecification check: the truth's smoothness std (the inversion keeps the "
                             f"prior's {PRIOR.smoothness_std})")
    parser.add_argument("--out", type=Path, help="folder for calibration_integrated.json")
    args = parser.parse_args(argv)
    hyperprior = sp.HyperPrior(family=args.hyperprior)
    if args.smoothness_log_std is not None:
        hyperprior = dataclasses.replace(hyperprior, smoothness_log_std=args.smoothness_log_std)
    n_rep = args.replicates or (QUICK_REPLICATES if args.quick else FULL_REPLICATES)
    wall = time.perf_counter()
    what = "the prior and the hyperprior" if args.draw_smoothness else "the prior"
    print(f"Calibration of the credible bands, openlab-like (30 elements + 2 springs), truth drawn from "
          f"{what} on the truth mesh; {n_rep} replicates per case, seed {args.seed}")
    print(f"{'case':<12}{'method':<12}{'cov95':>8}{'(se)':>8}{'cov75':>8}{'(se)':>8}{'at bound':>10}"
          f"{'flat':>6}{'warned':>8}{'nodes':>7}{'s/inv':>7}")
    everything = {}
    for name in args.cases:
        records = run_case(name, n_rep, args.seed, args.draw_smoothness, tuple(args.methods), hyperprior,
                           args.truth_smoothness)
        summary = summarise(records)
        everything[name] = {"summary": summary, "replicates": records}
        for method, s in summary.items():
            print(f"{name:<12}{method:<12}{s['coverage95']:>8.3f}{s['se95']:>8.3f}{s['coverage75']:>8.3f}"
                  f"{s['se75']:>8.3f}{s['at_bound']:>10d}{s['flat']:>6d}{s['warned']:>8d}"
                  f"{s['components']:>7.1f}{s['seconds']:>7.2f}")
        s = summary["integrated"]
        ok95 = TARGET_95[0] <= s["coverage95"] <= TARGET_95[1]
        ok75 = TARGET_75[0] <= s["coverage75"] <= TARGET_75[1]
        print(f"  {name}: integrated 95 % band {'within' if ok95 else 'OUTSIDE'} {TARGET_95}, 75 % band "
              f"{'within' if ok75 else 'OUTSIDE'} {TARGET_75}, tau at a grid end in {s['at_bound']} replicates")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "calibration_integrated.json").write_text(json.dumps(everything, indent=1))
    print(f"total time {time.perf_counter() - wall:.0f} s")
    return everything


if __name__ == "__main__":
    main()
