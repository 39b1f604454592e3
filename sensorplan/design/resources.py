"""Memory and CPU time a placement problem needs, estimated before anything is allocated.

The candidate count has no fixed cap: a design is refused only when its
estimated peak memory exceeds what the machine can give
(:attr:`ResourcePolicy.memory_fraction` of its physical memory) or its
estimated CPU time exceeds :attr:`ResourcePolicy.max_cpu_seconds`; the
message states both estimates and the candidate count (grid spacing) that
would fit.

The model counts what dominates at scale (dense linear algebra, one core):

* Fisher criteria (D, Ds, A, E): the candidates' information blocks are
  structured (:mod:`sensorplan.design.blocks`): per sensor kind the products
  of A fixed matrices, 8 (A P)^2 bytes, plus about 8 (A + 2) C P bytes per
  candidate set (coefficients, cross terms, the build's temporaries),
  never the 8 C P^2 bytes of dense blocks, but a cache of dense blocks of
  the candidates greedy and exchange evaluate (at most
  :data:`~sensorplan.design.blocks.DENSE_CACHE_BYTES`); plus the relaxation's working
  set of m candidates (its structured blocks, low-rank roots, the
  preconditioner and a Newton step's temporaries, about 8 m P^2 bytes at the
  peak);
  CPU: building the blocks (2 n_loads (A P)^2 + 2 n_loads A P C flops),
  the relaxation's Newton steps (~ 12 x 2 m P^3 / 3), the bound passes of
  greedy and exchange (~ 3 R passes of 2 A^2 P^2 k + 2 C A^2 k^2, k = 16)
  and their exact evaluations (~ 50 R Cholesky factorisations of P^3 / 3
  and dense blocks of 2 A^2 P^2);
* the detect criterion: :attr:`ResourcePolicy.detection_bytes_per_candidate`
  per candidate whatever N is (its Gram stacks), no Fisher blocks.

The constants are checked against the five-span benchmark
(studies/benchmarks/bench_network.py: N = 400, C = 200 to 3,000, R = 20);
the estimate is meant to be right within a factor of about two, erring high,
where the limits matter (N = 400: 1.2-2x high in CPU, 2-3x high in memory);
on dense blocks (N <= 120) it can be up to 3x low, where a design takes
seconds and far less than the limits.

Owns: ResourceEstimate, estimate_resources, check_resources.  May import: errors.
"""

import math
import os
from dataclasses import dataclass

from .._errors import ConfigError

__all__ = ["ResourcePolicy", "RESOURCES", "ResourceEstimate", "estimate_resources", "check_resources",
           "largest_fitting", "spacing_for", "physical_memory"]


@dataclass(frozen=True)
class ResourcePolicy:
    """The constants of the estimate and the limits, each with its reason."""

    flop_rate: float = 7.5e9  # effective flops per CPU second on one core (fits the benchmark within 20 %)
    base_bytes: float = 3e8  # interpreter, numpy, the case and the forward model's chunk
    working_set_factor: float = 3.0  # working set ~ this x the first one (smooth.py), at most C
    eigen_split: int = 16  # directions of the eigen-split of the upper bounds (criteria.linalg.eigen_split)
    newton_steps: int = 12  # Newton steps' worth of 2 m P^3 / 3 flops in the relaxation (structured products)
    bound_passes_per_sensor: int = 3  # bound passes of greedy and exchange per sensor
    evaluations_per_sensor: int = 50  # exact evaluations (Cholesky factorisations) per sensor
    dense_cache_bytes: float = 2**30  # dense blocks kept by the structured blocks (blocks.DENSE_CACHE_BYTES)
    fixed_matrices: int = 10  # A: the structured blocks' fixed matrices (support reactions + 2; a 7-support bridge)
    detection_bytes_per_candidate: float = 4 * 2**20  # the detect problem's Gram stacks (issue 38: ~4 MB)
    memory_fraction: float = 0.75  # of the physical memory: the rest for the system and other processes
    max_cpu_seconds: float = 6 * 3600.0  # beyond, a design is a batch job: say so instead of starting it


RESOURCES = ResourcePolicy()


