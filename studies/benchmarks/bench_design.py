"""Benchmark of optimal sensor placement: relaxations, greedy + exchange, recommend().

What it measures
----------------
For the criteria D, A and E at two sizes

    size 1: N = 60 elements,  C = 200 candidates, R = 6 new sensors
    size 2: N = 120 elements, C = 800 candidates, R = 10 new sensors

the wall time (``time.perf_counter``) of

(a) ``solve_relaxation(problem, "cvxpy")``: the generic cvxpy formulation
    solved by Clarabel (the reference);
(b) ``solve_relaxation(problem, "fast")``: column generation with a
    primal-dual interior-point method on the working set (D, A), or
    eigen-subspace cutting planes whose small SDPs are solved by a
    Schur-complement interior-point method (E);
(c) ``sensorplan.design.selection.greedy`` then ``exchange`` from its layout;
(d) the whole recommendation ``recommend(case, R, crit, curve_max=0,
    candidates=...)``: candidate Fisher blocks, baselines, greedy start,
    fast relaxation, integer layout from several starts, certificate,
    posterior standard deviations (no criterion-versus-R curve).

``problem = build_problem(case, R, crit, candidates=np.linspace(0.1, L - 0.1, C))``
so that C is exact.  The bridge is the embedded ``openlab-like`` example:
two continuous 15 m spans with rotational springs at the outer supports
(2e9 and 1e9 N m/rad), a two-axle 48 kN vehicle, tiltmeter noise 5 urad,
here with a uniform mesh of N elements and a sweep of 300 positions of the
front axle from 0 to 32 m (the whole vehicle crosses).  The springs are
fixed at their nominal stiffness (``recommend``'s default ``springs=False``),
so the number of parameters is P = N (log EI per element); the prior is the
default GMRF prior, one crossing.

Reported per criterion and method: wall time, the relaxation's certified
relative gap (``Relaxation.relative_gap``: (bound - utility) / max(1, |bound|)
with the bound computed by ``DesignProblem.dual_bound`` independently of the
solver), and the certified efficiency of an integer layout:

* (a), (b): the relaxed weights rounded (``round_weights``) then improved by
  ``exchange``, against the bound of that same relaxation (the rounding +
  exchange time is a separate column, not part of the relaxation time);
* (c): the greedy + exchange layout against the tightest bound of (a), (b);
* (d): the layout ``recommend`` returns, against its own bound.

Efficiencies follow ``Criterion.efficiency``: exp((value - bound) / P) for D,
bound / value for A (a lower bound on the trace), value / bound for E.
Timings of the fast path and of recommend() are reported as ratios against
cvxpy + Clarabel measured in the same run (fast / cvxpy < 1: the fast path
is faster).  Nothing is asserted.

Targets (checked and printed, met / not met):

* every relaxation solved to a certified relative duality gap <= 1e-6;
* the whole recommendation for the three criteria in under 5 s in total at
  size 1 and under 30 s at size 2 (on a 2-core machine);
* the certified efficiencies reached are reported.

If a target is not met, the script says by how much and profiles
(``cProfile``, top entries by internal time) the recommendation at that
size, within a time budget.

Time-boxing: every measurement runs in a child process of this script (the
same interpreter, the same thread settings, ``RLIMIT_AS`` of
``MEMORY_LIMIT_GB``) with a timeout; a child that times out or fails is
reported as such and the script goes on.  The cvxpy reference has a timeout
of ``CVXPY_TIMEOUT_S`` and, at size 2, is skipped (with a note) for a
criterion whose size-1 solve already took more than ``CVXPY_SKIP_S``: size 2
has 4x the candidates and 4x the entries per information block, so the
dense conic data are 16x larger.  Each child imports everything and solves
a tiny problem of the same kind first (warm-up, not timed); building the
problem (the candidate Fisher blocks) is not part of (a) - (c) but is part
of (d).

Threads: one BLAS thread (``OPENBLAS_NUM_THREADS = OMP_NUM_THREADS =
MKL_NUM_THREADS = 1``, as the CLI sets them) unless the variables are
already set; they are set before numpy is imported, printed, and inherited
by the children.  The load average is printed at start and end: the machine
may be shared, and a load above the number of cores means the benchmark
competed with other processes.

How to run
----------
From the repository root (the folder holding ``sensorplan/``)::

    python studies/benchmarks/bench_design.py

It is deterministic (fixed seeds); the timings are not.  It takes about 10
minutes on a 2-core machine, mostly in the cvxpy references (the timeouts,
see below, keep it from hanging) and the profile of a missed target.

Last run (2026-11-23, commit ab3055e, load average 0.25 at start, 1.3 at
end): size 1, D + A + E recommend() 2.1 s (target 5 s, met; D 0.46, A 0.70,
E 0.97 s).  The relaxation alone: cvxpy + Clarabel D 62.6 s, A 105.1 s,
E 6.5 s; the fast path 0.18, 0.34 and 0.28 s (ratios 0.003, 0.003, 0.043).
Size 2: 20.2 s (target 30 s, met: D 5.6, A 8.8, E 5.9 s; the E relaxation
1.98 s).  Every relaxation solved
reached a certified relative gap <= 1e-6 (largest 9.7e-7, cvxpy A at size 1;
fast path <= 2.7e-8); cvxpy at size 2 was skipped (D, A) or timed out after
120 s (E).  Certified efficiencies of the recommended layouts: size 1
D 97.4 %, A 93.8 %, E 85.8 %; size 2 D 98.7 %, A 93.7 %, E 94.3 % (the
integrality gap, not the solver, limits them).
"""

