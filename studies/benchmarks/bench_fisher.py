"""Benchmark of the per-sensor Fisher information blocks of sensorplan.

What it measures
----------------
Wall time (best of a few repeats, ``time.perf_counter``) and peak memory
(``tracemalloc``, which tracks numpy's allocations) of

    fb = sensorplan.model.fisher.fisher_blocks(case, sensors=candidates, noise=noise,
                                          parameterisation="log_ei", n_crossings=1)

for 400 candidate rotation-sensor positions x 100 elements x 500 load
positions on a two-span bridge (15 + 15 m) with rotational springs at the two
end supports, a two-axle vehicle, EI varying per element and AR(1) noise
(``NoiseModel(std, correlation_length=0.5)``, std varying per sensor), so the
bidiagonal whitening of the noise model is exercised (lag-one correlation
rho = exp(-step / 0.5) ~ 0.87 for the 0.068 m load step).

The reference is the straightforward dense computation, in the same run: for
each sensor i build the K x K correlation matrix Gamma[a, b] =
exp(-|x_a - x_b| / l) of the K = 500 load positions, invert it with
``np.linalg.inv`` and form J_i^T Gamma^{-1} J_i / sigma_i^2 from the
Jacobians J_i = ``case.influence_lines(sensors=...).jacobian("log_ei")``.
It is timed on a random subset of 20 sensors and extrapolated linearly
(x 400 / 20).  Timings are reported as ratios dense / fast of this run, never
as absolute assertions:

* end to end: ``fisher_blocks`` (forward model + whitening + products) against
  the same forward model (``influence_lines`` + ``jacobian`` in the same
  chunks of 64 sensors, timed separately for all 400) plus the extrapolated
  dense assembly;
* assembly only, on the identical precomputed 20-sensor Jacobians: the
  bidiagonal whitening + J^T J that ``fisher_blocks`` performs
  (``NoiseModel.whiten`` then ``np.matmul``) against the dense per-sensor
  loop, and against a less naive dense variant that inverts Gamma once and
  shares it (all sensors see the same load positions and correlation length).

Accuracy: the fast blocks of the subset are compared with the dense blocks,
max|fast - dense| / max|dense| per sensor (max over the subset), and the
point-wise relative difference of the block diagonals (the informativeness
curves, positive, so point-wise ratios are meaningful).

Memory: the peak of ``fisher_blocks`` for all 400 sensors with its default
``chunk_size`` (64), which includes the result array itself (its size is
printed), and, for context, the same call with ``chunk_size=16`` (also
timed); then the peak of the two assembly-only variants on the 20-sensor
subset with the Jacobians already in memory (not counted).  Memory is measured in separate,
untimed calls, because tracing slows allocation.

How to run
----------
From the repository root (the folder holding ``sensorplan/``)::

    python studies/benchmarks/bench_fisher.py

It is deterministic (numpy Generator, fixed seed) and takes well under a
minute on a 2-core machine.
"""

import inspect
import os
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import sensorplan as sp  # noqa: E402
from sensorplan.model.case import Case  # noqa: E402
from sensorplan.model.fisher import fisher_blocks  # noqa: E402
from sensorplan.model.noise import NoiseModel  # noqa: E402

SEED = 20240611
N_SENSORS = 400
N_ELEMENTS = 100
N_LOADS = 500
SPANS = (15.0, 15.0)
ROT_SPRINGS = (1.0e9, 0.0, 1.0e9)  # N m/rad: elastic restraint at the two ends
AXLE_OFFSETS = (0.0, 4.0)  # m
AXLE_LOADS = (80.0e3, 60.0e3)  # N
EI_MEAN = 1.5e10  # N m^2
NOISE_STD = 1.0e-6  # rad, nominal
CORRELATION_LENGTH = 0.5  # m
PARAMETERISATION = "log_ei"
N_SUBSET = 20
CHUNK = 64  # fisher_blocks' default chunk_size (checked below)
SMALL_CHUNK = 16
FAST_REPEATS = 5
DENSE_REPEATS = 3
ASSEMBLY_REPEATS = 20
MB = 1.0e6


def timed(func, repeats):
    """Best wall time [s] of ``repeats`` calls, and the last result."""
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = func()
        times.append(time.perf_counter() - t0)
    return float(np.min(times)), result


def peak_memory(func):
    """Peak traced memory [bytes] during ``func()`` (allocations alive before are not counted)."""
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    result = func()
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    del result
    return peak


