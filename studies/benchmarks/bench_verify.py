"""Benchmark of the verification of layouts by full Bayesian inversion.

What it measures
----------------
Throughput (scenarios per second, wall time ``time.perf_counter``) of

    result = sensorplan.verification.verify.verify_layouts(case, [(11.0, 19.0)],
                                                      n_locations=60, workers=W)

on the embedded ``openlab-like`` example as it is shipped (two continuous 15 m
spans with rotational end springs, 30 elements, the two tiltmeters PE1 and
PE2 at 11 and 19 m, noise 5 urad, a 2-axle vehicle, 129 load positions) with
the default 10 crossings per scenario.  ``n_locations=60`` gives 60 local
losses + 2 span softenings + 30 undamaged controls = 92 scenarios.  Each
scenario simulates 10 noisy crossings on a finer, differently aligned truth
mesh and inverts them (MAP + Laplace + evidence maximisation, springs
estimated); before the scenarios are dispatched, one pilot inversion (in the
calling process) provides the warm start of the hyperparameters.  The timed
call therefore contains 93 inversions for 92 scenarios.

W = 1 (everything in this process) and W = 2 (a ``ProcessPoolExecutor`` of
2 processes created and shut down by ``verify_layouts``, so its start-up is
included) are each run ``REPEATS`` times; the best and the worst are
printed.  When the ``dask`` extra is installed, the same call also runs on
a Dask LocalCluster of 2 single-threaded worker processes, "cold"
(``scheduler="local"``: the cluster is started and closed inside the timed
call, as the pool is) and "warm" (``executor=`` a cluster started before
the loop), reported as scenarios/s and as a ratio to the 2-process pool.
The four variants are interleaved in every repeat, so that a load drifting
on a shared machine favours none of them.

References measured in the same run (never asserted):

1. one ``invert`` on one scenario's data (a local loss in span 1), with the
   same options and warm start as inside ``verify_layouts``, best of
   ``INVERT_REPEATS``: the overhead per scenario is reported in units of
   this inversion;
2. the sum of the ``invert`` times of all 92 scenarios (data simulated
   beforehand, not timed): the cost that no scheduling can avoid.  The
   remainder of the W = 1 time is simulation, truth mesh and scoring.

Target: >= 50 scenarios per second on 2 cores (W = 2); the script says
whether it was met here.  It also checks that W = 1 and W = 2 give the same
JSON (``result.to_dict()``, serialised with sorted keys): each scenario draws
its noise from its own ``SeedSequence`` child, so the result must not depend
on the number of workers.

Threads: one BLAS thread per process (``OPENBLAS_NUM_THREADS`` etc. are set
to 1 before numpy is imported unless already set, as the CLI does; the pool
workers inherit them).  The load average is printed at start and end: the
machine may be shared, and a load above the number of cores means the
workers competed with other processes.

Measured (2026-11-24, commit 67e84b3 + the LocalCluster port fix, 2 logical
CPUs shared with about six other jobs: load average 8.5 to 12.5, i.e. this
benchmark got a fraction of a core at any time; interleaved run)
-------------------------------------------------------------------------
* reference 1 (one inversion): 524 ms best, 606 ms median; reference 2:
  547 ms per scenario; ceiling 3.7 scenarios/s on 2 idle cores.
* workers=1: 3.7 scenarios/s best (24.6 s), worst 59.4 s; workers=2 (pool):
  1.6 scenarios/s best (57.4 s), worst 80.2 s: speed-up 0.43.  Best/worst
  spreads of 2-3x show that the load, not the scheduling, dominates.
* Dask LocalCluster, 2 processes: cold 1.2 scenarios/s = 0.76 x the pool
  (best 75.1 s, includes starting and closing the cluster), warm 1.5
  scenarios/s = 0.94 x the pool (best 60.8 s).
* identical JSON for workers=1, workers=2, cold and warm Dask: yes.
* target of 50 scenarios/s: NOT MET (the inversions alone cap it at 3.7
  scenarios/s on 2 idle cores).
An earlier, non-interleaved run of the same day (load 10 rising to 17 while
the Dask variants ran last) gave pool 1.4 scenarios/s and Dask 0.8 (0.53 x
cold, 0.54 x warm): on this machine the Dask/pool ratio is between about
0.5 and 0.95 and its precision is limited by the shared load.  A Dask
cluster is for more cores than one machine has, not for speed on two.

How to run
----------
From the repository root (the folder holding ``sensorplan/``)::

    python studies/benchmarks/bench_verify.py
    python studies/benchmarks/bench_verify.py --locations 3 --repeats 1 --invert-repeats 1 --no-dask  # quick check

It takes a few minutes on an idle 2-core machine (10-15 minutes on a busy one).
"""

