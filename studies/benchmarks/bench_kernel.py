"""Benchmark of the exact influence-line kernel of sensorplan.

What it measures
----------------
Wall time (best of a few repeats, ``time.perf_counter``) of

    lines = sensorplan.influence_lines(bridge, mesh, ei, sensors, vehicle, positions)
    jac = lines.jacobian("log_ei", springs=True)

for 50 rotation sensors x 1000 load positions x 200 elements on a three-span
bridge (12 + 16 + 12 m) with rotational springs at the two end supports,
vertical springs at the two piers and a 3-axle vehicle.  The target is
"under 1 s on a 2-core machine"; the script says whether it was met here.

The kernel speed is reported as ratios against two references (never as
absolute assertions):

1. The independent Hermite finite-element solve of ``tests/fe_reference.py``
   (``fe_response``), timed on a random subset of load positions (all 50
   sensors in one call per load position) and extrapolated per load position
   to 1000 positions.  It gives predictions only, no Jacobian, which favours it.
   The maximum difference between kernel and FE predictions on the subset is
   printed as well (it should be ~1e-12 of the largest reading).
2. Dense Gauss-Legendre quadrature (8 points per element, no splitting at the
   kinks of the moment diagrams, so it is inexact) of the element integrals
   A[r, k, j] = int_element_j m_r(s) M(s; z_k) ds, with the closed-form moment
   diagrams of a simply supported span written out in this script:
       m_r(s)   = -s/L + H(s - r)                                (unit couple at r)
       M(s; z)  = P [ (L - z)/L s H(z - s) + z (1 - s/L) H(s - z) ]  (load P at z)
   It only exists for a single simply supported span, so this comparison uses
   a single 40 m span with the same element count (200) and element size
   (0.2 m), the same sensors, vehicle and load positions; the kernel is timed
   on that same single-span bridge for the ratio.  The quadrature errors
   against the kernel (and both against the FE reference) show that the
   kernel is exact while the quadrature is not.

Relative errors are normalised by the largest magnitude of the reference
quantity: max|a - b| / max|b| (point-wise ratios are meaningless near the
zeros of an influence line).

How to run
----------
From the repository root (the folder holding ``sensorplan/`` and ``tests/``)::

    python studies/benchmarks/bench_kernel.py

It is deterministic (numpy Generator, fixed seed) and takes well under two
minutes.
"""

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import sensorplan as sp  # noqa: E402
from fe_reference import fe_response  # noqa: E402

SEED = 20240607
N_SENSORS = 50
N_LOADS = 1000
N_ELEMENTS = 200
SPANS = (12.0, 16.0, 12.0)
ROT_SPRINGS = (5.0e8, 0.0, 0.0, 5.0e8)  # N m/rad: elastic restraint at the two ends
VERT_SPRINGS = (math.inf, 2.0e9, 2.0e9, math.inf)  # N/m: elastomeric bearings at the piers
AXLE_OFFSETS = (0.0, 3.5, 4.9)  # m
AXLE_LOADS = (60.0e3, 50.0e3, 50.0e3)  # N
EI_MEAN = 1.5e10  # N m^2
KERNEL_REPEATS = 5
N_FE_SUBSET = 20
N_QUAD_SUBSET = 100
QUAD_POINTS = 8
TARGET_S = 1.0


def best_time(func, repeats):
    """Best wall time [s] of ``repeats`` calls, and the last result."""
    best = math.inf
    result = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = func()
        best = min(best, time.perf_counter() - t0)
    return best, result


def run_kernel(bridge, mesh, ei, sensors, vehicle, positions):
    lines = sp.influence_lines(bridge, mesh, ei, sensors, vehicle, positions)
    jac = lines.jacobian("log_ei", springs=True)
    return lines, jac


def fe_predictions(bridge, mesh, ei, sensors, vehicle, positions):
    """FE readings, one ``fe_response`` call (all sensors) per load position."""
    length = bridge.length
    sensor_list = list(zip(sensors.positions.tolist(), sensors.kinds))
    out = np.empty((sensors.n_sensors, len(positions)))
    for k, z in enumerate(positions):
        axles = z - np.asarray(vehicle.axle_offsets)
        loads = [(float(x), float(p)) for x, p in zip(axles, vehicle.axle_loads)
                 if 0.0 <= x <= length]
        out[:, k] = fe_response(list(bridge.spans), mesh.edges, ei,
                                list(bridge.rotational_springs), list(bridge.vertical_springs),
                                loads, sensor_list)
    return out