def dense_blocks(jac, std, positions, length):
    """Straightforward dense reference: per sensor, Gamma, np.linalg.inv, J^T Gamma^-1 J / s^2."""
    out = np.empty((jac.shape[0], jac.shape[2], jac.shape[2]))
    for i in range(jac.shape[0]):
        gamma = np.exp(-np.abs(positions[:, None] - positions[None, :]) / length)
        gamma_inv = np.linalg.inv(gamma)
        out[i] = jac[i].T @ gamma_inv @ jac[i] / std[i] ** 2
    return out


def dense_blocks_shared(jac, std, positions, length):
    """Dense reference with Gamma^-1 computed once and shared by all sensors."""
    gamma_inv = np.linalg.inv(np.exp(-np.abs(positions[:, None] - positions[None, :]) / length))
    out = np.empty((jac.shape[0], jac.shape[2], jac.shape[2]))
    for i in range(jac.shape[0]):
        out[i] = jac[i].T @ gamma_inv @ jac[i] / std[i] ** 2
    return out


def fast_assembly(jac, noise, positions):
    """What fisher_blocks does after the forward model: bidiagonal whitening, then J^T J."""
    white = noise.whiten(jac, positions)
    return np.matmul(white.transpose(0, 2, 1), white)


def forward_chunks(case, sensors, chunk):
    """The forward work of fisher_blocks alone: influence lines + Jacobian per chunk."""
    for start in range(0, sensors.n_sensors, chunk):
        index = np.arange(start, min(start + chunk, sensors.n_sensors))
        case.influence_lines(sensors=sensors.subset(index)).jacobian(PARAMETERISATION)


