"""What a candidate sensor adds to the detect criterion: its packed Gram information over the centres.

For the candidates and the existing (fixed) sensors at once, the whitened
exact damage signatures of a loss of ``severity`` over ``length`` centred at
every damage centre (from length/2 to L - length/2 every ``step``, restricted
to ``region``) and the whitened nuisance Jacobian come from
:class:`~sensorplan.detection.signatures.SignatureModel`, exactly as
``sensorplan detectability`` computes them; their Gram matrices, times the
number of crossings, packed with the centre-independent nuisance block
stored once (:mod:`.criteria.detect_algebra`), are the blocks of the
placement problem.

The damage signatures are formed one centre at a time from undamaged
diagrams computed once (:meth:`SignatureModel.damage_each`, no forward
solve per centre), and the nuisance Jacobian a group of sensors at a time,
so that no readings x sensors x centres (or x elements) array is ever held
whole: the memory is the packed blocks (``n_centres (1 + n) + n^2`` numbers
per candidate), the whitened nuisance Jacobian (loads x n per candidate)
and one group's kernel of at most :data:`GROUP_BYTES`; :func:`detection_resources`
estimates it, and the CPU time, before anything is built.

Owns: DetectionTarget, the detection blocks of a placement problem and their resource estimate.
May import: model, detection, errors, design.
"""

from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError
from ..detection.detectability import check_detection_options
from ..detection.signatures import SignatureModel, centre_grid
from ..model.fisher import fisher_blocks
from .criteria.detect import RIDGE, DetectCriterion
from .criteria.detect_algebra import PackedLayout
from .resources import RESOURCES, ResourceEstimate

__all__ = ["DetectionTarget", "detection_information", "centres_inside", "detection_resources", "GROUP_BYTES"]

GROUP_BYTES = 2**27  # bytes of one group of the influence-line kernel (SignatureModel's nuisance, 128 MiB)
NEWTON_STEPS = 1000  # Newton steps of the relaxation over all its rounds (five-span benchmark: 700-1,900)
BOUND_PASSES = 60  # passes of the upper bounds over all candidates and centres per sensor (greedy, exchange)
EFFECTIVE_RATE = 0.4  # of the policy's flop rate (fitted: five-span benchmark, N = 400, C = 3,000, R = 20)


@dataclass(frozen=True)
class DetectionTarget:
    """The local loss the detect criterion must see, and how its power is reported.

    Parameters
    ----------
    severity : float
        Fraction of EI lost over the zone, in (0, 1).
    length : float
        Length of the damaged zone [m].
    nuisance : {"smooth", "levels"}
        What must not be mistaken for damage (as in ``detectability``).
    step : float
        Spacing of the damage centres [m].
    false_alarm : float
        False-alarm rate of the one-sided test, for the reported power only.
    """

    severity: float = 0.25
    length: float = 2.0
    nuisance: str = "smooth"
    step: float = 0.5
    false_alarm: float = 0.05


def centres_inside(centres, region):
    """Mask of the damage ``centres`` [m] inside ``region`` (start, stop) [m], ends included (all when None)."""
    centres = np.asarray(centres, dtype=float)
    if region is None:
        return np.ones(centres.shape, dtype=bool)
    a, b = region
    return (centres >= a - 1e-9) & (centres <= b + 1e-9)


def _centres(case, target, region):
    centres = centre_grid(case.bridge.length, target.length, target.step)
    if region is None:
        return centres, None
    try:
        a, b = (float(v) for v in region)
    except (TypeError, ValueError):
        raise ConfigError(f"The 'region' parameter must be (start, stop) in m. Got {region!r} instead.") from None
    if not b > a:
        raise ConfigError(f"The 'region' parameter must be start:stop with stop > start. Got {a:g}:{b:g} instead.")
    inside = centres[centres_inside(centres, (a, b))]
    if inside.size == 0:
        raise ConfigError(f"The 'region' {a:g}:{b:g} m contains no damage centre (centres run from "
                          f"{centres[0]:g} to {centres[-1]:g} m every {target.step:g} m); widen it.")
    return inside, (a, b)


def _packed_group(model, centres, severity):
    """(rows (S, n_centres, 1 + n), nuisance blocks (S, n, n)) of the model's sensors, per crossing, one
    centre at a time (its signatures (S, K) are contiguous, so whitening and the products stream)."""
    nuis = model.nuisance  # (S, K, n), whitened
    s_count, _, n = nuis.shape
    rows = np.empty((s_count, centres.size, 1 + n))
    for c, signal in enumerate(model.damage_each(centres, severity)):  # (S, K)
        rows[:, c, 0] = np.einsum("sk,sk->s", signal, signal)
        rows[:, c, 1:] = np.matmul(signal[:, None, :], nuis)[:, 0]
    return rows, np.einsum("skm,skn->smn", nuis, nuis)


