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

The damage signatures are formed a group of centres at a time (and the
nuisance Jacobian a group of sensors at a time, in SignatureModel), so that
no readings x sensors x centres (or x elements) array is ever held whole:
the memory is the packed blocks (``n_centres (1 + n) + n^2`` numbers per
candidate), the whitened nuisance Jacobian (loads x n per candidate) and
one group's arrays of at most :data:`GROUP_BYTES` (:func:`detection_memory`).

Owns: DetectionTarget, the detection blocks of a placement problem and their memory estimate.
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

__all__ = ["DetectionTarget", "detection_information", "centres_inside", "detection_memory", "GROUP_BYTES", "MEMORY_LIMIT"]

GROUP_BYTES = 2**27  # bytes of one group's signatures or influence-line kernel (128 MiB)
MEMORY_LIMIT = 4 * 2**30  # bytes a detect problem may take (issue 38: <= 4 GiB at 3,000 candidates)


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


def detection_memory(case, n_candidates, *, length=2.0, step=0.5, nuisance="smooth"):
    """Bytes the detect criterion needs for ``n_candidates`` on ``case`` (whatever its mesh): the packed
    blocks and their copies while they are assembled, the candidates' influence lines and nuisance Jacobian
    (raw and whitened), and a few groups of GROUP_BYTES.  Compare with :data:`MEMORY_LIMIT`."""
    n_centres = len(centre_grid(case.bridge.length, length, step))
    per_span = 1 if nuisance == "levels" else 3
    n_nuisance = per_span * case.bridge.n_spans + len(case.bridge.spring_names)
    n_loads = case.sweep.positions.size
    per_candidate = 3 * PackedLayout(n_centres, n_nuisance).size + n_loads * (2 * n_nuisance + 1)
    return 8 * n_candidates * per_candidate + 4 * GROUP_BYTES


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