def main():
    rng = np.random.default_rng(SEED)
    wall0 = time.perf_counter()

    bridge = sp.Bridge(SPANS, rotational_springs=ROT_SPRINGS)
    mesh = sp.Mesh.uniform(bridge, N_ELEMENTS)
    ei = EI_MEAN * np.exp(0.15 * rng.standard_normal(mesh.n_elements))
    vehicle = sp.Vehicle(AXLE_OFFSETS, AXLE_LOADS)
    sweep = sp.LoadSweep(np.linspace(0.0, bridge.length + vehicle.length, N_LOADS))
    positions = sweep.positions
    # Candidates at the midpoints of 400 equal cells, each jittered within its middle 50 %.
    cell = bridge.length / N_SENSORS
    sensor_x = cell * (np.arange(N_SENSORS) + rng.uniform(0.25, 0.75, N_SENSORS))
    candidates = sp.SensorLayout.candidates(sensor_x, kind="rotation")
    std = NOISE_STD * rng.uniform(0.7, 1.3, N_SENSORS)
    noise = NoiseModel(std, correlation_length=CORRELATION_LENGTH)
    case = Case(bridge, mesh, ei, vehicle, candidates, noise, sweep)
    subset = np.sort(rng.choice(N_SENSORS, N_SUBSET, replace=False))
    rho = noise.rho(positions)
    default_chunk = inspect.signature(fisher_blocks).parameters["chunk_size"].default  # through the decorator

    def fast():
        return fisher_blocks(case, sensors=candidates, noise=noise,
                             parameterisation=PARAMETERISATION, n_crossings=1)

    # --- Fast path, end to end ---------------------------------------------------------------
    t0 = time.perf_counter()
    fast()
    t_cold = time.perf_counter() - t0
    times = []
    for _ in range(FAST_REPEATS):
        t0 = time.perf_counter()
        fb = fast()
        times.append(time.perf_counter() - t0)
    t_fast, t_fast_med = min(times), float(np.median(times))
    t_fast_small, _ = timed(
        lambda: fisher_blocks(case, sensors=candidates, noise=noise,
                              parameterisation=PARAMETERISATION, n_crossings=1,
                              chunk_size=SMALL_CHUNK), FAST_REPEATS)
    t_forward, _ = timed(lambda: forward_chunks(case, candidates, default_chunk), FAST_REPEATS)
    t_insitu = t_fast - t_forward

    # --- Dense reference on the subset ---------------------------------------------------------
    sub_sensors = candidates.subset(subset)
    sub_noise = noise.subset(subset)
    jac = case.influence_lines(sensors=sub_sensors).jacobian(PARAMETERISATION)
    t_dense_sub, dense = timed(
        lambda: dense_blocks(jac, sub_noise.std, positions, CORRELATION_LENGTH), DENSE_REPEATS)
    t_shared_sub, dense_shared = timed(
        lambda: dense_blocks_shared(jac, sub_noise.std, positions, CORRELATION_LENGTH),
        DENSE_REPEATS)
    t_fastasm_sub, fast_sub = timed(lambda: fast_assembly(jac, sub_noise, positions),
                                    ASSEMBLY_REPEATS)
    scale = N_SENSORS / N_SUBSET
    t_dense_asm = t_dense_sub * scale
    t_dense_total = t_forward + t_dense_asm

    # --- Accuracy ------------------------------------------------------------------------------
    blocks = fb.blocks[subset]

    def rel_block(a, b):
        return float(np.max(np.abs(a - b).max(axis=(1, 2)) / np.abs(b).max(axis=(1, 2))))

    idx = np.arange(N_ELEMENTS)
    err_block = rel_block(blocks, dense)
    err_diag = float(np.max(np.abs(blocks[:, idx, idx] / dense[:, idx, idx] - 1.0)))
    err_shared = rel_block(blocks, dense_shared)
    err_asm = rel_block(fast_sub, dense)

    # --- Memory (separate, untimed calls) ------------------------------------------------------
    result_bytes = fb.blocks.nbytes
    del fb
    mem_fast = peak_memory(fast)
    mem_fast_small = peak_memory(
        lambda: fisher_blocks(case, sensors=candidates, noise=noise,
                              parameterisation=PARAMETERISATION, n_crossings=1,
                              chunk_size=SMALL_CHUNK))
    mem_fastasm = peak_memory(lambda: fast_assembly(jac, sub_noise, positions))
    mem_dense = peak_memory(lambda: dense_blocks(jac, sub_noise.std, positions,
                                                 CORRELATION_LENGTH))
    mem_shared = peak_memory(lambda: dense_blocks_shared(jac, sub_noise.std, positions,
                                                         CORRELATION_LENGTH))
    chunk_jac = default_chunk * N_LOADS * N_ELEMENTS * 8

    # --- Report --------------------------------------------------------------------------------
    line = "-" * 92
    print("sensorplan Fisher-block benchmark (fisher_blocks vs dense Gamma^-1)")
    print(f"numpy {np.__version__}, {os.cpu_count()} logical CPU(s), seed {SEED}")
    print(line)
    print(f"two-span {'+'.join(f'{x:g}' for x in SPANS)} m, rotational springs "
          f"{ROT_SPRINGS[0]:.1e} N m/rad at the ends")
    print(f"{N_ELEMENTS} elements, EI per element {ei.min():.2e}..{ei.max():.2e} N m^2")
    print(f"{vehicle.n_axles}-axle vehicle (offsets {AXLE_OFFSETS} m, loads "
          f"{tuple(p / 1e3 for p in AXLE_LOADS)} kN); {N_LOADS} load positions, step "
          f"{positions[1] - positions[0]:.4f} m")
    print(f"{N_SENSORS} candidate rotation sensors, std {std.min():.2e}..{std.max():.2e} rad")
    print(f"AR(1) noise, correlation length {CORRELATION_LENGTH:g} m (rho = {rho[0]:.4f})")
    print(f"parameterisation {PARAMETERISATION}, 1 crossing; result {fb_shape(N_SENSORS)} "
          f"float64 = {result_bytes / MB:.1f} MB")
    print(f"fisher_blocks default chunk_size = {default_chunk}")
    print(line)
    w = 58
    print(f"{'time':<{w}}{'sensors':>8}{'t [s]':>9}{'@400 [s]':>9}{'dense/fast':>11}")
    print(line)
    print(f"{'fast: fisher_blocks, end to end (best of %d)' % FAST_REPEATS:<{w}}"
          f"{N_SENSORS:>8}{t_fast:>9.3f}{t_fast:>9.3f}{1.0:>11.2f}")
    print(f"{'  of which forward model (lines + Jacobian, chunks of %d)' % default_chunk:<{w}}"
          f"{N_SENSORS:>8}{t_forward:>9.3f}{t_forward:>9.3f}{'':>11}")
    print(f"{'fast: fisher_blocks, chunk_size=%d (best of %d)' % (SMALL_CHUNK, FAST_REPEATS):<{w}}"
          f"{N_SENSORS:>8}{t_fast_small:>9.3f}{t_fast_small:>9.3f}{'':>11}")
    print(f"{'dense: same forward + per-sensor Gamma, inv, J^T G^-1 J':<{w}}"
          f"{N_SUBSET:>8}{'':>9}{t_dense_total:>9.3f}{t_dense_total / t_fast:>11.2f}")
    print(f"{'assembly only, same precomputed Jacobians:':<{w}}")
    print(f"{'  fast: bidiagonal whitening + J^T J (best of %d)' % ASSEMBLY_REPEATS:<{w}}"
          f"{N_SUBSET:>8}{t_fastasm_sub:>9.4f}{t_fastasm_sub * scale:>9.3f}{1.0:>11.2f}")
    print(f"{'  fast in situ: fisher_blocks minus forward model [1]':<{w}}"
          f"{N_SENSORS:>8}{t_insitu:>9.3f}{t_insitu:>9.3f}"
          f"{t_dense_asm / t_insitu:>11.1f}")
    print(f"{'  dense: per sensor Gamma, np.linalg.inv, J^T G^-1 J':<{w}}"
          f"{N_SUBSET:>8}{t_dense_sub:>9.4f}{t_dense_asm:>9.3f}"
          f"{t_dense_sub / t_fastasm_sub:>11.1f}")
    print(f"{'  dense, Gamma^-1 computed once and shared':<{w}}"
          f"{N_SUBSET:>8}{t_shared_sub:>9.4f}{t_shared_sub * scale:>9.3f}"
          f"{t_shared_sub / t_fastasm_sub:>11.1f}")
    print(line)
    print(f"'@400' extrapolates a {N_SUBSET}-sensor time linearly (x {scale:g}); 'dense/fast' "
          "divides by the fast")
    print("time of the same group (end to end, or assembly only on the same 20 sensors); > 1")
    print("means the fast path is faster.  [1] whitening + products for 400 sensors in")
    print("chunks of 64 plus the final symmetrisation of the 32 MB result, by difference of")
    print("two best-of times (rough); its ratio is the extrapolated dense assembly divided by it.")
    print("Repeated runs vary by ~20-30 %.")
    print(f"fast path: first (cold) call {t_cold:.3f} s, median of {FAST_REPEATS} repeats "
          f"{t_fast_med:.3f} s.")
    print(line)
    print(f"{'peak memory (tracemalloc)':<{w}}{'sensors':>8}{'peak [MB]':>11}")
    print(line)
    print(f"{'fast: fisher_blocks, chunk_size=%d (default), incl. result' % default_chunk:<{w}}"
          f"{N_SENSORS:>8}{mem_fast / MB:>11.1f}")
    print(f"{'fast: fisher_blocks, chunk_size=%d, incl. result' % SMALL_CHUNK:<{w}}"
          f"{N_SENSORS:>8}{mem_fast_small / MB:>11.1f}")
    print(f"{'  result array alone':<{w}}{N_SENSORS:>8}{result_bytes / MB:>11.1f}")
    label = f"  one chunk of Jacobians ({default_chunk} x {N_LOADS} x {N_ELEMENTS} float64)"
    print(f"{label:<{w}}"
          f"{default_chunk:>8}{chunk_jac / MB:>11.1f}")
    print(f"{'assembly only, Jacobians already in memory (not counted):':<{w}}")
    print(f"{'  fast: whitening + J^T J (all %d at once)' % N_SUBSET:<{w}}"
          f"{N_SUBSET:>8}{mem_fastasm / MB:>11.1f}")
    print(f"{'  dense: per-sensor Gamma + inverse':<{w}}{N_SUBSET:>8}{mem_dense / MB:>11.1f}")
    print(f"{'  dense, Gamma^-1 shared':<{w}}{N_SUBSET:>8}{mem_shared / MB:>11.1f}")
    print(line)
    print("The fast path's memory is set by chunk_size (whitened copies of a chunk's Jacobians,")
    print(f"O(chunk x K x P)) plus the result; the dense loop holds O(K^2) per sensor (K = "
          f"{N_LOADS}),")
    print("and over 400 sensors it would also need the forward model's chunk memory and the")
    print("result.")
    print(line)
    print(f"accuracy on the {N_SUBSET}-sensor subset:")
    rows = [
        ("fisher_blocks vs dense, max|a-b|/max|b| per block", err_block),
        ("fisher_blocks vs dense, diagonal (curves), point-wise relative", err_diag),
        ("fisher_blocks vs dense with shared Gamma^-1, per block", err_shared),
        ("fast assembly on the subset Jacobians vs dense, per block", err_asm),
    ]
    for text, value in rows:
        print(f"  {text:<{w + 17}}{value:>10.2e}")
    print(line)
    print(f"Total benchmark run time: {time.perf_counter() - wall0:.1f} s")


def fb_shape(n_sensors):
    return f"({n_sensors}, {N_ELEMENTS}, {N_ELEMENTS})"


if __name__ == "__main__":
    main()
