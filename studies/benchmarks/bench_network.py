"""Benchmark of design at network scale: a five-span continuous bridge, thousands of candidates, 20 sensors.

What it measures
----------------
The bridge: five continuous spans 30 + 40 + 40 + 40 + 30 m (180 m), EI
2e11 N m^2, pinned supports, a three-axle vehicle (60 + 50 + 50 kN, axles
at 0, 3.5 and 4.9 m), tiltmeters of 5 urad (deflection gauges of 0.1 mm for
the mixed design), a sweep of the front axle from 0 to 185 m every 0.25 m
(741 load positions), one crossing, the default GMRF prior.  Built through
the public API (``case_from_toml``, as the embedded examples are).
Candidates ``np.linspace(0.1, 179.9, C)`` so that C is exact.

For each configuration, in a child process (one BLAS thread,
``OPENBLAS_NUM_THREADS = OMP_NUM_THREADS = MKL_NUM_THREADS = 1``), the CPU
seconds (``time.process_time``) of the stages of ``recommend``:

* build: ``build_problem`` (candidate Fisher blocks, constraints);
* baselines, greedy, relaxation (``solve_relaxation(problem, "auto")``),
  best (rounding + exchange from every start), curve
  (``criterion_curve``: criterion versus R up to the requested R),
  the total; the relaxation's certified relative gap
  ((bound - utility) / max(1, |bound|), the bound computed by the
  criterion's own certificate over all candidates); the certified
  efficiency of the recommended layout; peak resident memory of the child
  (``ru_maxrss``), and the up-front estimate of
  :mod:`sensorplan.design.resources` for comparison.

Configurations:

* target: N = 400 elements, C = 3,000 candidates, R = 20, criteria D, A, E
  (acceptance of issue 38: each < 60 s CPU, gap <= 1e-6, peak <= 4 GiB);
* mixed: rotation + deflection at 1,500 positions (C = 3,000 candidates),
  costs 1 and 3, budget 40, R = 20, D (acceptance: < 120 s);
* growth: D with R = 20 against C in (200, 400, 800, 1600, 3000) at N = 400
  and against N in (60, 120, 240, 400) at C = 800; the exponents of
  time ~ C^a and time ~ N^b are fitted by least squares on the logs.

Nothing is asserted; the targets are printed as met / not met.

How to run
----------
From the repository root::

    python studies/benchmarks/bench_network.py [--quick] [--part=target] [--part=growth]

``--quick`` runs the growth series only up to C = 800 and N = 240 and the
target configurations at C = 800 (to check the script).  Each child has a
timeout of ``TIMEOUT_S``; a child that times out or fails is reported as such.

Last run
--------
Target rows, 2026-11-29 02:37-02:40 UTC, this tree (session 24: the small
SDPs' Schur complement by triangular products, E's side rows priced; D, A
and mixed as before), one BLAS thread, load average 1.0-1.2 (nothing else
running)::

    configuration                  build    base  greedy   relax    best   curve    total       gap    eff   peak    est   est_s
    D N=400 C=3000 R=20              1.1     1.7     3.6     6.2    20.4     1.4     34.5   1.6e-08  0.989   1.13   2.22      59
    A N=400 C=3000 R=20              0.5     2.0     6.2     7.5    23.3     2.0     41.5   1.9e-10  0.928   1.09   2.22      59
    E N=400 C=3000 R=20              0.5     2.0     3.4     8.3    14.4     1.9     30.5   5.0e-07  0.897   1.31   2.22      59
    mixed D N=400 C=3000 R=20        0.7     3.5     5.4     5.7    29.2     3.4     47.9   2.2e-08  0.989   1.14   2.34      62

E 34.2 s before the triangular products (relaxation 8.9 s, both measured
the same day; 11.0-12.9 s in the runs below), the same efficiency.  On the
six-span viaduct with stiff end springs of docs/limitations.md E took
71.2 s (relaxation 44.7 s; 86.0 and 60.6 s before).

Before: target rows, 2026-11-28 21:01-21:04 UTC (session 22: E's
relaxation to a gap of 1e-6 with every small SDP warm-started; exchange
takes E's swaps only when they gain more than 1e-6 of lambda_min; the
polish's local moves in two levels, every 5th of the 20 neighbours on each
side and then the 5 nearest), one BLAS thread, quiet machine (load average
0.1-0.9)::

    configuration                  build    base  greedy   relax    best   curve    total       gap    eff   peak    est   est_s
    D N=400 C=3000 R=20              1.1     1.8     3.8     6.1    18.9     1.4     33.1   1.6e-08  0.989   1.04   2.22      59
    A N=400 C=3000 R=20              0.5     2.1     7.0     7.1    23.3     2.2     42.3   1.9e-10  0.928   1.06   2.22      59
    E N=400 C=3000 R=20              0.6     2.6     3.9    12.9    15.1     2.9     37.9   3.2e-07  0.897   1.30   2.22      59
    mixed D N=400 C=3000 R=20        0.7     3.6     5.2     5.6    28.3     3.4     46.8   2.2e-08  0.989   1.14   2.34      62

After E's smallest eigenpair alone by dsyevr (commit ca00212; 21:40, load
0.4-1.0): D 33.4 s, A 42.1 s, E 34.8 s (relaxation 12.2, best 14.3, curve
1.9 s), the same layouts and efficiencies.

After E's small SDPs formed their Schur complement in single precision far
from their optimum (commit 744c4dc; 2026-11-28 23:45, back to back with
29264dc, on a machine running 10-20 % slower than above): E's relaxation
12.3 -> 11.0 s, E in all 35.8 -> 36.6 s (the rounding-and-exchange stage
varies with its start), gap 6.4e-7, efficiency 0.897 -> 0.9065.  No small
SDP here takes more than 25 steps, so the stall rule of 3a3a06a changes
nothing on this bridge.  After the split bounds took each half of more than
200 survivors along its own eigenvectors (commit 1272bfc; 2026-11-29 00:05,
same machine): A 49.6 -> 45.8 s (greedy 8.2 -> 6.6, best 26.9 -> 26.1),
efficiency 0.928 unchanged; D 33.1 -> 35.0 s (29264dc back to back; greedy
3.8 -> 4.0, best 18.9 -> 20.2), efficiency 0.989 unchanged.  After a far
swap of the polish's full search sent it back to the local moves (commit
b1ab5f5; 00:30, another job on the second core): A 42.9 s (greedy 6.4, best
24.4), D 36.2 s (best 21.6), E 35.5 s, the same efficiencies.

E 45.3 -> 37.9 s; its layout is the one it had with a gap of 1e-6 before
session 19 (efficiency 0.897; 0.909 from the cold 1e-7 relaxation, which
rounded to a better start here and to worse ones on other bridges, see
docs/limitations.md).  A 44.0 -> 42.3 s, the same efficiency.  D and mixed
end in better layouts (D 1971.4635 instead of 1971.4609) after a longer
final search (D 27.9 -> 33.1 s, mixed 38.3 -> 46.8 s): the two-level local
moves leave moves of more than 5 candidates to the full search, which on D
costs 0.14 s a search.  Through the command line (user + sys CPU, figures
and JSON included): D 40.0 s, A 49.1 s, E 42.4 s.

Before: target rows, 2026-11-28 13:15-13:18 UTC, main 51b562d (session 19: E's
small SDPs warm-started from the last round's weights while the relative
gap exceeds 1e-3; D, A and mixed unchanged), one BLAS thread, quiet
machine (load average 1.0)::

    configuration                      build  base greedy  relax   best  curve  total     gap   eff  peak   est  est_s
    D N=400 C=3000 R=20                  0.5   1.8    3.7    6.0   14.6    1.4   27.9  1.6e-8  0.989  0.79  2.22    59
    A N=400 C=3000 R=20                  0.5   2.0    6.5    7.4   25.4    2.1   44.0  1.9e-10 0.928  0.91  2.22    59
    E N=400 C=3000 R=20                  0.5   2.2    3.5   19.6   16.7    2.8   45.3  3.9e-8  0.909  1.34  2.22    59
    mixed D N=400 C=3000 R=20            0.7   3.3    5.0    5.3   20.5    3.5   38.3  2.2e-8  0.989  0.86  2.34    62

E's relaxation went from 23.6 to 19.6 s (the rounds' small SDPs take about
a third fewer interior-point steps from the warm start) and its best stage
from 19.4 to 16.7 s, with the same certified efficiency.  Through the
command line (``recommend --config five-span.toml --criterion X --count 20
--spacing 0.06``: 3,001 candidates, figures and JSON included, user + sys
CPU): D 36.6 s, A 48.9 s, E 55.0 s (56.9 s before the warm start).  The
seven-span viaduct below: E 43.9 s (53.3 s cold), efficiency 0.927.

Growth rows and the table below: 2026-11-28 10:23-10:32 UTC, main 3eb96f4 (this session: structured
families without the fixed matrices they do not use and congruences in
place; the searches one candidate at a time and local moves stopped after
n quiet sensors; A's inverse traces by LAPACK; the relaxation's
preconditioner from rank-4 Nystrom roots of the structure held as product
rows, A's 64 leading weighting directions, single-precision Hessian
products, resumed rounds, A's entering share 1.0; E at the default
tolerance 1e-7), one BLAS thread, children one at a time on a quiet
machine (load average 0.9-1.2)::

    configuration                      build  base greedy  relax   best  curve  total     gap   eff  peak   est  est_s
    D N=400 C=3000 R=20                  0.6   2.0    3.9    6.3   15.8    1.4   30.1  1.6e-8  0.989  0.78  2.22    59
    A N=400 C=3000 R=20                  0.5   2.1    7.1    7.4   26.6    2.2   45.9  1.9e-10 0.928  0.90  2.22    59
    E N=400 C=3000 R=20                  0.5   2.5    3.7   23.6   19.4    3.0   52.6  6.0e-8  0.909  1.29  2.22    59
    mixed D N=400 C=3000 R=20            0.7   3.6    5.3    5.5   21.4    3.7   40.3  2.2e-8  0.989  0.84  2.34    62
    growth, D:
    D N=400 C=200  R=20                  0.2   1.3    1.6    1.5    9.9    1.3   15.7  1.5e-8  0.990  0.53  0.88    28
    D N=400 C=400  R=20                  0.3   1.4    2.0    2.2   13.2    1.2   20.2  1.6e-8  0.990  0.68  1.25    35
    D N=400 C=800  R=20                  0.3   1.6    2.6    3.2   11.6    1.2   20.5  5.3e-8  0.990  0.75  1.74    36
    D N=400 C=1600 R=20                  0.4   1.7    2.8    3.8   13.3    1.2   23.2  3.8e-9  0.989  0.98  2.17    57
    D N=60  C=800  R=20 (dense)          0.4   0.1    0.1    0.1    0.5    0.1    1.2  1.9e-10 0.972  0.22  0.32     1
    D N=120 C=800  R=20 (dense)          0.7   0.2    0.3    0.6    4.5    0.3    6.7  7.9e-10 0.980  0.40  0.42     2
    D N=240 C=800  R=20                  0.2   0.5    1.0    1.0    5.2    0.5    8.4  2.3e-8  0.985  0.34  0.81    10
    D N=400 C=800  R=20                  0.4   1.4    2.6    3.0   11.7    1.3   20.5  5.3e-8  0.990  0.75  1.74    36

A run of the same tree twenty minutes before (load 1.5-2, the helper's
last test commits not yet merged): D 28.7, A 44.6, E 49.6, mixed 39.0 s.
After the last changes of the session (11:06-11:10 UTC, commits 63e117e
and cea2e55: congruences from the whitened readings where many redundants
make the pair products dearer, and blocks formed ahead in searches
without split bounds), quiet machine: D 30.5, A 47.3-48.4, E 50.2-52.1,
mixed 40.0 s, the same layouts; the spread of A's best stage between runs
of the same tree is about +-1.5 s.

On a bridge the benchmark was not tuned on (a seven-span viaduct 25 + 5 x
32 + 25 m with rotational end springs of 2e9 N m/rad, EI 3e11 N m^2, 400
elements, a four-axle vehicle, 741 load positions, 3,000 candidates,
R = 20; the child's stages through the same public steps), last run: D
37.7 s, A 55.9 s (54.2-56.7 over three runs), E 51.7 s (51.7-56.2), gaps
<= 5.8e-8, peaks <= 1.5 GiB.  Its families have eight
redundant diagrams (the five-span's five), so the bound passes cost more;
through the command line with R = 24 (figures and report included) D 48,
A 71 and E 68 s of user CPU.

Recommended layouts, methods and utilities (checked by a script that runs
the child's stages and prints them): D "greedy + exchange"
1971.460873879109, A "relaxation rounding + exchange" -5.909064332162562
(the same 20 candidates as before; the utility moves by 2e-15 with the
order of the blocks' sums), mixed "greedy + exchange" 1971.4573988498967,
all as in the session before; E "relaxation rounding + exchange"
8.91781239014641, better than before (8.805258175010064, efficiency 0.909
instead of 0.897): the tighter relaxation (1e-7 instead of E's former
1e-6) rounds to a better start.  Relaxations: D 7 rounds, working set 321,
122 Newton steps, 350 CG iterations; A 8 rounds (was 13), 610, 128 steps
(203), 251 CG (497); mixed 6 rounds, 225, 95 steps, 245 CG.

Acceptance (issue 38) at N = 400, C = 3,000, R = 20 (the 21:01 run of
session 22; the 13:15 run of session 19 in brackets):

* D: 33.1 s CPU (27.9; met: < 60 s; 46.6 s before session 18), gap 1.6e-8
  (met), peak 1.04 GiB (met).
* A: 42.3 s (44.0; met; 83.8 s before), gap 1.9e-10 (met), peak 1.06 GiB
  (met).
* E: 37.9 s, 34.8 s after commit ca00212 (45.3; met; 58.8-60.1 s before),
  gap 3.2e-7 (met), peak 1.30 GiB (met).
* Mixed kinds (rotation + deflection, costs 1 and 3, budget 40): 46.8 s
  (38.3; met: < 120 s), gap 2.2e-8, peak 1.14 GiB.

Cost growth (D, least squares on the logs, the rows above with the target
row): time ~ C^0.21 at N = 400, C = 200 -> 3,000 (15.7 -> 30.1 s); time ~
N^1.36 at C = 800, N = 60 -> 400 (1.2 -> 20.5 s; N <= 120 on dense
blocks).  Before this session C^0.24 and N^1.61; before issue 38's work
(79499f2) C^0.61 and N^2.2.  The up-front estimate
(:mod:`sensorplan.design.resources`, recalibrated this session) is 1.2-2x
high for structured blocks (59 s at the target), about right at N = 240
and up to 3x low for N = 120 on dense blocks, where a design takes seconds.

Where the time went in session 18: the integer searches' best stage (A 27 s: three
coarse-grid exchanges about 13 s, each visit's first bounds an
eigendecomposition of Q and congruences over the coarse candidates; the
polish's local moves about 8 s, split bounds over 41 neighbours; the
final exchange over all candidates about 5 s, which certifies the local
optimum) and E's relaxation (24 s; at its former tolerance 1e-6 the small
SDPs took 17.9 s of 19.3 s).  An exact A
evaluation (a factorisation and a triangular inverse of 400 x 400, about
2.3 ms) settles most of a search; the candidates that reach it lie within
about 0.1 % of the value to beat, far closer than any cheaper bound.

Session 17 (2026-11-28 08:03-08:22 UTC, branch s17-int), same
conditions::

    D N=400 C=3000 R=20                  1.3   2.5    5.1   16.3   19.9    1.5   46.6  1.6e-8  0.989  1.53
    A N=400 C=3000 R=20                  0.7   2.7   10.8   26.9   40.5    2.2   83.8  1.0e-8  0.928  2.04
    E N=400 C=3000 R=20                  1.3   2.9    4.3   19.3   27.9    3.0   58.8  2.9e-7  0.897  1.47
    mixed D N=400 C=3000 R=20            0.8   4.8    6.0   12.3   28.3    3.6   55.9  2.2e-8  0.989  1.53

Session 16 (2026-11-28 05:00-05:27 UTC, branch s16-int), same conditions,
load about 2::

    D N=400 C=3000 R=20                  0.8   2.6    5.6   29.6   24.1    1.9   64.7  1.8e-10 0.989  2.00
    A N=400 C=3000 R=20                  0.7   2.8   14.4   46.2   57.4    2.6  124.2  1.0e-8  0.928  3.17
    E N=400 C=3000 R=20                  0.7   3.0    4.5  201.3   41.3    3.4  254.1  6.6e-8  0.897  1.42
    mixed D N=400 C=3000 R=20            1.6   4.4    7.4   20.0   29.7    4.1   67.1  1.5e-9  0.989  2.21

Earlier, 2026-11-28 02:30-02:50 UTC, branch s15-int2 (commits e20b965..fb2a57d:
the Newton-CG interior point on structured blocks, the screened greedy and
exchange of sensorplan.design.screening, E's Cholesky test, structured
blocks from 160 parameters on), one BLAS thread, children one at a time
with the clean-clone CI suite on the other core (load average about 2).

CPU seconds per stage; gap: certified relative gap of the relaxation; eff:
certified efficiency of the recommended layout; peak: measured peak RSS
[GiB]::

    configuration                      build  base greedy  relax   best  curve  total     gap   eff  peak
    D N=400 C=3000 R=20                  1.2   7.1   19.2   36.4   40.7    2.7  107.3  4.1e-11 0.989  2.06
    A N=400 C=3000 R=20                  0.7   7.1   23.7   68.8   74.5    3.9  178.7  3.1e-9  0.928  2.84
    mixed D N=400 C=3000 R=20            0.9  11.1   14.4   29.5   37.7    5.3   98.8  2.6e-10 0.989  2.12
    E N=400 C=800 R=20 (s15-e 7fa60c9)   7.9   3.9    7.0  263.8   54.6    5.7  343    3.5e-8    -    1.93
    growth, D:
    D N=400 C=200  R=20                  0.3   4.4    3.2    5.8   21.8    2.3   37.7  2.5e-10 0.990  0.95
    D N=400 C=400  R=20                  0.3   4.3    4.8   19.3   27.0    2.6   58.4  2.8e-8  0.990  1.51
    D N=400 C=800  R=20                  0.4   4.9    8.9   18.1   22.7    2.2   57.2  4.6e-9  0.990  1.96
    D N=400 C=1600 R=20                  0.5   5.8   12.4   36.3   32.1    2.9   90.1  7.4e-8  0.989  2.18
    D N=60  C=800  R=20 (dense)          0.4   0.1    0.2    0.1    0.6    0.1    1.4  1.9e-10 0.972  0.22
    D N=120 C=800  R=20 (dense)          0.9   0.2    0.4    0.7    5.4    0.3    8.0  7.9e-10 0.980  0.35
    D N=240 C=800  R=20                  0.2   1.8    3.5    5.1   10.9    0.9   22.5  2.8e-11 0.985  0.67
    main d95c1d0, quiet machine, under cProfile:
    D N=400 C=3000 R=20                  1.3   7.7   53.0   99.8  132.6   10.2  304.6  1.1e-8  0.989  2.19

The relaxations (D: 14 rounds, working set 287, 175 Newton steps, 16
exact Hessians instead of 116, 327 conjugate-gradient iterations; A: 16
rounds, working set 613, 192 Newton steps; mixed: 10 rounds, 249, 129)
reach the same optimum as main's (each utility below the other's bound).
At the target the layouts are those of main (greedy, recommended layout
and method, baselines, the curve's counts; studies/benchmarks/bench_selection.py).  E at C = 3,000 does not finish: its
relaxation was stopped after 261 s CPU in round 11 at gap 1.1e-3 (working
set 1,897 of 3,000 candidates, basis 62 columns, 30-55 s per small SDP:
the relaxed E optimum spreads weight over about two thirds of the
candidates and lambda_min has multiplicity 3 at the optimum); at C = 800
it reaches the gap in 35 rounds without the cvxpy fallback that made it
abort before.

Where the time goes now (D at the target): the relaxation's
preconditioner rows (exact Hessian rows of the working set's weighted
core, ~40 % of the stage) and Hessian products (~30 %), ~12 Newton steps
a round because each round restarts from a centred point; in greedy the
eigen-split bounds of the survivors (k = 16 .. 128); in best the exact
evaluations of the candidates near the sensor being exchanged (their
values are within 0.1-0.2 of the best, closer than an eigen-split bound
with k <= 128 separates) and the polish's local moves.  Below 160
parameters the dense blocks are used where they fit 1 GiB (N <= 40: 2x
faster than structured ones; N = 120 even).

Acceptance (issue 38) at N = 400, C = 3,000, R = 20:

* D: 107.3 s CPU (not met: < 60 s; 304.6 s at main), gap 4.1e-11 (met:
  <= 1e-6), peak 2.06 GiB (met: <= 4 GiB); the curve reaches R = 20.
* A: 178.7 s (not met), gap 3.1e-9 (met), peak 2.84 GiB (met).
* E: not met (does not finish at C = 3,000; 343 s at C = 800).
* Mixed kinds (rotation + deflection, costs 1 and 3, budget 40): 98.8 s
  (met: < 120 s), gap 2.6e-10, peak 2.12 GiB.

Cost growth (D, least squares on the logs, the rows above): time ~ C^0.37
at N = 400, C = 200 -> 3,000 (37.7 -> 107.3 s); time ~ N^1.9 at C = 800,
N = 60 -> 400 (1.4 -> 57.2 s; N <= 120 on dense blocks).  Before this
work (79499f2): C^0.61 and N^2.2.

Earlier (2026-11-27, s14-dae 98f4b74, load 9-12): D at the target 321.5 s
(relaxation 108.6, best 130.6, greedy 63.4), A at C = 800 256.7 s, mixed
at C = 800 158.8 s; E at C = 800 aborted in the cvxpy fallback.
"""

