"""Benchmark of the full Bayesian inversion of sensorplan.

What it measures
----------------
Wall time (best of a few repeats, ``time.perf_counter``) of

    result = sensorplan.inference.inversion.invert(case, crossings)      # hyper="integrated"

i.e. the whole identification with the hyperparameters integrated out (the
default): the Gauss-Newton / Levenberg-Marquardt MAP at the start values,
the mode of the hyper-posterior of log tau on the linearised model, one
Laplace posterior per node of the quadrature over log tau (each started from
its neighbour's Gauss-Newton step), the mixture, its per-crossing fits and
the fit checks.  Crossing screening (on by default) is included.  The same
data are also inverted with ``hyper="evidence", detect=False`` (the previous default:
evidence maximisation of the noise scale and tau interleaved with the MAP,
one Laplace posterior), alternating the two in every repeat, and the ratio
integrated / evidence of the best times is printed (target: at most 3).

Size: 60 elements, 4 tiltmeters, 10 crossings x 300 load positions
(12 000 whitened residuals).

Case A (timed against the target): the embedded ``openlab-like`` example, two
continuous 15 m spans with elastic rotational springs at the two outer
supports (nominal 2e9 and 1e9 N m/rad), a two-axle 48 kN vehicle and tiltmeter
noise 5 urad.  The springs are estimated jointly with log EI (62 parameters),
so the bridge is statically indeterminate and the model is nonlinear in the
parameters.  The case is rebuilt from the example with 4 tiltmeters
(``with_sensors``), a 60-element mesh (``with_mesh``) and a sweep of 300
positions covering the whole crossing (``dataclasses.replace(..., sweep=)``).

Case B (comparison): a statically determinate variant, the embedded
``simply-supported`` example (one 20 m span, one 100 kN axle, noise 2 urad)
rebuilt the same way: 60 elements, 4 tiltmeters, 10 x 300.  No springs, so
60 parameters; the forward model is linear in the compliance 1/EI but
``invert`` works in log EI by default, so it is still solved iteratively.

Data (no inverse crime): simulated with noise (numpy Generator, fixed seed) on
a 3x finer mesh (180 elements) from a truth that differs modestly from the
nominal: EI 15 % lower over 2 m (case A: around 7.5 m, mid span 1; case B:
around 10 m) and, in case A, spring stiffnesses 2.5e9 and 0.8e9 N m/rad
instead of the nominal 2e9 and 1e9.  The inversion starts from the nominal.

Reference (measured in the same run, same size): one forward evaluation with
Jacobian on the 60-element inversion mesh,

    case.influence_lines(...).jacobian("log_ei", springs=True)

(4 sensors x 300 positions x 62 or 60 parameters), best of many repeats.  The
inversion is reported as "inversion time / one forward+Jacobian evaluation".
The script also counts (from the profile) how many forward evaluations one
inversion performs, and times one residual+Jacobian assembly of all 10
crossings (``EIProblem.evaluate``) to show how much of the cost is the forward
model and how much the bookkeeping around it.

Finally one run of case A is profiled with ``cProfile`` (top 12 entries by
cumulative time; the profiler itself slows the run down).

The targets are "under 2 s on a 2-core machine" and "integrated at most 3 x
evidence"; the script says whether they were met here.  Nothing is asserted.

Last run (2026-11-25, machine loaded by two other jobs: load average about 7 on 2 cores, so the
absolute times are inflated; the ratios are measured in the same run):

    case    best [s]   median    worst     cold  GN iter  converged  fwd+J [ms]  inv / fwd+J
    A          1.298    1.504    1.586    1.505       11       True       20.78           62
    B          1.128    1.315    1.567    1.425       15       True       13.17           86
    A: hyper='evidence' best 0.678 s (median 0.810 s); integrated / evidence (best): 1.91, (median): 1.86
    B: hyper='evidence' best 0.386 s (median 0.474 s); integrated / evidence (best): 2.92, (median): 2.77
    A, 1 BLAS thread: integrated best 1.160 s, evidence best 0.743 s, integrated / evidence 1.56

Both cases are within the 3x target.  The default ``invert`` runs the damage detector and the
local-loss hypotheses; the detector's scan works in the element space (the projected Gram matrix
of the compliance columns), so its cost does not grow with the number of readings times the
number of zones, and its estimates skip the zones whose likelihood maximum is e^-40 below the
best zone's evidence (a bound: the estimates are unchanged).  Case B is slower relative to its
reference because its evidence maximisation is fast and its 0.33 m elements give the scan more
zones.

The integrated inversion of case A uses 25 nodes of log tau and costs about
as much as evidence maximisation: the nodes need one or two forward +
Jacobian evaluations each and the tail nodes none, while the evidence loop
re-solves the MAP several times and spends about half of its time in the
L-BFGS maximisation of the linearised evidence.

Threads: the inversion makes many small BLAS/LAPACK calls (a 12 000 x 62
matrix product per Gauss-Newton step, 62 x 62 Cholesky solves in the evidence
optimisation).  OpenBLAS uses all cores by default, and its threads can make
these calls slower, and far more variable, than one thread, badly so when
other processes compete for the cores.  The script therefore also times case
A in a child process with ``OPENBLAS_NUM_THREADS = OMP_NUM_THREADS =
MKL_NUM_THREADS = 1`` (skipped if this process already runs with those
settings) and prints the load average before and after, so a busy machine
can be recognised.

How to run
----------
From the repository root (the folder holding ``sensorplan/``)::

    python studies/benchmarks/bench_inversion.py

Its results are deterministic (fixed seed); the timings are not.  It takes
well under a minute on an idle 2-core machine, longer when other processes
compete for the cores.
"""