def quadrature_kernel(length, edges, sensor_x, axle_offsets, axle_loads, positions, n_points):
    """A[r, k, j] by fixed Gauss-Legendre quadrature on a simply supported span.

    Closed-form diagrams (sagging positive), no splitting at kinks or jumps.
    """
    xi, wq = np.polynomial.legendre.leggauss(n_points)
    a, b = edges[:-1], edges[1:]
    half = 0.5 * (b - a)
    s = (0.5 * (a + b))[:, None] + half[:, None] * xi[None, :]  # (J, Q)
    w = half[:, None] * wq[None, :]  # (J, Q)
    # Sensor diagrams m_r(s) = -s/L + H(s - r), weighted: (J, R, Q)
    r = sensor_x[None, :, None]
    m = (-s[:, None, :] / length + (s[:, None, :] >= r)) * w[:, None, :]
    # Vehicle diagrams M(s; z_k) = sum_a P_a [...], axles off the span carry nothing: (J, Q, K)
    big_m = np.zeros((s.shape[0], n_points, positions.size))
    ss = s[:, :, None]
    for off, p in zip(axle_offsets, axle_loads):
        z = (positions - off)[None, None, :]
        on = (z >= 0.0) & (z <= length)
        left = (length - z) / length * ss
        right = z * (1.0 - ss / length)
        big_m += np.where(on, p * np.where(ss < z, left, right), 0.0)
    return np.matmul(m, big_m).transpose(1, 2, 0)  # (R, K, J)


