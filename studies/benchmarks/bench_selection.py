"""Benchmark of the integer searches at network scale: baselines, greedy, best layout (rounding + exchange), curve.

What it measures
----------------
The five-span bridge of :mod:`bench_network` (30 + 40 + 40 + 40 + 30 m,
N = 400 elements, C = 3,000 candidate tiltmeters, R = 20, structured Fisher
blocks), one BLAS thread, in a child process per criterion (D, A): the CPU
seconds (``time.process_time``) of the stages of ``recommend`` that do not
solve the relaxation, and the number of exact evaluations (Cholesky
factorisations of a P x P precision, counted by wrapping
``numpy.linalg.cholesky`` in the child).  The relaxation is solved once per
criterion (not timed) for the relaxed weights that ``best_layout`` rounds;
``--weights DIR`` keeps them between runs, so that two trees can be compared
on the same weights.  ``--out FILE`` writes the layouts, utilities and curve
of the run (JSON); ``--compare A B`` prints whether two such files hold the
same layouts and how far their utilities are apart.

How to run
----------
From the repository root::

    python studies/benchmarks/bench_selection.py [--crit=D] [--crit=A] [--weights DIR] [--out FILE]
    python studies/benchmarks/bench_selection.py --compare main.json branch.json

Last run
--------
2026-11-28, 01:10-02:20 UTC, branch s15-select (0653bec) against main
d95c1d0 (same relaxed weights, same period), a 2-core machine shared with
two other helpers' jobs (load average 4-6 throughout: the CPU seconds are
inflated by about 1.5-2x against a quiet machine; compare the rows, not
the absolute values).  CPU seconds per stage and exact evaluations::

    criterion  tree        baselines  greedy    best  curve   total   evals greedy / best
    D          main            7.8     57.4   147.3   10.5   223.0    14,395 / 42,036
    D          s15-select      9.2     20.3    45.1    2.9    77.5     2,120 / 10,462
    A          main            8.2    224.8   215.9   11.3   460.2    34,903 / 37,375
    A          s15-select      8.0     25.5    76.2    3.5   113.2     1,679 / 13,564

(quiet machine, main d95c1d0 under cProfile, for scale: D baselines 7.7,
greedy 53.0, best 132.6, curve 10.2 s.)  Same layouts as main for D and A
(greedy layout, recommended layout and method, every baseline, the
curve's counts); utilities equal to 3e-12 (D, 1.5e-15 relative) and
2e-14 (A): small layouts of structured blocks are summed from their
cached dense blocks instead of the structured weighted sum (round-off).
Peak RSS of these stages (no relaxation): 1.96 GiB (D), 1.72 GiB (A).
A run of this script (D, load average 5-6): baselines 7.8, greedy 21.5,
best 48.0, curve 2.9 s, 2,120 / 8,335 exact evaluations (thresholds of
c41c7d2: more evaluations, fewer bounds since).

Where the time goes now (D, a profile of greedy alone): the eigen-split
bounds on the survivors (k = 16 .. 128: 13.7 s of 20.2 s, the k = 128
level 7.5 s) and 2,080 exact evaluations; in best the exact
evaluations of the candidates within about 7 m of the sensor being
exchanged (their values are within 0.1-0.2 of the best, closer than any
eigen-split bound with k <= 128 can separate: 50-150 survive a position
of the final exchange) and the local moves of the polish (41 neighbours
per sensor, evaluated exactly: bounds do not separate them either).  The
concavity bound at the best candidate evaluated (utility(Q + I_b) +
<G_b, I_i - I_b>) was tried and is looser than the eigen-split even for
b's neighbours (median slack 0.49 within 6 m); skipping, in the first
round of the full exchange, the neighbours the polish's local moves have
just checked saved 129 of 10,462 evaluations (neither is kept).

Acceptance (issue 38: the whole ``recommend`` < 60 s at N = 400, C = 3,000,
R = 20; these stages' share about 25 s): not met as measured (D 77.5 s,
A 113.2 s of stages under load 4-6, against 223.0 s and 460.2 s for main
in the same period: 2.9x and 4.1x less CPU).
"""

import os

THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
for _var in THREAD_VARS:  # before numpy is imported; the children inherit it
    os.environ[_var] = "1"

import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

CHILD_FLAG = "--child"
N_ELEMENTS, N_CANDIDATES, COUNT = 400, 3000, 20


