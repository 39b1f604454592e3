"""Bayesian identification of EI(x): the whitened-problem engine and the EI problem.

:mod:`.engine` is the one engine of every whitened least-squares problem
(the EI problem here, the joint problem of the diagnosis): the whitened data
and their normal equations (:class:`~.engine.WhitenedProblem`), the
Levenberg-Marquardt MAP, the secant curvature and the Laplace evidence;
:mod:`.laplace` the hyperparameter point estimates (evidence maximisation,
quasi-optimality, GCV) and :mod:`.hyperposterior` their integration (a
quadrature over log tau of Laplace posteriors); :mod:`.mixture` the
resulting Gaussian mixture; :mod:`.ei_problem` the EI problem,
:mod:`.inversion` :func:`invert`; :mod:`.posterior` the result type;
:mod:`.screening` the data checks; :mod:`.checks` the checks of a finished
fit; :mod:`.damage` the local-loss hypotheses of the bands.

Owns: the engine, MAP, Laplace, hyperparameters, posterior results.
May import: model, detection and the foundations.
"""
