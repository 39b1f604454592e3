"""Figures from result objects.  matplotlib is imported lazily, in this subpackage only.

Every function takes the result first and ``ax=None`` and returns the Axes
(scikit-learn's Display convention).  :func:`save_figure` writes a PNG
atomically.

Owns: the figures, one module per kind of result: ``model`` (influence
lines, informativeness, identifiability), ``design`` (layout, uncertainty,
criterion curve, detectability, verification), ``inference`` (EI posterior,
data against model), ``diagnosis`` (the sim-to-real gap), ``acquisition``
(logger records), ``noise`` (a logger's estimated noise: Allan deviation)
and ``common`` (what they share: new figures, the bridge's marks,
engineering units, the PNG writer).
May import: analysis and the layers below it (it reads their result objects).
"""

from .acquisition import plot_crossing_events
from .common import mark_bridge, new_figure, save_figure
from .design import plot_criterion_curve, plot_detectability, plot_layout, plot_posterior_std, plot_verification
from .diagnosis import plot_ei_before_after, plot_residual_map, plot_shrinkage
from .inference import plot_ei_posterior, plot_fit
from .model import plot_eigenvectors, plot_influence_lines, plot_informativeness, plot_spectrum
from .noise import plot_allan_deviation

__all__ = ["plot_informativeness", "plot_spectrum", "plot_eigenvectors", "plot_ei_posterior", "plot_fit", "plot_layout",
           "plot_posterior_std", "plot_criterion_curve", "plot_verification", "plot_residual_map",
           "plot_shrinkage", "plot_ei_before_after", "plot_influence_lines", "plot_detectability",
           "plot_crossing_events", "plot_allan_deviation", "save_figure", "mark_bridge", "new_figure"]