import os

THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
THREADS_PRESET = {k: os.environ.get(k) for k in THREAD_VARS}
for _var in THREAD_VARS:  # before numpy is imported (the pool workers inherit it)
    os.environ.setdefault(_var, "1")

import contextlib  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from dataclasses import dataclass, replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from sensorplan._errors import SensorplanWarning  # noqa: E402
from sensorplan._executors import executor_for  # noqa: E402
from sensorplan.inference.inversion import invert  # noqa: E402
from sensorplan.io.config import example_case  # noqa: E402
from sensorplan.model.noise import NoiseModel  # noqa: E402
from sensorplan.model.simulate import simulate_crossings  # noqa: E402
from sensorplan.verification.scenarios import truth_mesh  # noqa: E402
from sensorplan.verification.verify import plan_verification, run_pilot, verify_layouts  # noqa: E402

EXAMPLE = "openlab-like"
LAYOUT = (11.0, 19.0)
N_LOCATIONS = 60
N_CROSSINGS = 10
SEED = 1
REPEATS = 2
INVERT_REPEATS = 7
WORKERS = (1, 2)
TARGET_PER_S = 50.0
FALSE_ALARM = 0.05  # verify_layouts' default
DAMAGE_LENGTH = 2.0  # m, verify_layouts' default


def package_commit():
    """Short git commit of the working tree (the package may change between runs), or 'unknown'."""
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=10)
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "sensorplan"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return out.stdout.strip() + (" + uncommitted changes in sensorplan/" if dirty else "") or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def scenario_inputs(case, n_locations):
    """Per-scenario (case with the layout's sensors, data, warm start), as inside verify_layouts."""
    plan = plan_verification(case, [LAYOUT], n_locations=n_locations, length=DAMAGE_LENGTH, n_crossings=N_CROSSINGS,
                             seed=SEED, false_alarm=FALSE_ALARM)
    start = run_pilot(plan.pilots()[0])  # (noise scale, tau) of the pilot inversion
    # the same steps as a verification task (sensorplan.verification.verify), up to the inversion
    sensors = plan.layouts[0]
    inv_case = replace(case, sensors=sensors, noise=NoiseModel(sensors.noise_std, case.noise.correlation_length))
    fine_mesh = truth_mesh(inv_case)
    fine = inv_case.with_mesh(fine_mesh)
    out = []
    for scenario, seed in zip(plan.scenarios, plan.seeds):
        truth = scenario.truth(fine_mesh, fine.ei)
        data = simulate_crossings(fine, N_CROSSINGS, noise=True, rng=np.random.default_rng(seed), ei=truth)
        out.append((scenario, data))
    return inv_case, out, start


def run_invert(inv_case, data, start):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SensorplanWarning)
        return invert(inv_case, data, screen=False, noise_scale=start[0], tau=start[1])


def run_verify(case, workers, n_locations, scheduler=None, executor=None):
    t0 = time.perf_counter()
    result = verify_layouts(case, [LAYOUT], n_locations=n_locations, n_crossings=N_CROSSINGS, seed=SEED,
                            workers=workers, length=DAMAGE_LENGTH, scheduler=scheduler, executor=executor)
    return time.perf_counter() - t0, result


def has_dask():
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def parse_args(argv=None):
    import argparse

    parser = argparse.ArgumentParser(description="Benchmark of verify_layouts (see the module docstring).")
    parser.add_argument("--locations", type=int, default=N_LOCATIONS,
                        help=f"local-damage locations (default {N_LOCATIONS}; smaller for a quick check)")
    parser.add_argument("--repeats", type=int, default=REPEATS, help=f"runs of each variant (default {REPEATS})")
    parser.add_argument("--invert-repeats", type=int, default=INVERT_REPEATS,
                        help=f"repeats of reference 1 (default {INVERT_REPEATS})")
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask variants even when dask is installed")
    return parser.parse_args(argv)


@dataclass(frozen=True)
class References:
    """Reference 1 (one inversion, best and median of repeats) and reference 2 (all inversions back to back)."""

    inputs: list  # (scenario, data) per scenario
    scenario: object  # the scenario of reference 1
    post: object  # its posterior
    best: float  # [s]
    median: float  # [s]
    total: float  # [s], reference 2