import os

THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
THREADS_PRESET = {k: os.environ.get(k) for k in THREAD_VARS}
for _var in THREAD_VARS:  # before numpy is imported; the children inherit it
    os.environ.setdefault(_var, "1")

import cProfile  # noqa: E402
import dataclasses  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import pstats  # noqa: E402
import signal  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

CHILD_FLAG = "--child"
SIZES = ((60, 200, 6), (120, 800, 10))  # (N elements, C candidates, R sensors)
CRITERIA = ("D", "A", "E")
N_LOADS = 300
EXAMPLE = "openlab-like"
EDGE_GAP = 0.1  # m, first and last candidate from the bridge ends
GAP_TARGET = 1e-6
RECOMMEND_TARGET_S = (5.0, 30.0)  # per size, D + A + E together
CVXPY_TIMEOUT_S = 120.0
CVXPY_SKIP_S = 30.0  # skip cvxpy at size 2 if size 1 took longer than this
TIMEOUT_S = (300.0, 400.0)  # per size: fast, greedy, recommend children
PROFILE_BUDGET_S = (120.0, 300.0)  # per size: profiled recommend() runs (stopped after this)
MEMORY_LIMIT_GB = 8.0
TOP = 14
WARM = (10, 20, 2)  # tiny warm-up problem


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


# --------------------------------------------------------------------------- the problems --

def make_case(n_elements):
    import sensorplan as sp
    from sensorplan.io.config import example_case

    base = example_case(EXAMPLE)
    case = base.with_mesh(sp.Mesh.uniform(base.bridge, n_elements))
    stop = case.bridge.length + case.vehicle.length  # the whole vehicle crosses
    return dataclasses.replace(case, sweep=sp.LoadSweep(np.linspace(0.0, stop, N_LOADS)))


def make_candidates(case, n_candidates):
    return np.linspace(EDGE_GAP, case.bridge.length - EDGE_GAP, n_candidates)


def build(n_elements, n_candidates, count, crit):
    from sensorplan.design.recommend import CandidateGrid, build_problem

    case = make_case(n_elements)
    cands = make_candidates(case, n_candidates)
    return case, cands, build_problem(case, count, crit, grid=CandidateGrid(positions=cands))


# ----------------------------------------------------------------------- child processes --

def _efficiency(problem, utility, bound_utility):
    """Certified efficiency of a layout of ``utility`` against a utility bound."""
    crit = problem.criterion
    sign = 1.0 if crit.maximise else -1.0
    return crit.efficiency(sign * utility, sign * bound_utility)


def task_relaxation(spec):
    from sensorplan.design.relaxation import solve_relaxation
    from sensorplan.design.selection import exchange, round_weights

    def run(n, c, r):
        _, _, problem = build(n, c, r, spec["crit"])
        t0 = time.perf_counter()
        rel = solve_relaxation(problem, spec["solver"])
        t_rel = time.perf_counter() - t0
        t0 = time.perf_counter()
        layout, util = exchange(problem, round_weights(problem, rel.weights))
        t_int = time.perf_counter() - t0
        return problem, rel, t_rel, util, t_int

    run(*WARM)
    problem, rel, t_rel, util, t_int = run(*spec["size"])
    return {"time": t_rel, "gap": rel.relative_gap, "utility": rel.utility, "bound": rel.bound,
            "status": str(rel.stats.get("status")), "iterations": rel.stats.get("iterations"),
            "rounds": rel.stats.get("rounds"), "working_set": rel.stats.get("working_set"),
            "newton": rel.stats.get("newton_iterations"), "int_utility": util, "int_time": t_int,
            "int_eff": _efficiency(problem, util, rel.bound), "n_params": problem.n_params,
            "n_candidates": problem.n_candidates}


