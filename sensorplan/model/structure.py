"""Structure: spans, supports with springs, and the element mesh of EI(x).

Units: lengths [m], vertical springs [N/m], rotational springs [N m/rad],
flexural rigidity [N m^2].
"""

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .._errors import ConfigError
from .._validation import as_float, as_float_array, as_float_tuple

__all__ = ["Support", "Bridge", "Mesh"]

_MAX_ELEMENTS = 20_000


@dataclass(frozen=True)
class Support:
    """One support of the beam.

    Parameters
    ----------
    position : float
        Position along the bridge [m].
    vertical_stiffness : float
        Vertical spring [N/m]; ``inf`` (default) is rigid.  Must be > 0.
    rotational_stiffness : float
        Rotational spring [N m/rad]; 0 (default) is a pin, ``inf`` a clamp.
    """

    position: float
    vertical_stiffness: float = math.inf
    rotational_stiffness: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "position", as_float(self.position, "position", "Support"))
        object.__setattr__(
            self,
            "vertical_stiffness",
            as_float(self.vertical_stiffness, "vertical_stiffness", "Support",
                     low=0.0, low_open=True, allow_inf=True),
        )
        object.__setattr__(
            self,
            "rotational_stiffness",
            as_float(self.rotational_stiffness, "rotational_stiffness", "Support",
                     low=0.0, allow_inf=True),
        )


@dataclass(frozen=True)
class Bridge:
    """A straight beam over supports at the ends of consecutive spans.

    Parameters
    ----------
    spans : sequence of float
        Span lengths from left to right [m].
    rotational_springs : sequence of float, optional
        One per support [N m/rad]; 0 = pin (default), ``inf`` = clamped.
    vertical_springs : sequence of float, optional
        One per support [N/m]; ``inf`` = rigid (default).  Must be > 0.

    Examples
    --------
    >>> bridge = Bridge(spans=(15.0, 15.0), rotational_springs=(1e9, 0.0, 1e9))
    >>> bridge.length
    30.0
    >>> bridge.support_positions.tolist()
    [0.0, 15.0, 30.0]
    """

    spans: tuple
    rotational_springs: tuple | None = None
    vertical_springs: tuple | None = None

    def __post_init__(self):
        spans = as_float_tuple(self.spans, "spans", "Bridge", low=0.0, low_open=True)
        n_supports = len(spans) + 1
        rot = self.rotational_springs
        rot = (0.0,) * n_supports if rot is None else as_float_tuple(
            rot, "rotational_springs", "Bridge", length=n_supports, low=0.0, allow_inf=True)
        vert = self.vertical_springs
        vert = (math.inf,) * n_supports if vert is None else as_float_tuple(
            vert, "vertical_springs", "Bridge", length=n_supports, low=0.0, low_open=True,
            allow_inf=True)
        object.__setattr__(self, "spans", spans)
        object.__setattr__(self, "rotational_springs", rot)
        object.__setattr__(self, "vertical_springs", vert)

    @property
    def n_spans(self):
        return len(self.spans)

    @property
    def length(self):
        """Total length [m]."""
        return float(sum(self.spans))

    @cached_property
    def support_positions(self):
        """Support positions [m], shape (n_spans + 1,)."""
        out = np.concatenate([[0.0], np.cumsum(self.spans)])
        out.setflags(write=False)
        return out

    @property
    def supports(self):
        """The supports as :class:`Support` objects."""
        return tuple(
            Support(x, kv, kr)
            for x, kv, kr in zip(self.support_positions, self.vertical_springs,
                                 self.rotational_springs)
        )

    @cached_property
    def spring_parameters(self):
        """Elastic springs (0 < k < inf) as ``(support_index, kind)`` pairs.

        ``kind`` is ``"rotational"`` or ``"vertical"``.  Only these springs have
        a finite log-stiffness that data can inform; pins, clamps and rigid
        supports are fixed boundary conditions.
        """
        out = []
        for i, k in enumerate(self.rotational_springs):
            if 0.0 < k < math.inf:
                out.append((i, "rotational"))
        for i, k in enumerate(self.vertical_springs):
            if k < math.inf:
                out.append((i, "vertical"))
        return tuple(out)

    @property
    def spring_names(self):
        """Names of :attr:`spring_parameters`, e.g. ``"rotational_0"``."""
        return tuple(f"{kind}_{i}" for i, kind in self.spring_parameters)

    def spring_stiffness(self):
        """Stiffness of each elastic spring, in :attr:`spring_parameters` order."""
        return np.array([self._stiffness(i, kind) for i, kind in self.spring_parameters])

    def _stiffness(self, i, kind):
        return self.rotational_springs[i] if kind == "rotational" else self.vertical_springs[i]

    def with_spring_stiffness(self, stiffness):
        """Return a copy with the elastic springs set to ``stiffness``.

        ``stiffness`` follows :attr:`spring_parameters` order.
        """
        stiffness = np.asarray(stiffness, dtype=float)
        if stiffness.shape != (len(self.spring_parameters),):
            raise ConfigError(
                f"The 'stiffness' parameter of Bridge.with_spring_stiffness must have "
                f"{len(self.spring_parameters)} entries. Got shape {stiffness.shape} instead.")
        rot = list(self.rotational_springs)
        vert = list(self.vertical_springs)
        for (i, kind), k in zip(self.spring_parameters, stiffness):
            if not (0.0 < k < math.inf):
                raise ConfigError(
                    f"Spring stiffnesses must stay positive and finite. Got {k!r} for {kind}_{i}.")
            if kind == "rotational":
                rot[i] = float(k)
            else:
                vert[i] = float(k)
        return Bridge(self.spans, tuple(rot), tuple(vert))

    def span_of(self, x):
        """Index of the span containing each position ``x`` (supports go right)."""
        x = np.asarray(x, dtype=float)
        idx = np.searchsorted(self.support_positions, x, side="right") - 1
        return np.clip(idx, 0, self.n_spans - 1)

    def check_on_bridge(self, positions, name, owner):
        """Raise a :class:`ConfigError` if a position lies off the bridge."""
        positions = np.asarray(positions, dtype=float)
        bad = (positions < 0.0) | (positions > self.length) | ~np.isfinite(positions)
        if np.any(bad):
            what = owner if owner.startswith("--") else f"The '{name}' parameter of {owner}"
            raise ConfigError(
                f"{what} must lie on the bridge (0 to {self.length:g} m). "
                f"Got {float(positions[bad][0])!r} m instead.")