def detection_resources(case, n_candidates, count, *, length=2.0, step=0.5, nuisance="smooth", policy=RESOURCES):
    """:class:`~sensorplan.design.resources.ResourceEstimate` of a detect design with ``n_candidates`` on
    ``case`` and ``count`` new sensors.

    Memory (bytes): the packed blocks and their copies while they are assembled (3 x 8 P per candidate,
    P = n_centres (1 + n) + n^2), the whitened nuisance Jacobian and its raw copy (2 x 8 n_loads n), the
    undamaged diagrams on the zones' mesh and one centre's products (8 (2 E + 4 n_loads)), and the
    influence-line groups of the nuisance (4 x GROUP_BYTES).  CPU: the signatures' products (per centre
    and candidate, n_loads (n + 9) products; per element, n_loads (n + 2)), the relaxation's Newton
    steps (NEWTON_STEPS x n_active n m^2, m = its working set, n_active = 2/3 of the centres) and the
    bound passes of greedy and exchange (R x BOUND_PASSES x C n_centres (1 + n)), at the policy's flop
    rate scaled by EFFECTIVE_RATE (numpy's small products run below the rate of dense BLAS).
    """
    n_centres = len(centre_grid(case.bridge.length, length, step))
    per_span = 1 if nuisance == "levels" else 3
    n = per_span * case.bridge.n_spans + len(case.bridge.spring_names)
    n_loads, n_el = case.sweep.positions.size, case.n_elements
    c, r = float(n_candidates), float(max(1, count))
    zone_elements = n_el + 2 * n_centres
    per_candidate = 3 * PackedLayout(n_centres, n).size + 2 * n_loads * n + 2 * zone_elements + 4 * n_loads
    memory = policy.base_bytes + 8 * c * per_candidate + 4 * GROUP_BYTES
    m = min(c, 8 * r + 90)
    flops = (2 * c * n_loads * (n_centres * (n + 9) + n_el * (n + 2))
             + NEWTON_STEPS * (2 * n_centres / 3) * n * m * m + r * BOUND_PASSES * c * n_centres * (1 + n))
    return ResourceEstimate(int(n_candidates), n_centres, int(count), memory,
                            flops / (EFFECTIVE_RATE * policy.flop_rate))


def detection_information(case, cands, *, n_crossings, region, target, prior, springs, functionals):
    """(blocks, q0, criterion, posterior_of) of the detect criterion for the candidates ``cands``
    (a CandidateSet: positions, kinds and noise of each candidate, plus the existing sensors)."""
    target = DetectionTarget() if target is None else target
    if springs or functionals is not None:
        raise ConfigError("'springs' and 'functionals' apply to the information criteria, not to detect "
                          "(its nuisance always includes the elastic springs).")
    severity, length, false_alarm, n_crossings, step = check_detection_options(
        case, severity=target.severity, length=target.length, false_alarm=target.false_alarm,
        n_crossings=n_crossings, nuisance=target.nuisance, step=target.step)
    centres, region = _centres(case, target, region)
    sensors = cands.layout()
    model = SignatureModel(case, sensors, case.noise_for(sensors),
                           target.nuisance, length)
    rows, nn = _packed_group(model, centres, severity)
    rows *= n_crossings
    nn *= n_crossings
    names = model.nuisance_names
    # nuisance columns no sensor sees do not change d^2: drop them
    seen = np.einsum("snn->n", nn) > 0.0
    rows = rows[:, :, np.concatenate([[True], seen])]
    nn = nn[:, seen][:, :, seen]
    packing = PackedLayout(centres.size, int(seen.sum()))
    grams = packing.pack(rows, nn)
    n_cand = cands.n_candidates
    blocks, q0 = grams[:n_cand], grams[n_cand:].sum(axis=0)
    ridge = RIDGE * np.einsum("snn->sn", nn[:n_cand]).mean(axis=0)
    crit = DetectCriterion(centres.size, centres=centres, ridge=ridge, false_alarm=false_alarm,
                           n_crossings=n_crossings, severity=severity, length=length, nuisance=target.nuisance,
                           region=region, step=step, nuisance_names=[n for n, k in zip(names, seen) if k])
    n_el = case.n_elements

    def posterior_of(index):
        info = fisher_blocks(case, sensors=cands.layout(index), parameterisation="log_ei", n_crossings=n_crossings)
        return prior.precision(n_el, 0) + info.blocks.sum(axis=0)

    return blocks, q0, crit, posterior_of
