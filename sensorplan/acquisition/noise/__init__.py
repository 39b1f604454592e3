"""A logger channel's noise estimated from the quiet parts of its record.

White noise + an Ornstein-Uhlenbeck part (std, correlation time) + a random
walk per channel (the model of :class:`sensorplan.model.noise.NoiseModel`),
by maximum likelihood of the exact state-space model on the quiet segments,
with standard errors, and the Allan deviation of the data and of the fit.

Owns: :func:`estimate_noise`, :class:`NoiseEstimate` and its parts.
May import: the foundations and model.
"""

from .allan import allan_variance_data, allan_variance_model, octave_factors
from .estimate import estimate_noise, fit_channel
from .quiet import QuietParts, quiet_parts
from .results import AllanDeviation, ChannelEstimate, Estimate, NoiseEstimate

__all__ = ["estimate_noise", "fit_channel", "NoiseEstimate", "ChannelEstimate", "Estimate", "AllanDeviation",
           "quiet_parts", "QuietParts", "allan_variance_data", "allan_variance_model", "octave_factors"]
