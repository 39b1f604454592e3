"""The physical limit of naming a changed rotational restraint next to a second effect (issue 18).

studies/diagnosis/pairs.py names a changed rotational restraint together with a
second effect in 12/15 single-span datasets but in 1/15 on the two-span
(middle support) and three-span (right end) bridges.  Is that the method
or the data?  This study measures what the data allow: the optimal test
that *knows* the restraint's support and value, with EI (and the case's
elastic springs, and the second effect's parameters) as nuisance.

For noise-free truth data (the restraint changed as pairs.py changes it,
on the finer truth mesh of ``effects_data``) it fits, with the noise scale
1 and the prior scale tau of the base fit to one noisy dataset,

    null:        EI (+ case springs) + second effect
    alternative: the same + the support_rotational_spring effect

and reports d^2 = 2 (J_null - J_alt), J = |r|^2 / 2 + (theta - theta0)^T Q
(theta - theta0) / 2 at each MAP.  d^2 is the non-centrality of the
penalised likelihood-ratio test of the two, so the best one-sided test at
level a has power Phi(d - z_a).  Naming a cause takes a log Bayes factor of
3, comparable to a = 0.005 (z = 2.576) for one parameter; a = 0.05 is shown
as well.  The oracle knows where and how large the change is; the diagnosis
searches every support and every value, so its rates can only be lower.

Run: python studies/diagnosis/restraint_limit.py [--crossings N]

Last run (2026-11-26, 10 crossings; power at a = 0.05 / 0.005):
  single span, left support: d^2 = 444 to 2273 with any second effect: power 1.00 / 1.00
  (pairs.py names both in 12/15).
  two-span, middle support: d^2 = 4.2 to 4.6 whatever the second effect: 0.66-0.69 / 0.30-0.33
  (pairs.py: 1/15; the restraint is reported as confounded with EI in 11/15).
  three-span, right end: alone d^2 = 7.9 (0.88 / 0.59); with sensor offsets 4.9 (0.72 / 0.36),
  thermal drift 2.9 (0.52 / 0.19), axle loads 7.4, position offsets 7.3, sensor gain 7.7
  (0.85-0.87 / 0.55-0.58) (pairs.py: 1/15).
  So at a naming level even the oracle finds these two restraints in only 19-59 % of
  datasets; the diagnosis's 1/15 is about 0.1-0.2 of that.  With 8 crossings d^2 is lower
  still (two-span 4.9, three-span 7.0 alone), with 12 higher (7.3, 9.0).
"""

import os
import sys

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.stats import norm  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parents[1]))  # this checkout's sensorplan

import pairs  # noqa: E402
from effects_data import _fine, generate  # noqa: E402

from sensorplan.diagnosis.effects import make_effect  # noqa: E402
from sensorplan.diagnosis.joint.problem import JointProblem  # noqa: E402
from sensorplan.diagnosis.joint.fits import integrated_fit  # noqa: E402
from sensorplan.diagnosis.selection.refit import quick_fit  # noqa: E402
from sensorplan.model.prior import GMRFPrior  # noqa: E402
from sensorplan.model.simulate import simulate_crossings  # noqa: E402

SECOND = ([], ["sensor_offset"], ["thermal_drift"], ["axle_loads"], ["position_offset"], ["sensor_gain"])


def penalised_misfit(case, data, names, prior, tau):
    """J at the MAP of the model with effects ``names`` (noise scale 1, prior scale ``tau``)."""
    problem = JointProblem(case, data, [make_effect(n) for n in names], prior)
    fit = quick_fit(problem, problem.theta0, 1.0, tau, max_iter=300)
    lin = problem.evaluate(fit.theta)
    d = fit.theta - problem.theta0
    q = tau * problem.rough + problem.fixed
    return 0.5 * lin.rr + 0.5 * d @ q @ d


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--crossings", type=int, default=10)
    args = ap.parse_args(argv)
    n = args.crossings
    warnings.simplefilter("ignore")
    prior = GMRFPrior()
    for bridge in pairs.BRIDGES:
        support = pairs.ROTATES[bridge]
        case = pairs.make_case(bridge)
        truth = pairs.rotated(case, support)
        clean = simulate_crossings(_fine(truth), n, noise=False)
        noisy = generate(truth, None, np.random.SeedSequence((7, n)), n)
        tau = integrated_fit(JointProblem(case, noisy, [], prior), prior).tau
        for second in SECOND:
            d2 = 2.0 * (penalised_misfit(case, clean, second, prior, tau)
                        - penalised_misfit(case, clean, second + ["support_rotational_spring"], prior, tau))
            d = float(np.sqrt(max(d2, 0.0)))
            print(f"{bridge:12s} support {support} + {', '.join(second) or 'nothing':16s} {n} crossings: "
                  f"d^2 = {d2:8.2f}; optimal power at 0.05 {norm.cdf(d - 1.645):.2f}, at 0.005 "
                  f"{norm.cdf(d - 2.576):.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