import cProfile
import dataclasses
import io
import json
import os
import pstats
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import sensorplan as sp  # noqa: E402
from sensorplan.io.config import example_case  # noqa: E402
from sensorplan._threads import single_threaded  # noqa: E402
from sensorplan.inference.ei_problem import EIProblem  # noqa: E402
from sensorplan.inference.inversion import invert  # noqa: E402
from sensorplan.model.simulate import simulate_crossings  # noqa: E402

SEED = 20240612
N_ELEMENTS = 60
N_FINE = 180  # data mesh, 3x finer than the inversion mesh
N_LOADS = 300
N_CROSSINGS = 10
INVERT_REPEATS = 5
FORWARD_REPEATS = 50
TARGET_S = 2.0
TARGET_RATIO = 3.0  # integrated / evidence
DAMAGE = 0.85  # EI factor of the truth over DAMAGE_WIDTH
DAMAGE_WIDTH = 2.0  # m
TOP = 12
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
CHILD_FLAG = "--single-thread-child"

# Case A: openlab-like, springs estimated.
A_SENSORS = (4.0, 11.0, 19.0, 26.0)  # m; 11 and 19 are the example's PE1 / PE2
A_DAMAGE_AT = 7.5  # m, mid span 1
A_TRUE_SPRINGS = (2.5e9, 0.8e9)  # N m/rad; nominal (2e9, 1e9)
# Case B: simply supported, determinate.
B_SENSORS = (3.0, 8.0, 12.0, 17.0)  # m
B_DAMAGE_AT = 10.0  # m, mid span


def timed(func, repeats):
    """Wall times [s] of ``repeats`` calls (array), and the last result."""
    times = []
    result = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = func()
        times.append(time.perf_counter() - t0)
    return np.array(times), result


def build(example, sensor_x):
    """The example rebuilt with 4 tiltmeters, 60 elements and a 300-position sweep."""
    base = example_case(example)
    names = [f"T{i + 1}" for i in range(len(sensor_x))]
    case = base.with_sensors(sp.SensorLayout(list(sensor_x), names=names))
    case = case.with_mesh(sp.Mesh.uniform(case.bridge, N_ELEMENTS))
    stop = case.bridge.length + case.vehicle.length  # the whole vehicle crosses
    return dataclasses.replace(case, sweep=sp.LoadSweep(np.linspace(0.0, stop, N_LOADS)))


def synthetic(case, damage_at, true_springs, seed):
    """Noisy crossings simulated on the finer mesh; returns data and the truth."""
    fine = case.with_mesh(sp.Mesh.uniform(case.bridge, N_FINE))
    mid = fine.mesh.midpoints
    ei_fine = fine.ei * np.where(np.abs(mid - damage_at) < 0.5 * DAMAGE_WIDTH, DAMAGE, 1.0)
    bridge = None if true_springs is None else case.bridge.with_spring_stiffness(true_springs)
    data = simulate_crossings(fine, N_CROSSINGS, noise=True, rng=seed, ei=ei_fine, bridge=bridge)
    # Element truth on the inversion mesh: the element-average compliance.
    ratio = N_FINE // N_ELEMENTS
    ei_truth = 1.0 / np.mean((1.0 / ei_fine).reshape(N_ELEMENTS, ratio), axis=1)
    return data, ei_truth