import os

THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
for _var in THREAD_VARS:  # before numpy is imported; the children inherit it
    os.environ[_var] = "1"

import json  # noqa: E402
import math  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

CHILD_FLAG = "--child"
TIMEOUT_S = 3600.0
GAP_TARGET = 1e-6
TIME_TARGET_S = 60.0
MIXED_TARGET_S = 120.0
MEMORY_TARGET_GIB = 4.0
GROWTH_C = (200, 400, 800, 1600, 3000)
GROWTH_N = (60, 120, 240, 400)

FIVE_SPAN = """
[case]
name = "five-span"

[bridge]
spans = [30.0, 40.0, 40.0, 40.0, 30.0]
ei = 2.0e11
elements = {n_elements}

[vehicle]
axle_offsets = [0.0, 3.5, 4.9]
axle_loads = [60.0e3, 50.0e3, 50.0e3]

[sensors]
names = ["T1", "T2"]
positions = [15.0, 50.0]
kinds = ["rotation", "rotation"]
noise_std = 5.0e-6

[loads]
start = 0.0
stop = 185.0
step = 0.25
"""


def five_span(n_elements):
    from sensorplan.io.config import case_from_toml

    return case_from_toml(FIVE_SPAN.format(n_elements=n_elements), name="five-span")


# ----------------------------------------------------------------------- the child --