def task_greedy(spec):
    from sensorplan.design.selection import exchange, greedy

    def run(n, c, r):
        _, _, problem = build(n, c, r, spec["crit"])
        t0 = time.perf_counter()
        layout, u_greedy = greedy(problem)
        t_greedy = time.perf_counter() - t0
        t0 = time.perf_counter()
        layout, u_exch = exchange(problem, layout)
        return u_greedy, t_greedy, u_exch, time.perf_counter() - t0

    run(*WARM)
    u_greedy, t_greedy, u_exch, t_exch = run(*spec["size"])
    return {"t_greedy": t_greedy, "t_exchange": t_exch, "time": t_greedy + t_exch,
            "u_greedy": u_greedy, "utility": u_exch}


def task_recommend(spec):
    from sensorplan.design.criteria import make_criterion
    from sensorplan.design.recommend import CandidateGrid, recommend

    def run(n, c, r):
        case = make_case(n)
        cands = make_candidates(case, c)
        t0 = time.perf_counter()
        res = recommend(case, r, spec['crit'], curve_max=0, grid=CandidateGrid(positions=cands))
        return res, time.perf_counter() - t0

    run(*WARM)
    res, dt = run(*spec["size"])
    best = res.best_baseline()
    crit = make_criterion(spec["crit"], res.n_params)
    b_eff = None if best is None else crit.efficiency(res.baseline(best).value, res.bound)
    sign = 1.0 if crit.maximise else -1.0
    return {"time": dt, "gap": res.solver.relative_gap, "t_relaxation": res.solver.time_s,
            "efficiency": res.efficiency, "value": res.value, "bound": res.bound, "method": res.method,
            "utility": sign * res.value, "best_baseline": best, "baseline_eff": b_eff,
            "layout_m": list(res.layout_m)}


class _Budget(Exception):
    pass


def task_profile(spec):
    """cProfile of recommend() for the criteria in turn, stopped after a time budget."""
    from sensorplan.design.recommend import CandidateGrid, recommend

    def run(n, c, r, crit):
        case = make_case(n)
        return recommend(case, r, crit, curve_max=0, grid=CandidateGrid(positions=make_candidates(case, c)))

    for crit in spec["crits"]:
        run(*WARM, crit)

    def stop(signum, frame):
        raise _Budget()

    profiler = cProfile.Profile()
    done = []
    signal.signal(signal.SIGALRM, stop)
    signal.setitimer(signal.ITIMER_REAL, spec["budget"])
    t0 = time.perf_counter()
    try:
        for crit in spec["crits"]:
            profiler.enable()
            run(*spec["size"], crit)
            profiler.disable()
            done.append(crit)
    except _Budget:
        profiler.disable()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
    elapsed = time.perf_counter() - t0
    out = io.StringIO()
    pstats.Stats(profiler, stream=out).strip_dirs().sort_stats("tottime").print_stats(spec["top"])
    text = out.getvalue().strip("\n").splitlines()
    start = next((i for i, s in enumerate(text) if s.lstrip().startswith("ncalls")), 0)
    out = io.StringIO()
    pstats.Stats(profiler, stream=out).strip_dirs().sort_stats("cumulative").print_stats(spec["top"])
    text2 = out.getvalue().strip("\n").splitlines()
    start2 = next((i for i, s in enumerate(text2) if s.lstrip().startswith("ncalls")), 0)
    return {"done": done, "elapsed": elapsed, "tottime": text[start:], "cumulative": text2[start2:]}


TASKS = {"relaxation": task_relaxation, "greedy": task_greedy, "recommend": task_recommend,
         "profile": task_profile}


def child_main(spec_text):
    spec = json.loads(spec_text)
    import warnings

    import cvxpy  # noqa: F401  (imported up front: the fast path for E imports it lazily)

    warnings.simplefilter("ignore")
    result = TASKS[spec["task"]](spec)
    print(json.dumps(result))


