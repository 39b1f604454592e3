"""The joint model: the case's model extended by effects, fitted jointly with log EI.

:mod:`.problem` (the whitened problem), :mod:`.assembly` (predictions and
Jacobian columns at one parameter vector), :mod:`.source` and :mod:`.lines`
(the vehicle's lines read off the exact interpolant), :mod:`.columns` (the
column blocks effects return), :mod:`.binning` (dense records in whitened
bins), :mod:`.factored` (the log-EI block of binned crossings as two
factors), :mod:`.entry` (axles rolling onto elastic end bearings),
:mod:`.cache` (what a problem keeps between evaluations), :mod:`.fits`
(fits with hyperparameters integrated, warm starts).

Owns: the joint model.  May import: inference, model, the effects' protocol and the foundations.
"""
