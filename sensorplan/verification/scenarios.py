"""Synthetic truths for verification: local losses, span softening, controls, truth meshes.

Owns: Scenario, make_scenarios, the finer and differently aligned truth mesh.
May import: model and the foundations.
"""

from dataclasses import dataclass

import numpy as np

from .._errors import ConfigError
from .._validation import MIN_ZONE_LENGTH
from ..model.structure import Mesh

__all__ = ["Scenario", "make_scenarios", "truth_mesh", "element_average_ei"]


@dataclass(frozen=True)
class Scenario:
    """A synthetic truth: ``kind`` is "local", "span" or "control"."""

    kind: str
    start: float = 0.0  # damaged zone [m]
    stop: float = 0.0
    severity: float = 0.0  # fraction of EI lost

    @property
    def centre(self):
        return 0.5 * (self.start + self.stop)

    def truth(self, mesh, nominal):
        """EI on ``mesh`` (per element) for this scenario."""
        ei = np.array(nominal, dtype=float)
        if self.kind == "control":
            return ei
        inside = (mesh.midpoints > self.start) & (mesh.midpoints < self.stop)
        ei[inside] *= 1.0 - self.severity
        return ei


def make_scenarios(case, n_locations=8, *, severity=0.25, length=2.0, n_controls=None, spans=True):
    """Local losses scanned across the bridge, span-wise softening and undamaged controls."""
    if not 0.0 < severity < 1.0:
        raise ConfigError(f"The 'severity' parameter must be in (0, 1). Got {severity!r} instead.")
    total = case.bridge.length
    if not MIN_ZONE_LENGTH <= length < total:
        raise ConfigError(f"The 'length' parameter must be in [{MIN_ZONE_LENGTH:g}, {total:g}) m (1 mm to the bridge "
                          f"length). Got {length!r} instead.")
    if int(n_locations) != n_locations or n_locations < 1:
        raise ConfigError(f"The 'scenarios' parameter must be a positive integer. Got {n_locations!r} instead.")
    h = float(np.min(case.mesh.lengths))
    # centres spread over the bridge, shifted by a fraction of an element so
    # that damage edges fall inside inversion elements
    centres = length / 2 + (total - length) * (np.arange(n_locations) + 0.5) / n_locations + 0.37 * h
    centres = np.clip(centres, length / 2, total - length / 2)
    out = [Scenario("local", c - length / 2, c + length / 2, severity) for c in centres]
    if spans:
        xs = case.bridge.support_positions
        out += [Scenario("span", a, b, severity) for a, b in zip(xs[:-1], xs[1:])]
    n_controls = max(5, n_locations // 2) if n_controls is None else int(n_controls)
    out += [Scenario("control")] * n_controls
    return out


def truth_mesh(case):
    """Finer, differently aligned mesh: 4 k + 1 elements in a span of k elements."""
    counts = np.bincount(case.bridge.span_of(case.mesh.midpoints), minlength=case.bridge.n_spans)
    return Mesh.from_counts(case.bridge, [4 * int(k) + 1 for k in counts])


def element_average_ei(fine_mesh, fine_ei, mesh):
    """EI of each element of ``mesh`` equivalent to ``fine_ei`` (average compliance, paper eq. v_avg)."""
    lo = np.maximum(mesh.edges[:-1, None], fine_mesh.edges[None, :-1])
    hi = np.minimum(mesh.edges[1:, None], fine_mesh.edges[None, 1:])
    overlap = np.clip(hi - lo, 0.0, None)
    return mesh.lengths / (overlap @ (1.0 / fine_ei))