def run_invert(case, data, hyper="integrated"):
    # "evidence" is the previous invert (one Laplace posterior, no detector); "integrated" is today's
    # default: hyperparameters integrated out, the damage detector and the local-loss hypotheses
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = invert(case, data, hyper=hyper, detect=hyper != "evidence")
    return result, [str(w.message) for w in caught]


def forward_jacobian(case):
    lines = case.influence_lines(positions=case.sweep.positions)
    return lines.jacobian("log_ei", springs=True)


def time_inversion(case, data):
    """Cold time, repeated times (array), result and warnings of ``invert``, and the evidence times.

    The integrated and the evidence inversions alternate, so that both see the same machine load.
    """
    t0 = time.perf_counter()
    run_invert(case, data)  # cold call (imports, caches), not counted
    t_cold = time.perf_counter() - t0
    run_invert(case, data, "evidence")
    times, times_ev = [], []
    for _ in range(INVERT_REPEATS):
        t_ev, _ = timed(lambda: run_invert(case, data, "evidence"), 1)
        t_int, (result, messages) = timed(lambda: run_invert(case, data), 1)
        times.append(t_int[0])
        times_ev.append(t_ev[0])
    return t_cold, np.array(times), result, messages, np.array(times_ev)


def time_forward(case):
    """Best time of one forward + Jacobian evaluation, and the Jacobian."""
    forward_jacobian(case)
    t_fwd_all, jac = timed(lambda: forward_jacobian(case), FORWARD_REPEATS)
    return float(t_fwd_all.min()), jac


def bench_case(label, case, data):
    """Time the inversion and its references for one case; returns a dict of results."""
    t_cold, times, result, messages, times_ev = time_inversion(case, data)
    t_fwd, jac = time_forward(case)
    problem = EIProblem(case, data, estimate_springs=bool(case.bridge.spring_names),
                        parameterisation="log_ei")
    # one BLAS thread, as inside invert; the problem's cache is cleared each time
    t_eval_all, _ = timed(single_threaded(lambda: (problem.clear_cache(), problem.evaluate(problem.theta0))), 20)
    return {
        "label": label, "case": case, "data": data, "result": result, "messages": messages,
        "t_cold": t_cold, "t_best": float(times.min()), "t_median": float(np.median(times)),
        "t_worst": float(times.max()), "t_fwd": t_fwd, "t_evidence": float(times_ev.min()),
        "t_evidence_median": float(np.median(times_ev)),
        "t_eval": float(t_eval_all.min()), "jac_shape": jac.shape,
    }


def profile_counts(stats):
    """Number of calls of the forward model and of EIProblem.evaluate in a profile."""
    counts = {"influence_lines": 0, "evaluate": 0}
    for (filename, _, func), (_, ncalls, *_rest) in stats.stats.items():
        if func == "influence_lines" and filename.endswith("forward.py"):
            counts["influence_lines"] += ncalls
        if func == "evaluate" and filename.endswith("problem.py"):
            counts["evaluate"] += ncalls
    return counts


def case_a_setup():
    case = build("openlab-like", A_SENSORS)
    data, truth = synthetic(case, A_DAMAGE_AT, A_TRUE_SPRINGS, SEED)
    return case, data, truth


def single_thread_child():
    """Case A only, run in a child process with one BLAS thread; prints one JSON line."""
    case, data, _ = case_a_setup()
    t_cold, times, result, _, times_ev = time_inversion(case, data)
    t_fwd, _ = time_forward(case)
    print(json.dumps({"t_cold": t_cold, "t_best": float(times.min()), "t_evidence": float(times_ev.min()),
                      "t_median": float(np.median(times)), "t_worst": float(times.max()),
                      "t_fwd": t_fwd, "n_iter": result.n_iter, "converged": result.converged}))