@dataclass(frozen=True)
class Runs:
    """Wall times of verify_layouts per variant, the last result and whether every variant gave the same JSON."""

    times: dict  # workers -> [s] per repeat
    dask: tuple | None  # (cold times, warm times) or None when not measured
    result: object
    json_text: str  # result.to_dict() of workers=1, sorted keys
    same: bool


def measure_references(case, args):
    """Reference 1: one invert() on one scenario's data; reference 2: invert() on every scenario in turn."""
    inv_case, inputs, start = scenario_inputs(case, args.locations)
    ref_k = next(k for k, (s, _) in enumerate(inputs) if s.kind == "local" and s.centre > 5.0)
    ref_scenario, ref_data = inputs[ref_k]
    run_invert(inv_case, ref_data, start)  # warm-up
    t_inv_all = []
    for _ in range(args.invert_repeats):
        t0 = time.perf_counter()
        post = run_invert(inv_case, ref_data, start)
        t_inv_all.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    for _, data in inputs:
        run_invert(inv_case, data, start)
    t_inv_sum = time.perf_counter() - t0
    return References(inputs, ref_scenario, post, float(min(t_inv_all)), float(np.median(t_inv_all)), t_inv_sum)


def measure_runs(case, args):
    """verify_layouts with 1 and 2 workers (and on Dask), interleaved in every repeat.

    Interleaved (1 worker, pool, Dask cold, Dask warm in every repeat) so that a drifting load on a shared
    machine biases none of them.
    """
    runs = {w: [] for w in WORKERS}
    dicts = {}
    dask_runs = ([], [], set()) if has_dask() and not args.no_dask else None
    with (executor_for(2, "local") if dask_runs else contextlib.nullcontext()) as cluster:
        for _ in range(args.repeats):
            for w in WORKERS:
                dt, result = run_verify(case, w, args.locations)
                runs[w].append(dt)
                dicts.setdefault(w, json.dumps(result.to_dict(), sort_keys=True))
            if dask_runs:
                for k, options in ((0, dict(scheduler="local")), (1, dict(executor=cluster))):
                    dt, other = run_verify(case, 2, args.locations, **options)
                    dask_runs[k].append(dt)
                    dask_runs[2].add(json.dumps(other.to_dict(), sort_keys=True))
    same = len(set(dicts.values()) | (dask_runs[2] if dask_runs else set())) == 1
    return Runs(runs, dask_runs[:2] if dask_runs else None, result, dicts[WORKERS[0]], same)


def main(argv=None):
    args = parse_args(argv)
    wall0 = time.perf_counter()
    load0 = os.getloadavg()
    case = example_case(EXAMPLE)
    refs = measure_references(case, args)
    runs = measure_runs(case, args)
    load1 = os.getloadavg()
    print_setup(case, args, refs, (load0, load1))
    rate = print_runs(refs, runs)
    print_target(refs, rate)
    print(f"Total benchmark run time: {time.perf_counter() - wall0:.1f} s")


LINE = "-" * 96


def print_setup(case, args, refs, loads):
    """The machine, the case, the scenarios and the two references."""
    cores = os.cpu_count()
    env = ", ".join(f"{k}={os.environ.get(k)}" + ("" if THREADS_PRESET[k] is not None else " (set here)")
                    for k in THREAD_VARS)
    print("sensorplan verification benchmark (verify_layouts: simulate + invert + score per scenario)")
    print(f"sensorplan commit {package_commit()}; numpy {np.__version__}, {cores} logical CPU(s); {env}")
    print("  (BLAS threads should be 1: the CLI sets OPENBLAS_NUM_THREADS=1; pool workers inherit it)")
    print(f"load average (1 min) {loads[0][0]:.2f} at start, {loads[1][0]:.2f} at end "
          f"(> {cores} means other processes compete for the cores)")
    print(LINE)
    b = case.bridge
    print(f"Case: {EXAMPLE}, spans {'+'.join(f'{x:g}' for x in b.spans)} m, {case.n_elements} elements, "
          f"rotational springs {' and '.join(f'{k:.1e}' for k in b.spring_stiffness())} N m/rad (estimated),")
    print(f"  layout {LAYOUT} m (rotation, noise {case.noise.std[0]:.1e} rad), {case.sweep.n_loads} load "
          f"positions, {N_CROSSINGS} crossings per scenario, seed {SEED}.")
    n_scen = len(refs.inputs)
    kinds = [s.kind for s, _ in refs.inputs]
    print(f"Scenarios: n_locations={args.locations} -> {n_scen} = {kinds.count('local')} local + "
          f"{kinds.count('span')} span + {kinds.count('control')} control "
          f"(+ 1 pilot inversion before dispatch).")
    print(LINE)
    post = refs.post
    print(f"Reference 1: one invert() on one scenario's data ({refs.scenario.kind} loss at "
          f"{refs.scenario.centre:.2f} m), best of {args.invert_repeats}: {1e3 * refs.best:.1f} ms "
          f"(median {1e3 * refs.median:.1f} ms; {post.n_iter} GN iterations, converged {post.converged})")
    print(f"Reference 2: invert() on all {n_scen} scenarios back to back: {refs.total:.3f} s = "
          f"{1e3 * refs.total / n_scen:.1f} ms per scenario = {refs.total / n_scen / refs.best:.2f} x reference 1;")
    print(f"  -> at most {n_scen / refs.total:.1f} scenarios/s per core if only the inversions cost anything")
    print(LINE)