def rel(a, b):
    """max|a - b| / max|b|."""
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def main():
    rng = np.random.default_rng(SEED)
    wall0 = time.perf_counter()

    bridge = sp.Bridge(SPANS, rotational_springs=ROT_SPRINGS, vertical_springs=VERT_SPRINGS)
    mesh = sp.Mesh.uniform(bridge, N_ELEMENTS)
    length = bridge.length
    ei = EI_MEAN * np.exp(0.15 * rng.standard_normal(mesh.n_elements))
    sensors = sp.SensorLayout(np.sort(rng.uniform(0.1, length - 0.1, N_SENSORS)))
    vehicle = sp.Vehicle(AXLE_OFFSETS, AXLE_LOADS)
    positions = np.linspace(0.0, length + vehicle.length, N_LOADS)

    # --- Exact kernel, three-span bridge -------------------------------------------------
    run_kernel(bridge, mesh, ei, sensors, vehicle, positions)  # warm-up
    t_kernel, (lines, jac) = best_time(
        lambda: run_kernel(bridge, mesh, ei, sensors, vehicle, positions), KERNEL_REPEATS)

    # --- Reference 1: Hermite FE on a random subset --------------------------------------
    fe_idx = np.sort(rng.choice(N_LOADS, N_FE_SUBSET, replace=False))
    t_fe_sub, y_fe = best_time(
        lambda: fe_predictions(bridge, mesh, ei, sensors, vehicle, positions[fe_idx]), 2)
    t_fe = t_fe_sub / N_FE_SUBSET * N_LOADS
    err_fe = rel(lines.predictions[:, fe_idx], y_fe)

    # --- Reference 2: dense quadrature on a single simply supported span ------------------
    single = sp.Bridge((length,))
    mesh1 = sp.Mesh.uniform(single, N_ELEMENTS)
    run_kernel(single, mesh1, ei, sensors, vehicle, positions)  # warm-up
    t_kernel1, (lines1, _) = best_time(
        lambda: run_kernel(single, mesh1, ei, sensors, vehicle, positions), KERNEL_REPEATS)
    q_idx = np.sort(rng.choice(N_LOADS, N_QUAD_SUBSET, replace=False))

    def quad():
        a_q = quadrature_kernel(length, mesh1.edges, sensors.positions, vehicle.axle_offsets,
                                vehicle.axle_loads, positions[q_idx], QUAD_POINTS)
        return a_q, a_q @ (1.0 / ei)

    t_quad_sub, (a_quad, y_quad) = best_time(quad, 3)
    t_quad = t_quad_sub / N_QUAD_SUBSET * N_LOADS
    a_kern1 = lines1.kernel[:, q_idx, :]
    y_kern1 = lines1.predictions[:, q_idx]
    err_quad_a = rel(a_quad, a_kern1)
    err_quad_y = rel(y_quad, y_kern1)
    fe1_idx = q_idx[:N_FE_SUBSET]
    y_fe1 = fe_predictions(single, mesh1, ei, sensors, vehicle, positions[fe1_idx])
    err_kern1_fe = rel(lines1.predictions[:, fe1_idx], y_fe1)
    err_quad_fe = rel(y_quad[:, :N_FE_SUBSET], y_fe1)

    # --- Report ---------------------------------------------------------------------------
    cores = os.cpu_count()
    met = t_kernel < TARGET_S
    n_par = jac.shape[2]
    line = "-" * 86
    print("sensorplan exact influence-line kernel benchmark")
    print(f"numpy {np.__version__}, {cores} logical CPU(s), seed {SEED}")
    print(line)
    print(f"Case A (timed): three-span {'+'.join(f'{x:g}' for x in SPANS)} m, "
          f"{N_ELEMENTS} elements, {N_SENSORS} rotation sensors, {N_LOADS} load positions,")
    print(f"  3-axle vehicle, rotational springs {ROT_SPRINGS[0]:.1e} N m/rad at the ends, "
          f"vertical springs {VERT_SPRINGS[1]:.1e} N/m at the piers;")
    print(f"  Jacobian d/dlog EI + d/dlog k: shape {jac.shape} ({n_par - N_ELEMENTS} springs)")
    print(f"Case B (quadrature comparison): single simply supported span of {length:g} m, same "
          f"{N_ELEMENTS} elements")
    print(f"  of {mesh1.lengths[0]:g} m, same sensors, vehicle and load positions "
          "(the closed-form quadrature diagrams exist only for one simple span).")
    print(line)
    hdr = f"{'method':<44}{'case':>5}{'subset':>8}{'time [s]':>11}{'@1000 [s]':>10}{'kernel x':>9}"
    print(hdr)
    print(line)
    print(f"{'exact kernel + Jacobian (best of %d)' % KERNEL_REPEATS:<44}{'A':>5}"
          f"{N_LOADS:>8}{t_kernel:>11.3f}{t_kernel:>10.3f}{1.0:>9.1f}")
    print(f"{'Hermite FE, predictions only (best of 2)':<44}{'A':>5}{N_FE_SUBSET:>8}"
          f"{t_fe_sub:>11.3f}{t_fe:>10.2f}{t_fe / t_kernel:>9.1f}")
    print(f"{'exact kernel + Jacobian (best of %d)' % KERNEL_REPEATS:<44}{'B':>5}"
          f"{N_LOADS:>8}{t_kernel1:>11.3f}{t_kernel1:>10.3f}{1.0:>9.1f}")
    print(f"{'Gauss-Legendre %d pt/element, A + y (best of 3)' % QUAD_POINTS:<44}{'B':>5}"
          f"{N_QUAD_SUBSET:>8}{t_quad_sub:>11.3f}{t_quad:>10.2f}{t_quad / t_kernel1:>9.1f}")
    print(line)
    print("'@1000' extrapolates the subset time linearly per load position; 'kernel x' is that")
    print("time divided by the kernel time of the same case (>1: the kernel is faster).")
    print("The FE reference returns predictions only (no Jacobian), which favours it.")
    print(line)
    print("Accuracy, max|a - b| / max|b|:")
    print(f"  A: kernel vs FE predictions ({N_FE_SUBSET} positions)         {err_fe:10.2e}")
    print(f"  B: kernel vs FE predictions ({N_FE_SUBSET} positions)         {err_kern1_fe:10.2e}")
    print(f"  B: quadrature vs FE predictions ({N_FE_SUBSET} positions)     {err_quad_fe:10.2e}")
    print(f"  B: quadrature vs kernel, predictions ({N_QUAD_SUBSET} positions) {err_quad_y:10.2e}")
    print(f"  B: quadrature vs kernel, element integrals A         {err_quad_a:10.2e}")
    print(line)
    verdict = "MET" if met else "NOT MET"
    print(f"Target: kernel + Jacobian for case A under {TARGET_S:g} s on a 2-core machine.")
    print(f"Result: {t_kernel:.3f} s on this machine ({cores} logical CPU(s)) -> target {verdict}"
          + ("" if cores == 2 else " (note: this machine does not have exactly 2 cores)") + ".")
    print(f"Total benchmark run time: {time.perf_counter() - wall0:.1f} s")


if __name__ == "__main__":
    main()