def run_child(spec):
    """One recommendation, stage by stage (what ``recommend`` does), in CPU seconds, in a process tuned as the
    command line tunes its own (``keep_freed_memory``)."""
    from sensorplan import keep_freed_memory
    from sensorplan.design.baselines import baselines as make_baselines
    from sensorplan.design.recommend import CandidateGrid, Constraints, build_problem, criterion_curve
    from sensorplan.design.relaxation import solve_relaxation
    from sensorplan.design.resources import estimate_resources
    from sensorplan.design.selection import best_layout, greedy

    keep_freed_memory()
    case = five_span(spec["n"])
    mixed = spec.get("mixed", False)
    n_positions = spec["c"] // 2 if mixed else spec["c"]
    positions = tuple(np.linspace(0.1, case.bridge.length - 0.1, n_positions))
    kinds = ("rotation", "deflection") if mixed else ("rotation",)
    grid = CandidateGrid(positions=positions, kinds=kinds)
    options = {}
    if mixed:
        options = {"constraints": Constraints(costs={"rotation": 1.0, "deflection": 3.0}, budget=40.0),
                   "noise_std": {"rotation": 5e-6, "deflection": 1e-4}}
    stages = {}
    t = time.process_time()
    problem = build_problem(case, spec["r"], spec["crit"], grid=grid, **options)
    stages["build"] = time.process_time() - t
    t = time.process_time()
    base = make_baselines(problem, length=case.bridge.length, support_positions=case.bridge.support_positions,
                          n_random=100, rng=0)
    stages["baselines"] = time.process_time() - t
    t = time.process_time()
    g_start, _ = greedy(problem)
    stages["greedy"] = time.process_time() - t
    t = time.process_time()
    rel = solve_relaxation(problem, "auto", start_layout=g_start)
    stages["relaxation"] = time.process_time() - t
    t = time.process_time()
    method, layout, utility = best_layout(problem, rel.weights, base, greedy_layout=g_start, rng=0)
    stages["best"] = time.process_time() - t
    t = time.process_time()
    curve = criterion_curve(problem, spec["r"], None, rel.weights, layout, greedy_layout=g_start)
    stages["curve"] = time.process_time() - t
    crit = problem.criterion
    sign = 1.0 if crit.maximise else -1.0
    estimate = estimate_resources(problem.n_candidates, problem.n_params, spec["r"], n_loads=case.sweep.n_loads,
                                  n_kinds=len(kinds))
    return {"stages": stages, "total": sum(stages.values()), "gap": rel.relative_gap,
            "efficiency": crit.efficiency(sign * utility, sign * rel.bound), "method": method,
            "curve_counts": [p.count for p in curve if not p.failed],
            "stats": {k: v for k, v in rel.stats.items() if isinstance(v, (int, float, str))},
            "peak_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 2**30,
            "estimate_gib": estimate.memory_bytes / 2**30, "estimate_s": estimate.cpu_seconds,
            "n_candidates": problem.n_candidates}


