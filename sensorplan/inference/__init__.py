"""Bayesian identification of EI(x): one Laplace / evidence engine and the EI problem.

:mod:`.laplace` holds the engine (MAP by Levenberg-Marquardt, Laplace
covariance, evidence maximisation) and :class:`WhitenedData`, the shared
base of every problem (the EI problem here, the joint problem of the
diagnosis); :mod:`.hyperposterior` integrates the hyperparameters out (a
quadrature over log tau of Laplace posteriors); :mod:`.mixture` the
resulting Gaussian mixture; :mod:`.inversion` the EI problem and
:func:`invert`; :mod:`.posterior` the result type; :mod:`.screening` the
data checks; :mod:`.checks` the checks of a finished fit.

Owns: MAP, Laplace, hyperparameters, posterior results.
May import: model and the foundations.
"""
