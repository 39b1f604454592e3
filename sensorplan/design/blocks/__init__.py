"""Candidates' Fisher blocks held in the structure of the beam's kernel instead of one dense P x P block each.

Owns: :class:`StructuredBlocks` (:mod:`.structured`, families of :mod:`.algebra`), their assembly from the
force method (:mod:`.build`) and low-rank roots of dense blocks (:mod:`.roots`).  May import: model, errors.
"""

from .algebra import BlockFamily
from .build import candidate_information, structured_fisher
from .roots import low_rank_roots
from .structured import DENSE_CACHE_BYTES, StructuredBlocks

__all__ = ["DENSE_CACHE_BYTES", "BlockFamily", "StructuredBlocks", "structured_fisher", "candidate_information",
           "low_rank_roots"]