@dataclass(frozen=True, eq=False)
class Mesh:
    """Element mesh on which EI(x) is piecewise constant.

    Parameters
    ----------
    edges : array_like
        Strictly increasing element edges [m] from 0 to the bridge length.
        Must contain every support position.
    """

    edges: np.ndarray

    def __post_init__(self):
        edges = as_float_array(self.edges, "edges", "Mesh")
        if edges.size < 2 or np.any(np.diff(edges) <= 0.0):
            raise ConfigError(
                "The 'edges' parameter of Mesh must be strictly increasing with at least "
                f"2 entries. Got {edges.tolist()[:6]!r} instead.")
        object.__setattr__(self, "edges", edges)

    @classmethod
    def uniform(cls, bridge, n_elements):
        """Mesh with about ``n_elements`` elements, spread over the spans by length.

        Each span gets ``max(1, round(n_elements * span / length))`` equal
        elements, adjusted so that the total is exactly ``n_elements`` when
        ``n_elements >= n_spans``.
        """
        try:
            valid = (not isinstance(n_elements, (bool, str)) and int(n_elements) == n_elements
                     and bridge.n_spans <= n_elements <= _MAX_ELEMENTS)
        except (TypeError, ValueError, OverflowError):
            valid = False
        if not valid:
            raise ConfigError(
                f"The 'elements' parameter of Mesh must be an integer from the number of spans "
                f"({bridge.n_spans}) to {_MAX_ELEMENTS}. Got {n_elements!r} instead.")
        counts = _split_count(np.array(bridge.spans), int(n_elements))
        return cls.from_counts(bridge, counts)

    @classmethod
    def from_length(cls, bridge, element_length):
        """Mesh with elements of at most ``element_length`` [m] in every span."""
        h = as_float(element_length, "element_length", "Mesh", low=0.0, low_open=True)
        counts = [max(1, math.ceil(span / h - 1e-9)) for span in bridge.spans]
        if sum(counts) > _MAX_ELEMENTS:
            raise ConfigError(f"The 'element_length' parameter of Mesh gives {sum(counts)} elements, "
                              f"more than {_MAX_ELEMENTS}. Use a longer element length.")
        return cls.from_counts(bridge, counts)

    @classmethod
    def from_counts(cls, bridge, counts):
        """Mesh with ``counts[i]`` equal elements in span ``i``."""
        pieces = [
            np.linspace(a, b, n + 1)[:-1]
            for a, b, n in zip(bridge.support_positions[:-1], bridge.support_positions[1:], counts)
        ]
        edges = np.concatenate(pieces + [[bridge.length]])
        return cls(edges)

    @property
    def n_elements(self):
        return self.edges.size - 1

    @cached_property
    def lengths(self):
        """Element lengths [m]."""
        return np.diff(self.edges)

    @cached_property
    def midpoints(self):
        """Element midpoints [m]."""
        return 0.5 * (self.edges[1:] + self.edges[:-1])

    def check_fits(self, bridge):
        """Raise a :class:`ConfigError` unless the mesh spans ``bridge`` with edges at supports."""
        if abs(self.edges[0]) > 1e-9 or abs(self.edges[-1] - bridge.length) > 1e-9 * max(1.0, bridge.length):
            raise ConfigError(
                f"The mesh must run from 0 to the bridge length {bridge.length:g} m. "
                f"Got {self.edges[0]:g} to {self.edges[-1]:g} m instead.")
        for x in bridge.support_positions:
            if np.min(np.abs(self.edges - x)) > 1e-9 * max(1.0, bridge.length):
                raise ConfigError(
                    f"The mesh edges must include every support. Support at {x:g} m is not an edge.")

    def element_of(self, x):
        """Index of the element containing each position ``x`` (edges go right)."""
        idx = np.searchsorted(self.edges, np.asarray(x, dtype=float), side="right") - 1
        return np.clip(idx, 0, self.n_elements - 1)

    def span_values(self, bridge, per_span):
        """Expand one value per span into one value per element."""
        per_span = np.asarray(per_span, dtype=float)
        return per_span[bridge.span_of(self.midpoints)]


def _split_count(spans, total):
    """Largest-remainder split of ``total`` elements over spans by length, >= 1 each."""
    ideal = spans / spans.sum() * total
    counts = np.maximum(1, np.floor(ideal).astype(int))
    while counts.sum() < total:
        counts[np.argmax(ideal - counts)] += 1
    while counts.sum() > total:
        candidates = np.where(counts > 1)[0]
        counts[candidates[np.argmin((ideal - counts)[candidates])]] -= 1
    return counts