def print_runs(refs, runs):
    """The table of the verify_layouts variants, the Dask ratios and the identical-JSON check; returns the rates."""
    n_scen, n_total, t_inv = len(refs.inputs), runs.result.layouts[0].n_scenarios, refs.best
    print(f"{'workers':>7}{'best [s]':>10}{'worst [s]':>11}{'scen/s':>9}{'wall/scen [ms]':>16}"
          f"{'core-ms/scen':>14}{'/ 1 invert':>12}{'overhead/scen':>15}")
    rate = {}
    for w in WORKERS:
        best, worst = min(runs.times[w]), max(runs.times[w])
        rate[w] = n_total / best
        per = best / n_total
        core = per * w
        print(f"{w:>7d}{best:>10.3f}{worst:>11.3f}{rate[w]:>9.1f}{1e3 * per:>16.1f}{1e3 * core:>14.1f}"
              f"{core / t_inv:>12.2f}{(core - t_inv) / t_inv:>14.2f}x")
    print(f"speed-up 2 workers / 1 worker: {rate[2] / rate[1]:.2f} (ideal 2.00)")
    if runs.dask is None:
        print("Dask LocalCluster: not measured (the dask extra is not installed)")
    else:
        for label, times in (("cold", runs.dask[0]), ("warm", runs.dask[1])):
            best = min(times)
            print(f"Dask LocalCluster, 2 processes, {label}: best {best:.3f} s, worst {max(times):.3f} s, "
                  f"{n_total / best:.1f} scen/s = {n_total / best / rate[2]:.2f} x the 2-process pool")
        print("  (cold: the cluster is started and closed inside the timed call, as the pool is; warm: started "
              "before; runs interleaved with the pool's)")
    print("core-ms/scen = wall time x workers / scenarios (the pilot is counted in the wall time);")
    print("'/ 1 invert' divides it by reference 1; overhead/scen = (core-ms/scen - 1 invert) / 1 invert")
    print("(simulation of the truth, truth mesh, scoring, pilot, pool start-up and pickling, idle time).")
    print(f"Of the 1-worker time, the {n_scen} inversions alone (reference 2) are "
          f"{100 * refs.total / min(runs.times[1]):.0f} %.")
    print(LINE)
    print(f"workers=1, workers=2{' and the Dask LocalCluster' if runs.dask else ''} give identical JSON "
          f"(result.to_dict()): {'yes' if runs.same else 'NO'}")
    print(runs.result.summary())
    print(f"result JSON (sorted keys) sha256 {hashlib.sha256(runs.json_text.encode()).hexdigest()[:16]}")
    print(LINE)
    return rate


def print_target(refs, rate):
    """Whether the target of scenarios per second was met, and the ceiling the inversions alone set."""
    cores = os.cpu_count()
    n_scen = len(refs.inputs)
    met = rate[2] >= TARGET_PER_S
    note = "" if cores == 2 else f" (this machine has {cores} logical CPUs, not 2)"
    print(f"Target: >= {TARGET_PER_S:g} scenarios per second on 2 cores (workers=2).")
    verdict = "MET" if met else f"NOT MET (short by a factor {TARGET_PER_S / rate[2]:.2f})"
    print(f"Result: {rate[2]:.1f} scenarios/s on this machine{note} -> target {verdict}.")
    if not met:
        need = 2.0 / TARGET_PER_S
        print(f"  At 2 cores, 50 scenarios/s allows {1e3 * need:.0f} core-ms per scenario; one inversion "
              f"alone takes {1e3 * refs.best:.1f} ms (reference 1),")
        print(f"  {1e3 * refs.total / n_scen:.1f} ms on average (reference 2): even with no overhead at all "
              f"the ceiling here is {2 * n_scen / refs.total:.1f} scenarios/s.")


if __name__ == "__main__":
    main()