def single_thread_run():
    """Case A timed in a child process with one BLAS thread (None if already so here)."""
    if all(os.environ.get(k) == "1" for k in THREAD_VARS):
        return None
    env = dict(os.environ, **{k: "1" for k in THREAD_VARS})
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), CHILD_FLAG], env=env,
                          capture_output=True, text=True, timeout=1800)
    if proc.returncode != 0:
        return {"error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else "failed"}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main():
    wall0 = time.perf_counter()
    load0 = os.getloadavg()
    case_a, data_a, truth_a = case_a_setup()
    case_b = build("simply-supported", B_SENSORS)
    data_b, truth_b = synthetic(case_b, B_DAMAGE_AT, None, SEED + 1)

    a = bench_case("A", case_a, data_a)
    b = bench_case("B", case_b, data_b)

    profiler = cProfile.Profile()
    profiler.enable()
    t0 = time.perf_counter()
    run_invert(case_a, data_a)
    t_profiled = time.perf_counter() - t0
    profiler.disable()
    stats = pstats.Stats(profiler)
    counts = profile_counts(stats)
    single = single_thread_run()
    load1 = os.getloadavg()

    # --- Report ------------------------------------------------------------------------------
    cores = os.cpu_count()
    line = "-" * 96
    env = ", ".join(f"{k}={os.environ.get(k, 'unset')}" for k in THREAD_VARS)
    print("sensorplan Bayesian inversion benchmark (MAP + Laplace, hyperparameters integrated / by evidence)")
    print(f"numpy {np.__version__}, {cores} logical CPU(s), seed {SEED}; {env}")
    print(f"load average (1 min) {load0[0]:.2f} at start, {load1[0]:.2f} at end "
          f"(> {cores} means other processes compete for the cores)")
    print(line)
    ra = a["result"]
    springs = " and ".join(f"{k:.1e}" for k in case_a.bridge.spring_stiffness())
    print(f"Case A: openlab-like two spans {'+'.join(f'{x:g}' for x in case_a.bridge.spans)} m, "
          f"rotational end springs {springs} N m/rad estimated jointly,")
    print(f"  {N_ELEMENTS} elements + {ra.n_springs} springs = {ra.theta.size} parameters, "
          f"tiltmeters at {A_SENSORS} m (noise {case_a.noise.std[0]:.1e} rad),")
    print(f"  {N_CROSSINGS} crossings x {N_LOADS} positions (0 to {case_a.sweep.positions[-1]:g} m), "
          f"{case_a.vehicle.n_axles}-axle vehicle.")
    print(f"  Truth on {N_FINE} elements: EI x {DAMAGE} over {DAMAGE_WIDTH:g} m at "
          f"{A_DAMAGE_AT:g} m, springs {' and '.join(f'{k:.1e}' for k in A_TRUE_SPRINGS)} N m/rad.")
    print(f"Case B: simply supported {case_b.bridge.spans[0]:g} m span (determinate, no springs), "
          f"{N_ELEMENTS} elements = {b['result'].theta.size} parameters,")
    print(f"  tiltmeters at {B_SENSORS} m (noise {case_b.noise.std[0]:.1e} rad), "
          f"{N_CROSSINGS} x {N_LOADS} positions, 1 axle.")
    print(f"  Truth on {N_FINE} elements: EI x {DAMAGE} over {DAMAGE_WIDTH:g} m at {B_DAMAGE_AT:g} m.")
    print(line)
    head = (f"{'case':<6}{'best [s]':>10}{'median':>9}{'worst':>9}{'cold':>9}{'GN iter':>9}"
            f"{'converged':>11}{'fwd+J [ms]':>12}{'inv / fwd+J':>13}")
    print(f"invert(case, crossings), best of {INVERT_REPEATS} (after one cold call); "
          f"fwd+J best of {FORWARD_REPEATS}")
    print(head)
    for r in (a, b):
        res = r["result"]
        print(f"{r['label']:<6}{r['t_best']:>10.3f}{r['t_median']:>9.3f}{r['t_worst']:>9.3f}"
              f"{r['t_cold']:>9.3f}{res.n_iter:>9d}{str(res.converged):>11}"
              f"{1e3 * r['t_fwd']:>12.2f}{r['t_best'] / r['t_fwd']:>13.0f}")
    if single is not None and "error" not in single:
        label = "A, 1 BLAS thread (child process)"
        print(f"{label}: best {single['t_best']:.3f} s, median {single['t_median']:.3f} s, worst "
              f"{single['t_worst']:.3f} s, cold {single['t_cold']:.3f} s, {single['n_iter']} GN iter, "
              f"converged {single['converged']},")
        print(f"  evidence best {single['t_evidence']:.3f} s, integrated / evidence "
              f"{single['t_best'] / single['t_evidence']:.2f};")
        print(f"  fwd+J {1e3 * single['t_fwd']:.2f} ms, inv / fwd+J "
              f"{single['t_best'] / single['t_fwd']:.0f}; default threads / 1 thread (best): "
              f"{a['t_best'] / single['t_best']:.1f}")
    elif single is not None:
        print(f"A, 1 BLAS thread (child process): failed ({single['error']})")
    print(f"A / B inversion time: {a['t_best'] / b['t_best']:.2f}")
    for r in (a, b):
        print(f"{r['label']}: hyper='evidence' best {r['t_evidence']:.3f} s (median {r['t_evidence_median']:.3f} s); "
              f"integrated / evidence (best): {r['t_best'] / r['t_evidence']:.2f}, (median): "
              f"{r['t_median'] / r['t_evidence_median']:.2f}")
    print("fwd+J = case.influence_lines(...).jacobian('log_ei', springs=True) on the inversion "
          f"mesh, output {a['jac_shape']} (A), {b['jac_shape']} (B).")
    print(line)
    print("Result checks (not part of the timing):")
    for r, truth in ((a, truth_a), (b, truth_b)):
        res = r["result"]
        err = np.abs(np.log(res.ei_map / truth))
        ci = res.credible_interval(0.95)
        cover = np.mean((truth >= ci[:, 0]) & (truth <= ci[:, 1]))
        worst = r["case"].mesh.midpoints[np.argmin(res.ei_map)]
        mix = res.mixture
        text = (f"  {r['label']}: noise scale {res.noise_scale:.3f}, tau {res.tau:.3g} (mode; "
                f"{mix.n_components} nodes, mass at the grid ends {res.tau_mass_at_bound:.1e}), "
                f"max|log(EI_map / EI_true)| {err.max():.3f}, 95 % CI coverage {cover:.0%}, "
                f"min EI_map at {worst:.2f} m")
        print(text)
        for name, s in res.springs().items():
            print(f"     spring {name}: MAP {s['map']:.3e} (nominal {s['nominal']:.1e}), "
                  f"95 % [{s['low']:.2e}, {s['high']:.2e}]")
        if res.excluded_crossings:
            print(f"     excluded crossings: {', '.join(res.excluded_crossings)}")
        for m in sorted(set(r["messages"])):
            print(f"     warning: {m}")
    print(line)
    t_fwd_a = a["t_fwd"]
    n_lines = counts["influence_lines"]
    print("Where the time goes (case A):")
    print(f"  forward evaluations per inversion (influence_lines calls): {n_lines}; "
          f"{n_lines} x fwd+J = {n_lines * t_fwd_a:.3f} s = "
          f"{100 * n_lines * t_fwd_a / a['t_best']:.1f} % of the best inversion time")
    print(f"  one residual + whitened Jacobian of all {N_CROSSINGS} crossings (EIProblem.evaluate): "
          f"{1e3 * a['t_eval']:.2f} ms = {a['t_eval'] / t_fwd_a:.1f} x fwd+J; "
          f"{counts['evaluate']} calls per inversion")
    print(line)
    print(f"cProfile of one case-A inversion ({t_profiled:.3f} s under the profiler), "
          f"top {TOP} by cumulative time:")
    out = io.StringIO()
    pstats.Stats(profiler, stream=out).strip_dirs().sort_stats("cumulative").print_stats(TOP)
    text = out.getvalue().strip("\n").splitlines()
    start = next(i for i, s in enumerate(text) if s.lstrip().startswith("ncalls"))
    print("\n".join(text[start:]))
    print(line)
    met = a["t_best"] < TARGET_S
    verdict = "MET" if met else "NOT MET"
    note = "" if cores == 2 else f" (this machine has {cores} logical CPUs, not 2)"
    print(f"Target: case A inversion (60 elements, 4 tiltmeters, 10 x 300, springs) under "
          f"{TARGET_S:g} s on a 2-core machine.")
    print(f"Result: best {a['t_best']:.3f} s (median {a['t_median']:.3f} s, worst "
          f"{a['t_worst']:.3f} s) on this machine{note} -> target {verdict}.")
    if single is not None and "error" not in single:
        verdict1 = "MET" if single["t_best"] < TARGET_S else "NOT MET"
        print(f"        with 1 BLAS thread: best {single['t_best']:.3f} s (worst "
              f"{single['t_worst']:.3f} s) -> target {verdict1}.")
    ratio = a["t_best"] / a["t_evidence"]
    print(f"Target: integrated at most {TARGET_RATIO:g} x evidence on case A: {ratio:.2f} -> "
          f"{'MET' if ratio <= TARGET_RATIO else 'NOT MET'}.")
    print(f"Total benchmark run time: {time.perf_counter() - wall0:.1f} s")


if __name__ == "__main__":
    if CHILD_FLAG in sys.argv[1:]:
        single_thread_child()
    else:
        main()
