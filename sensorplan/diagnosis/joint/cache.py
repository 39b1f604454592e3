"""What a joint problem keeps between evaluations, in one object with one ``clear()``.

Owns: :class:`JointCache`.  May import: the cache.
"""

from ..._cache import Cache, value_key

__all__ = ["JointCache"]

LINES_HELD = 256  # lines, slopes and axle responses kept at one EI before they are dropped (a bound on memory)


class JointCache:
    """The memo of a :class:`~.problem.JointProblem`: every entry keyed by the values it was computed from.

    * ``lines``: interpolants, lines, slopes and axle responses at the
      current EI (their keys hold the model state, not EI): dropped when EI
      changes (:meth:`at_ei`), so that the Jacobian at an accepted trial point
      reuses the trial's forward solve and no older EI is kept;
    * ``maps``: the interpolation maps of the loads (independent of EI),
      dropped all at once when they would hold more than ``budget_rows``
      rows (loads moved by an effect make new maps at every evaluation);
    * ``layouts``: the bin maps of binned crossings side by side;
    * ``grams``: R^T diag(w) R of the mapped weights (:mod:`.factored`);
    * ``last``: the last evaluation.
    """

    def __init__(self, *, budget_rows, n_grams):
        self.budget_rows = budget_rows
        self.lines = Cache()
        self.maps = Cache()
        self.layouts = Cache()
        self.grams = Cache(maxsize=n_grams)
        self.last = Cache(maxsize=1)
        self._ei_key = None
        self._rows_held = 0

    def at_ei(self, ei):
        """Make ``ei`` the EI of the ``lines`` entries (dropping them if it changed or they grew past a bound)."""
        key = value_key(ei)
        if key != self._ei_key or len(self.lines) > LINES_HELD:
            self.lines.clear()
            self._ei_key = key
        return key

    def maps_for(self, key, build):
        """The interpolation maps under ``key``, built by ``build()`` (and kept) when absent."""
        found, maps = self.maps.lookup((), key=key)
        if not found:
            maps = build()
            if self._rows_held + maps.n_rows > self.budget_rows:
                self.maps.clear()
                self._rows_held = 0
            self.maps.put((), maps, key=key)
            self._rows_held += maps.n_rows
        return maps

    def clear(self):
        """Forget everything (it is rebuilt on demand)."""
        for cache in (self.lines, self.maps, self.layouts, self.grams, self.last):
            cache.clear()
        self._ei_key = None
        self._rows_held = 0