def physical_memory():
    """Physical memory of the machine [bytes] (8 GiB when the system does not say)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 8.0 * 2**30


@dataclass(frozen=True)
class ResourceEstimate:
    """Estimated peak memory [bytes] and CPU time [s] of a placement problem."""

    n_candidates: int
    n_params: int
    count: int
    memory_bytes: float
    cpu_seconds: float

    def summary(self):
        """'about 3.1 GiB and 4.2 min of CPU' (what the refusal message quotes)."""
        return f"about {self.memory_bytes / 2**30:.2g} GiB and {_duration(self.cpu_seconds)} of CPU"

    def to_dict(self):
        return {"n_candidates": self.n_candidates, "n_params": self.n_params, "count": self.count,
                "memory_bytes": self.memory_bytes, "cpu_seconds": self.cpu_seconds}


def _duration(seconds):
    if seconds < 120:
        return f"{seconds:.2g} s"
    if seconds < 7200:
        return f"{seconds / 60:.2g} min"
    return f"{seconds / 3600:.2g} h"


def estimate_resources(n_candidates, n_params, count, *, n_loads, detection=False, n_kinds=1, policy=RESOURCES):
    """:class:`ResourceEstimate` of a placement problem with ``n_candidates`` candidates, ``n_params``
    parameters, ``count`` new sensors, ``n_loads`` load positions per crossing and ``n_kinds`` sensor kinds."""
    c, p, r = float(n_candidates), float(n_params), float(max(1, count))
    if detection:
        memory = policy.base_bytes + c * policy.detection_bytes_per_candidate
        flops = c * 2.0 * n_loads * p * p + policy.bound_passes_per_sensor * r * c * 1e6
        return ResourceEstimate(int(n_candidates), int(n_params), int(count), memory, flops / policy.flop_rate)
    k = min(p, policy.eigen_split)
    m = min(c, policy.working_set_factor * max(4 * r + 20, min(c / 8, 8 * r + 40)))
    a = float(policy.fixed_matrices)
    cache = min(float(policy.dense_cache_bytes), 8 * c * p * p)
    memory = policy.base_bytes + 8 * n_kinds * (a * p) ** 2 + 8 * (a + 2) * c * p + 8 * m * p * p + cache
    flops = (n_kinds * 2 * n_loads * (a * p) ** 2 + 2 * n_loads * a * p * c + policy.newton_steps * 2 * m * p**3 / 3
             + policy.bound_passes_per_sensor * r * 2 * (a * a * p * p * k + c * a * a * k * k)
             + policy.evaluations_per_sensor * r * (p**3 / 3 + 2 * a * a * p * p))
    return ResourceEstimate(int(n_candidates), int(n_params), int(count), memory, flops / policy.flop_rate)


def check_resources(estimate, *, what, fits=None, policy=RESOURCES, memory=None):
    """Raise ConfigError when ``estimate`` exceeds the memory or CPU limit.

    ``what`` names the cause (e.g. "--spacing 0.06 m gives 3001 candidates"); ``fits`` is the advice that
    would fit (e.g. "use --spacing >= 0.09"), computed by the caller from :func:`largest_fitting`.
    """
    limit = policy.memory_fraction * (physical_memory() if memory is None else memory)
    over = []
    if estimate.memory_bytes > limit:
        over.append(f"more than the {limit / 2**30:.2g} GiB this machine can give")
    if estimate.cpu_seconds > policy.max_cpu_seconds:
        over.append(f"more than {_duration(policy.max_cpu_seconds)} of CPU")
    if over:
        raise ConfigError(f"{what}, which needs {estimate.summary()} ({estimate.n_params} parameters, "
                          f"{estimate.count} sensors): {' and '.join(over)}" + (f"; {fits}." if fits else "."))


def largest_fitting(estimate_for, *, policy=RESOURCES, memory=None, upper=10**7):
    """The largest candidate count C (>= 1) with ``estimate_for(C)`` within both limits (0 if none)."""
    limit = policy.memory_fraction * (physical_memory() if memory is None else memory)

    def ok(c):
        e = estimate_for(c)
        return e.memory_bytes <= limit and e.cpu_seconds <= policy.max_cpu_seconds

    if not ok(1):
        return 0
    lo, hi = 1, upper
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo if not ok(hi) else hi


def spacing_for(length, n_candidates, n_kinds=1):
    """The smallest grid spacing [m] (3 significant digits, rounded up) that gives at most ``n_candidates``
    candidates of ``n_kinds`` kinds on a bridge of ``length`` m."""
    per_kind = max(1, n_candidates // max(1, n_kinds))
    if per_kind <= 1:
        return length
    raw = length / (per_kind - 1)
    digits = 3 - int(math.floor(math.log10(raw))) - 1
    return math.ceil(raw * 10**digits) / 10**digits