def child_main():
    spec = json.loads(sys.argv[2])
    print(json.dumps(run_child(spec)))


# ---------------------------------------------------------------------- the parent --

def run(spec):
    """The child's result dict, or {'error': ...}."""
    cmd = [sys.executable, __file__, CHILD_FLAG, json.dumps(spec)]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {TIMEOUT_S:.0f} s"}
    if out.returncode != 0:
        return {"error": (out.stderr.strip().splitlines() or ["exit %d" % out.returncode])[-1]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def row(label, res):
    if "error" in res:
        return f"{label:<28s} {res['error']}"
    s = res["stages"]
    return (f"{label:<28s} {s['build']:7.1f} {s['baselines']:7.1f} {s['greedy']:7.1f} {s['relaxation']:7.1f} "
            f"{s['best']:7.1f} {s['curve']:7.1f} {res['total']:8.1f} {res['gap']:9.1e} {res['efficiency']:6.3f} "
            f"{res['peak_gib']:6.2f} {res['estimate_gib']:6.2f} {res['estimate_s']:7.0f}")


HEADER = (f"{'configuration':<28s} {'build':>7s} {'base':>7s} {'greedy':>7s} {'relax':>7s} {'best':>7s} "
          f"{'curve':>7s} {'total':>8s} {'gap':>9s} {'eff':>6s} {'peak':>6s} {'est':>6s} {'est_s':>7s}")


def fit_exponent(xs, ts):
    """Least-squares slope of log t against log x (None with fewer than two points)."""
    pts = [(math.log(x), math.log(t)) for x, t in zip(xs, ts) if t is not None and t > 0]
    if len(pts) < 2:
        return None
    a = np.array(pts)
    return float(np.polyfit(a[:, 0], a[:, 1], 1)[0])


def main(quick=False, parts=("target", "growth")):
    print(f"load average at start: {os.getloadavg()}; threads: "
          + ", ".join(f"{k}={os.environ[k]}" for k in THREAD_VARS))
    c_target = 800 if quick else 3000
    print("CPU seconds per stage (one core); gap: certified relative gap of the relaxation; eff: certified "
          "efficiency of the layout; peak / est: measured peak RSS / up-front estimate [GiB]; est_s: estimated CPU s")
    print(HEADER)
    results = {}
    if "target" in parts:
        target_part(results, c_target)
    if "growth" in parts:
        growth_part(results, c_target, quick)
    print(f"load average at end: {os.getloadavg()}")


def target_part(results, c_target):
    """D, A, E and the mixed design at N = 400, C = ``c_target``, R = 20, against the targets."""
    for crit in ("D", "A", "E"):
        res = results[crit] = run({"n": 400, "c": c_target, "r": 20, "crit": crit})
        print(row(f"{crit} N=400 C={c_target} R=20", res), flush=True)
    res = results["mixed"] = run({"n": 400, "c": c_target, "r": 20, "crit": "D", "mixed": True})
    print(row(f"mixed D N=400 C={c_target} R=20", res), flush=True)
    for crit in ("D", "A", "E"):
        res = results[crit]
        if "error" not in res:
            print(f"  {crit}: total {res['total']:.1f} s (< {TIME_TARGET_S:g}: {res['total'] < TIME_TARGET_S}), gap "
                  f"{res['gap']:.1e} (<= {GAP_TARGET:g}: {res['gap'] <= GAP_TARGET}), peak {res['peak_gib']:.2f} GiB "
                  f"(<= {MEMORY_TARGET_GIB:g}: {res['peak_gib'] <= MEMORY_TARGET_GIB}), curve up to R = "
                  f"{max(res['curve_counts'], default=0)}")
    if "error" not in results["mixed"]:
        print(f"  mixed: total {results['mixed']['total']:.1f} s (< {MIXED_TARGET_S:g}: "
              f"{results['mixed']['total'] < MIXED_TARGET_S})")


def growth_part(results, c_target, quick):
    """D against C at N = 400 and against N at C = 800, with the fitted exponents."""
    # run alone (--part=growth), the largest C is left to the target part (its D row)
    growth_c = [c for c in GROWTH_C if c < c_target or c == c_target and "D" in results]
    growth_n = [n for n in GROWTH_N if not quick or n <= 240]
    times_c = []
    for c in growth_c:
        res = results["D"] if c == c_target and "D" in results else run({"n": 400, "c": c, "r": 20, "crit": "D"})
        print(row(f"D N=400 C={c} R=20", res), flush=True)
        times_c.append(None if "error" in res else res["total"])
    times_n = []
    for n in growth_n:
        res = run({"n": n, "c": 800, "r": 20, "crit": "D"})
        print(row(f"D N={n} C=800 R=20", res), flush=True)
        times_n.append(None if "error" in res else res["total"])
    print(f"fitted exponents: time ~ C^{fit_exponent(growth_c, times_c)} (N = 400, C = {growth_c}), "
          f"time ~ N^{fit_exponent(growth_n, times_n)} (C = 800, N = {growth_n})")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == CHILD_FLAG:
        child_main()
    else:
        chosen = tuple(a[len("--part="):] for a in sys.argv[1:] if a.startswith("--part=")) or ("target", "growth")
        main(quick="--quick" in sys.argv, parts=chosen)
