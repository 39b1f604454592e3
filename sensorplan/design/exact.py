"""Exact search for the detect criterion, as the design to a requirement (:mod:`.target`) uses it.

The branch and bound itself lives with the criterion
(:mod:`.criteria.detect_search`), which also uses it to certify a layout.

Owns: nothing of its own (the public names of the exact search).  May import: design.criteria.
"""

from .criteria.detect_search import MAX_NODES, ExactSearch, estimate_nodes, exact_search

__all__ = ["ExactSearch", "exact_search", "estimate_nodes", "MAX_NODES"]