def run_child(crit, weights_dir):
    """Stages of one criterion in CPU seconds, exact evaluations per stage, layouts and utilities."""
    counter = {"n": 0}
    cholesky = np.linalg.cholesky

    def counted(a, *args, **kwargs):
        if a.ndim == 2 and a.shape[0] == N_ELEMENTS:
            counter["n"] += 1
        return cholesky(a, *args, **kwargs)

    np.linalg.cholesky = counted
    import bench_network as bn
    from sensorplan.design.baselines import baselines as make_baselines
    from sensorplan.design.recommend import CandidateGrid, build_problem, criterion_curve
    from sensorplan.design.relaxation import solve_relaxation
    from sensorplan.design.selection import best_layout, greedy

    case = bn.five_span(N_ELEMENTS)
    grid = CandidateGrid(positions=tuple(np.linspace(0.1, case.bridge.length - 0.1, N_CANDIDATES)),
                         kinds=("rotation",))
    problem = build_problem(case, COUNT, crit, grid=grid)
    stages, evals, out = {}, {}, {}

    def stage(name, run):
        start, t = counter["n"], time.process_time()
        result = run()
        stages[name], evals[name] = time.process_time() - t, counter["n"] - start
        return result

    base = stage("baselines", lambda: make_baselines(problem, length=case.bridge.length,
                                                     support_positions=case.bridge.support_positions,
                                                     n_random=100, rng=0))
    g_layout, g_util = stage("greedy", lambda: greedy(problem))
    path = None if weights_dir is None else Path(weights_dir) / f"weights_{crit}_{N_CANDIDATES}.npy"
    if path is not None and path.exists():
        weights = np.load(path)
    else:
        weights = solve_relaxation(problem, "auto", start_layout=g_layout).weights
        if path is not None:
            np.save(path, weights)
    method, layout, util = stage("best", lambda: best_layout(problem, weights, base, greedy_layout=g_layout, rng=0))
    curve = stage("curve", lambda: criterion_curve(problem, COUNT, None, weights, layout, greedy_layout=g_layout))
    out.update(greedy=[int(i) for i in g_layout], greedy_u=g_util, method=method, layout=[int(i) for i in layout],
               util=util, baselines={k: None if v is None else [int(i) for i in v] for k, v in base.items()},
               curve=[(p.count, p.value, p.bound) for p in curve])
    return {"crit": crit, "stages": stages, "evals": evals, **out}


def compare(first, second):
    """Whether two --out files hold the same layouts, and the largest utility difference."""
    a, b = (json.loads(Path(f).read_text()) for f in (first, second))
    for ra, rb in zip(a, b):
        same = {k: ra[k] == rb[k] for k in ("greedy", "layout", "method", "baselines")}
        same["curve counts"] = [c[0] for c in ra["curve"]] == [c[0] for c in rb["curve"]]
        diff = max([abs(ra["util"] - rb["util"]), abs(ra["greedy_u"] - rb["greedy_u"])]
                   + [abs(x[1] - y[1]) for x, y in zip(ra["curve"], rb["curve"]) if x[1] is not None])
        print(f"{ra['crit']}: same {same}; largest utility difference {diff:.1e}")


def main(crits, weights_dir, out_file):
    print(f"load average at start: {os.getloadavg()}")
    print(f"{'crit':<5s} {'baselines':>9s} {'greedy':>7s} {'best':>7s} {'curve':>6s}  evals (greedy / best)")
    results = []
    for crit in crits:
        cmd = [sys.executable, __file__, CHILD_FLAG, crit, weights_dir or ""]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            print(f"{crit:<5s} failed: {(done.stderr.strip().splitlines() or ['?'])[-1]}")
            continue
        res = json.loads(done.stdout.strip().splitlines()[-1])
        results.append(res)
        s, e = res["stages"], res["evals"]
        print(f"{crit:<5s} {s['baselines']:9.1f} {s['greedy']:7.1f} {s['best']:7.1f} {s['curve']:6.1f}  "
              f"{e['greedy']:,} / {e['best']:,}", flush=True)
    if out_file:
        Path(out_file).write_text(json.dumps(results))
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    argv = sys.argv[1:]
    if argv and argv[0] == CHILD_FLAG:
        print(json.dumps(run_child(argv[1], argv[2] or None)))
    elif argv and argv[0] == "--compare":
        compare(argv[1], argv[2])
    else:
        chosen = [a.split("=", 1)[1] for a in argv if a.startswith("--crit=")] or ["D", "A"]
        w = argv[argv.index("--weights") + 1] if "--weights" in argv else None
        o = argv[argv.index("--out") + 1] if "--out" in argv else None
        main(chosen, w, o)