def _limit_memory():
    import resource

    limit = int(MEMORY_LIMIT_GB * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def run_child(spec, timeout):
    """Run one measurement in a child process; a dict, with "error" on timeout or failure."""
    cmd = [sys.executable, str(Path(__file__).resolve()), CHILD_FLAG, json.dumps(spec)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=str(ROOT),
                              preexec_fn=_limit_memory)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout:g} s", "timeout": True}
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        lines = proc.stderr.strip().splitlines()
        return {"error": (lines[-1] if lines else f"exit code {proc.returncode}")[:150], "child_s": wall}
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["child_s"] = wall
    return out


# ------------------------------------------------------------------------------- report --

def fmt_time(r, width=9):
    """Time column of a failed or timed-out child."""
    if r.get("timeout"):
        limit = CVXPY_TIMEOUT_S if r.get("cvx") else r.get("limit", 0.0)
        return f"{'> ' + format(limit, 'g'):>{width}}"
    return f"{'failed':>{width}}"


def gap_verdict(gap):
    return "-" if gap is None else ("met" if gap <= GAP_TARGET else "NOT MET")


def main():
    wall0 = time.perf_counter()
    load0 = os.getloadavg()
    cores = os.cpu_count()
    line = "-" * 122
    env = ", ".join(f"{k}={os.environ.get(k)}" + ("" if THREADS_PRESET[k] is not None else " (set here)")
                    for k in THREAD_VARS)
    import cvxpy
    import scipy

    from sensorplan.design.criteria import make_criterion

    print("sensorplan optimal sensor placement benchmark (relaxations, greedy + exchange, recommend)")
    print(f"sensorplan commit {package_commit()}; numpy {np.__version__}, scipy {scipy.__version__}, "
          f"cvxpy {cvxpy.__version__}, "
          f"{cores} logical CPU(s); {env}")
    print("  (BLAS threads should be 1, as the CLI sets OPENBLAS_NUM_THREADS=1; the children inherit them)")
    print(f"load average (1 min) {load0[0]:.2f} at start (> {cores} means other processes compete "
          f"for the cores)", flush=True)
    case = make_case(SIZES[0][0])
    b = case.bridge
    print(f"Bridge: {EXAMPLE}, spans {'+'.join(f'{x:g}' for x in b.spans)} m, rotational end springs "
          f"{' and '.join(f'{k:.1e}' for k in b.spring_stiffness())} N m/rad (fixed, springs=False -> P = N),")
    print(f"  {case.vehicle.n_axles}-axle vehicle ({case.vehicle.total_load / 1e3:g} kN), {N_LOADS} load "
          f"positions 0..{case.sweep.positions[-1]:g} m, noise {case.noise.std[0]:.1e} rad, 1 crossing; "
          f"candidates linspace({EDGE_GAP:g}, {b.length - EDGE_GAP:g}, C).")
    print(line, flush=True)

    results = {}
    cvxpy_size1 = {}
    for k, (n, c, r) in enumerate(SIZES):
        size = [n, c, r]
        limit = TIMEOUT_S[k]
        for crit in CRITERIA:
            row = {}
            skip = k > 0 and cvxpy_size1.get(crit, 0.0) > CVXPY_SKIP_S
            if skip:
                row["cvxpy"] = None
            else:
                row["cvxpy"] = run_child({"task": "relaxation", "solver": "cvxpy", "crit": crit, "size": size},
                                         CVXPY_TIMEOUT_S)
                row["cvxpy"]["cvx"] = True
                if k == 0:
                    cv = row["cvxpy"]
                    cvxpy_size1[crit] = cv["time"] if "error" not in cv else math.inf
            for name, spec in (("fast", {"task": "relaxation", "solver": "fast"}),
                               ("greedy", {"task": "greedy"}), ("recommend", {"task": "recommend"})):
                row[name] = run_child(dict(spec, crit=crit, size=size), limit)
                row[name]["limit"] = limit
            results[(k, crit)] = row
            print(f"  [done: size {k + 1}, {crit}, {time.perf_counter() - wall0:.0f} s elapsed]", flush=True)

    load1 = os.getloadavg()

    # --- tables ----------------------------------------------------------------------------
    print(line)
    notes = []
    all_gaps = []
    rec_totals = []
    for k, (n, c, r) in enumerate(SIZES):
        print(f"Size {k + 1}: N = {n} elements (P = {n} parameters), C = {c} candidates, R = {r} sensors")
        print(f"{'crit':<5}{'method':<24}{'time [s]':>9}{'rel. gap':>10}{'<=1e-6':>8}{'int. layout':>34}"
              f"{'+[s]':>7}{'cert. eff.':>11}{'vs cvxpy':>10}")
        total = 0.0
        total_known = True
        for crit in CRITERIA:
            row = results[(k, crit)]
            cv, fa, gr, rc = row["cvxpy"], row["fast"], row["greedy"], row["recommend"]
            ok = [x for x in (cv, fa) if x is not None and "error" not in x]
            best_bound = min(x["bound"] for x in ok) if ok else None
            t_cv = cv["time"] if cv is not None and "error" not in cv else None
            for label, x in (("(a) cvxpy + Clarabel", cv), ("(b) fast (column gen.)", fa)):
                if x is None:
                    took = (f"timed out after {CVXPY_TIMEOUT_S:g} s" if math.isinf(cvxpy_size1[crit])
                            else f"took {cvxpy_size1[crit]:.1f} s > {CVXPY_SKIP_S:g} s")
                    print(f"{crit:<5}{label:<24}{'skipped':>9}  (at size 1 it {took}; 16x the conic data here)")
                    continue
                if "error" in x:
                    print(f"{crit:<5}{label:<24}{fmt_time(x)}  {x['error']}")
                    continue
                all_gaps.append((k, crit, label, x["gap"]))
                ratio = ("" if t_cv is None or x is cv else f"{x['time'] / t_cv:>10.3f}")
                if x is fa and t_cv is None and cv is not None:
                    ratio = f"{'<' + format(fa['time'] / CVXPY_TIMEOUT_S, '.3f'):>10}"
                print(f"{crit:<5}{label:<24}{x['time']:>9.2f}{x['gap']:>10.1e}{gap_verdict(x['gap']):>8}"
                      f"{'rounding + exchange':>34}{x['int_time']:>7.2f}{100 * x['int_eff']:>10.2f}%{ratio}")
            if "error" in gr:
                print(f"{crit:<5}{'(c) greedy + exchange':<24}{fmt_time(gr)}  {gr['error']}")
            else:
                eff = None
                if best_bound is not None:
                    sign = 1.0 if crit != "A" else -1.0
                    eff = make_criterion(crit, n).efficiency(sign * gr["utility"], sign * best_bound)
                eff_s = f"{100 * eff:>10.2f}%" if eff is not None else f"{'no bound':>11}"
                print(f"{crit:<5}{'(c) greedy + exchange':<24}{gr['time']:>9.2f}{'-':>10}{'-':>8}"
                      f"{'(greedy ' + format(gr['t_greedy'], '.2f') + ' s + exchange)':>34}"
                      f"{gr['t_exchange']:>7.2f}{eff_s}")
            if "error" in rc:
                print(f"{crit:<5}{'(d) recommend()':<24}{fmt_time(rc)}  {rc['error']}")
                total += rc.get("limit", 0.0) if rc.get("timeout") else 0.0
                total_known = False
            else:
                total += rc["time"]
                all_gaps.append((k, crit, "(d) recommend() relaxation", rc["gap"]))
                ratio = "" if t_cv is None else f"{rc['time'] / t_cv:>10.3f}"
                print(f"{crit:<5}{'(d) recommend()':<24}{rc['time']:>9.2f}{rc['gap']:>10.1e}"
                      f"{gap_verdict(rc['gap']):>8}{rc['method'][:33]:>34}{'':>7}"
                      f"{100 * rc['efficiency']:>10.2f}%{ratio}")
                notes.append(f"size {k + 1} {crit}: recommend() spent {rc['t_relaxation']:.2f} s of "
                             f"{rc['time']:.2f} s in the fast relaxation; best baseline {rc['best_baseline']} "
                             f"certified efficiency {100 * rc['baseline_eff']:.2f} %; layout "
                             + ", ".join(f"{x:.2f}" for x in rc["layout_m"]) + " m")
            if cv is not None and fa is not None and "error" not in cv and "error" not in fa:
                notes.append(f"size {k + 1} {crit}: certified bounds (utility) cvxpy {cv['bound']:.10g}, "
                             f"fast {fa['bound']:.10g}; relaxed utilities {cv['utility']:.10g}, "
                             f"{fa['utility']:.10g}; fast: {fa['rounds']} rounds, working set "
                             f"{fa['working_set']} of {c}, {fa['newton']} Newton iterations")
            elif fa is not None and "error" not in fa:
                notes.append(f"size {k + 1} {crit}: fast: {fa['rounds']} rounds, working set "
                             f"{fa['working_set']} of {c}, {fa['newton']} Newton iterations")
        rec_totals.append((total, total_known))
        print(line)
    print("time: (a), (b) the relaxation only; (c) greedy + exchange; (d) the whole recommend(), problem "
          "build included.")
    print("int. layout / +[s]: how the integer layout was obtained and the extra time it took (not in 'time');")
    print("cert. eff.: certified efficiency of that layout against the bound of the same relaxation, (c) "
          "against the tightest")
    print("bound of (a) and (b), (d) against recommend()'s own bound.  vs cvxpy: time / cvxpy time (same "
          "size and criterion).")
    for text in notes:
        print("  " + text)
    print(line)

    # --- targets ---------------------------------------------------------------------------
    note = "" if cores == 2 else f" (this machine has {cores} logical CPUs, not 2)"
    print(f"Targets (on this machine{note}; load average {load0[0]:.2f} at start, {load1[0]:.2f} at end):")
    bad = [g for g in all_gaps if g[3] > GAP_TARGET]
    worst = max(all_gaps, key=lambda g: g[3]) if all_gaps else None
    missing = sum(1 for row in results.values() for x in (row["cvxpy"], row["fast"])
                  if x is None or "error" in x)
    verdict = "MET" if not bad else f"NOT MET for {len(bad)} of {len(all_gaps)}"
    print(f"  relaxations solved to a relative duality gap <= {GAP_TARGET:g}: {verdict} "
          f"({len(all_gaps)} solved, largest gap {worst[3]:.2e} ({worst[2]}, size {worst[0] + 1}, {worst[1]}); "
          f"{missing} relaxation(s) not solved: skipped or timed out)")
    for g in bad:
        print(f"    size {g[0] + 1} {g[1]} {g[2]}: gap {g[3]:.2e} = {g[3] / GAP_TARGET:.1f} x the target")
    over = []
    for k, (total, known) in enumerate(rec_totals):
        target = RECOMMEND_TARGET_S[k]
        per = ", ".join(f"{crit} " + (f"{results[(k, crit)]['recommend']['time']:.2f}"
                                      if "error" not in results[(k, crit)]["recommend"]
                                      else f"> {results[(k, crit)]['recommend'].get('limit', 0):g}")
                        for crit in CRITERIA)
        lead = "" if known else "> "
        met = known and total < target
        verdict = "MET" if met else (f"NOT MET: {lead}{total:.1f} s = {lead}{total / target:.1f} x the target, "
                                     f"{lead}{total - target:.1f} s over")
        print(f"  size {k + 1}: recommend() for D + A + E under {target:g} s: {lead}{total:.2f} s ({per}) "
              f"-> {verdict}")
        if not met:
            over.append(k)
    effs = []
    for k in range(len(SIZES)):
        for crit in CRITERIA:
            rc = results[(k, crit)]["recommend"]
            effs.append(f"size {k + 1} {crit} " + ("n/a" if "error" in rc else f"{100 * rc['efficiency']:.2f} %"))
    print("  certified efficiencies of the recommended layouts: " + "; ".join(effs))
    print(line)

    # --- profiles where the time target was missed ------------------------------------------
    for k in over:
        n, c, r = SIZES[k]
        budget = PROFILE_BUDGET_S[k]
        prof = run_child({"task": "profile", "crits": list(CRITERIA), "size": [n, c, r], "top": TOP,
                          "budget": budget}, budget + 120.0)
        print(f"cProfile of recommend() at size {k + 1} (criteria {', '.join(CRITERIA)} in turn, stopped after "
              f"{budget:g} s of profiling):")
        if "error" in prof:
            print(f"  profile failed: {prof['error']}")
            continue
        done = prof["done"]
        print(f"  completed under the profiler: {', '.join(done) if done else 'none'}"
              + ("" if len(done) == len(CRITERIA) else
                 f"; {CRITERIA[len(done)]} was interrupted (its partial profile is included)")
              + f"; {prof['elapsed']:.1f} s profiled")
        print(f"  top {TOP} by internal time:")
        print("\n".join("  " + s for s in prof["tottime"]))
        print(f"  top {TOP} by cumulative time:")
        print("\n".join("  " + s for s in prof["cumulative"]))
        print(line)
    print(f"load average (1 min) {load0[0]:.2f} at start, {os.getloadavg()[0]:.2f} at end")
    print(f"Total benchmark run time: {time.perf_counter() - wall0:.1f} s")


if __name__ == "__main__":
    if CHILD_FLAG in sys.argv[1:]:
        child_main(sys.argv[sys.argv.index(CHILD_FLAG) + 1])
    else:
        main()
