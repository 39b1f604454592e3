"""Fisher information: per-sensor blocks, informativeness curves, identifiability.

For sensor i with Jacobian J_i (n_loads x n_params), noise standard
deviation sigma_i and within-crossing correlation Gamma_i, the Fisher
information of one crossing is I^(i) = J_i^T Gamma_i^{-1} J_i / sigma_i^2
(paper eq. fisher-sum); n independent crossings multiply it by n.  Gamma_i^{-1}
is applied through the whitening of :class:`NoiseModel` (a bidiagonal AR(1)
recursion in x, or the Kalman filter of the time model at the crossing
speed), never as a dense inverse.  Parameterisations follow the paper's chain rule
(eq. fisher-ei): dy/dEI = -dy/dv / EI^2, dy/dlog EI = -dy/dv / EI.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from .._errors import ConfigError
from .._threads import single_threaded
from .forward import influence_lines

if TYPE_CHECKING:
    from .case import Case
    from .noise import NoiseModel
    from .prior import GMRFPrior
    from .sensors import SensorLayout

__all__ = ["FisherBlocks", "fisher_blocks", "Identifiability", "identifiability", "Informativeness",
           "informativeness"]

_UNITS = {"compliance": "(N m^2)^2 / unit^2", "ei": "1 / (N m^2)^2", "log_ei": "dimensionless"}


@dataclass(frozen=True, eq=False)
class FisherBlocks:
    """Per-sensor Fisher information blocks.

    Attributes
    ----------
    blocks : ndarray, shape (n_sensors, n_params, n_params)
        I^(i) for each sensor, for ``n_crossings`` crossings.
    parameterisation : str
        ``"compliance"``, ``"ei"`` or ``"log_ei"`` for the element parameters.
    n_elements, n_springs : int
        The parameters are the elements, then (optionally) the spring
        log-stiffnesses of ``bridge.spring_parameters``.
    sensors : SensorLayout
    edges : ndarray
        Element edges [m].
    """

    blocks: np.ndarray
    parameterisation: str
    n_elements: int
    n_springs: int
    sensors: object
    edges: np.ndarray
    n_crossings: int

    @property
    def n_sensors(self):
        return self.blocks.shape[0]

    @property
    def n_params(self):
        return self.blocks.shape[1]

    def total(self, weights=None):
        """Sum of the blocks weighted by ``weights`` (default all ones)."""
        if weights is None:
            return self.blocks.sum(axis=0)
        weights = np.asarray(weights, dtype=float)
        if weights.shape != (self.n_sensors,):
            raise ConfigError(f"The 'weights' parameter must have {self.n_sensors} entries. "
                              f"Got shape {weights.shape} instead.")
        return np.tensordot(weights, self.blocks, axes=1)

    @cached_property
    def curves(self):
        """Informativeness curves: diag of I^(i) per element, shape (n_sensors, n_elements)."""
        idx = np.arange(self.n_elements)
        return self.blocks[:, idx, idx]

    def peaks(self):
        """Midpoint [m] of the element where each sensor's curve peaks."""
        mid = 0.5 * (self.edges[1:] + self.edges[:-1])
        return mid[np.argmax(self.curves, axis=1)]

    @property
    def unit(self):
        return _UNITS[self.parameterisation]

    def subset(self, index):
        index = np.atleast_1d(index)
        return FisherBlocks(self.blocks[index], self.parameterisation, self.n_elements,
                            self.n_springs, self.sensors.subset(index), self.edges, self.n_crossings)

    def summary(self):
        lines = [f"Fisher information ({self.parameterisation}, {self.n_crossings} crossing(s), "
                 f"{self.n_elements} elements, {self.n_springs} springs)"]
        for name, x, peak, top in zip(self.sensors.names, self.sensors.positions, self.peaks(),
                                      self.curves.max(axis=1)):
            lines.append(f"  {name:>10s} at {x:8.3f} m: curve peaks at {peak:8.3f} m ({top:.3e})")
        return "\n".join(lines)

    def to_dict(self):
        return {
            "parameterisation": self.parameterisation,
            "n_crossings": self.n_crossings,
            "edges_m": self.edges.tolist(),
            "sensors": list(self.sensors.names),
            "positions_m": self.sensors.positions.tolist(),
            "curves": self.curves.tolist(),
            "peaks_m": self.peaks().tolist(),
        }


@single_threaded
def fisher_blocks(case: "Case", *, sensors: "SensorLayout | None" = None, noise: "NoiseModel | None" = None,
                  ei: "np.ndarray | None" = None, parameterisation: str = "log_ei", springs: bool = False,
                  n_crossings: int = 1, chunk_size: int = 64) -> "FisherBlocks":
    """Per-sensor Fisher information blocks for ``case``.

    Parameters
    ----------
    case : Case
        Bridge, mesh, nominal EI, vehicle and load sweep.
    sensors : SensorLayout, optional
        Sensors or candidate positions (default: the case's sensors).
    noise : NoiseModel, optional
        Must match ``sensors`` (default: the case's noise, or a noise model
        built from ``sensors.noise_std``, or else for each sensor the median
        noise of the case's sensors of its kind, :meth:`Case.noise_std_for`).
    ei : array_like, optional
        EI at which to evaluate (default: the nominal).
    parameterisation : {"compliance", "ei", "log_ei"}
    springs : bool
        Append the spring log-stiffnesses as extra (nuisance) parameters.
    n_crossings : int
        Number of independent crossings.
    chunk_size : int
        Sensors per forward evaluation (bounds the memory).
    """
    sensors = case.sensors if sensors is None else sensors
    noise = _resolve_noise(case, sensors, noise)
    if int(n_crossings) != n_crossings or n_crossings < 1:
        raise ConfigError(f"The 'n_crossings' parameter must be a positive integer. Got {n_crossings!r} instead.")
    positions = case.sweep.positions
    n_springs = len(case.bridge.spring_parameters) if springs else 0
    n_params = case.mesh.n_elements + n_springs
    blocks = np.empty((sensors.n_sensors, n_params, n_params))
    for start in range(0, sensors.n_sensors, chunk_size):
        index = np.arange(start, min(start + chunk_size, sensors.n_sensors))
        chunk = sensors.subset(index)
        lines = influence_lines(case.bridge, case.mesh, case.ei if ei is None else ei, chunk,
                                case.vehicle, positions)
        white = noise.subset(index).whiten(lines.jacobian(parameterisation, springs=springs), positions)
        chunk_blocks = np.matmul(white.transpose(0, 2, 1), white)
        chunk_blocks *= n_crossings
        # symmetrised chunk by chunk: no temporary of the size of all blocks
        blocks[index] = 0.5 * (chunk_blocks + chunk_blocks.transpose(0, 2, 1))
    blocks.setflags(write=False)
    return FisherBlocks(blocks, parameterisation, case.mesh.n_elements, n_springs, sensors,
                        case.mesh.edges, int(n_crossings))


def _resolve_noise(case, sensors, noise):
    if noise is not None:
        if noise.n_sensors != sensors.n_sensors:
            raise ConfigError(f"The noise model has {noise.n_sensors} entries for "
                              f"{sensors.n_sensors} sensors.")
        return noise
    noise = case.noise_for(sensors)  # new sensors: the median noise of the case's sensors of the same kind
    if noise is not None:
        return noise
    raise ConfigError("No noise level is known for the sensors; set noise_std in [sensors].")


@dataclass(frozen=True, eq=False)
class Identifiability:
    """Eigen-analysis of the total information and its split against a prior.

    Attributes
    ----------
    eigenvalues : ndarray (n_params,)
        Eigenvalues of the total information, largest first.
    eigenvectors : ndarray (n_params, n_params)
        Columns are the matching directions (fields along the bridge for the
        element part).
    threshold : float
        Eigenvalues >= threshold * largest count towards :attr:`effective_rank`.
    data_precision, prior_precision : ndarray (n_params,) or None
        Per-parameter split of the posterior precision diagonal.
    """

    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    threshold: float
    edges: np.ndarray
    n_elements: int
    data_precision: np.ndarray | None = None
    prior_precision: np.ndarray | None = None
    data_dof: float | None = None

    @property
    def effective_rank(self):
        """Number of eigenvalues above ``threshold`` times the largest."""
        top = self.eigenvalues[0] if self.eigenvalues.size else 0.0
        return int(np.sum(self.eigenvalues >= self.threshold * top)) if top > 0 else 0

    @property
    def condition_number(self):
        low = self.eigenvalues[-1]
        return np.inf if low <= 0 else float(self.eigenvalues[0] / low)

    def well_informed(self, count=3):
        """The ``count`` best-informed directions (columns)."""
        return self.eigenvectors[:, :count]

    def poorly_informed(self, count=3):
        """The ``count`` least-informed directions (columns), least first."""
        return self.eigenvectors[:, ::-1][:, :count]

    @property
    def data_share(self):
        """Fraction of each parameter's posterior precision that comes from the data."""
        if self.data_precision is None:
            return None
        return self.data_precision / (self.data_precision + self.prior_precision)

    def summary(self):
        lines = [f"Identifiability: effective rank {self.effective_rank} of {self.eigenvalues.size} "
                 f"(threshold {self.threshold:g} of the largest eigenvalue)",
                 f"  eigenvalues: largest {self.eigenvalues[0]:.3e}, smallest {self.eigenvalues[-1]:.3e}"]
        if self.data_dof is not None:
            lines.append(f"  parameters determined by the data (trace I Q^-1): {self.data_dof:.2f}")
        return "\n".join(lines)

    def to_dict(self):
        out = {"eigenvalues": self.eigenvalues.tolist(), "effective_rank": self.effective_rank,
               "threshold": self.threshold}
        if self.data_precision is not None:
            out.update(data_precision=self.data_precision.tolist(),
                       prior_precision=self.prior_precision.tolist(),
                       data_dof=self.data_dof)
        return out


def identifiability(information: "FisherBlocks | np.ndarray", *, prior_precision: "np.ndarray | None" = None,
                    threshold: float = 1e-6, edges: "np.ndarray | None" = None,
                    n_elements: int | None = None) -> "Identifiability":
    """Eigen-analysis of a total information matrix.

    Parameters
    ----------
    information : ndarray (n_params, n_params) or FisherBlocks
        Total Fisher information (FisherBlocks are summed).
    prior_precision : ndarray (n_params, n_params), optional
        Gives the per-parameter split of the posterior precision into data
        and prior parts and the effective number of parameters determined by
        the data, trace(I (I + Q_prior)^{-1}).
    threshold : float
        Relative eigenvalue threshold of the effective rank.
    """
    if isinstance(information, FisherBlocks):
        edges = information.edges if edges is None else edges
        n_elements = information.n_elements if n_elements is None else n_elements
        information = information.total()
    information = np.asarray(information, dtype=float)
    n = information.shape[0]
    vals, vecs = np.linalg.eigh(0.5 * (information + information.T))
    order = np.argsort(vals)[::-1]
    vals = np.clip(vals[order], 0.0, None)
    vecs = vecs[:, order]
    # Fix the sign of each direction so that its largest component is positive.
    flip = np.sign(vecs[np.argmax(np.abs(vecs), axis=0), np.arange(n)])
    vecs = vecs * np.where(flip == 0, 1.0, flip)
    data = prior = dof = None
    if prior_precision is not None:
        prior_precision = np.asarray(prior_precision, dtype=float)
        data = np.diag(information).copy()
        prior = np.diag(prior_precision).copy()
        post = information + prior_precision
        dof = float(np.trace(np.linalg.solve(post, information)))
    return Identifiability(vals, vecs, float(threshold), np.asarray(edges), n if n_elements is None else n_elements,
                           data, prior, dof)


@dataclass(frozen=True, eq=False)
class Informativeness:
    """What a set of sensors sees: Fisher blocks (curves) and the identifiability of log EI.

    Attributes
    ----------
    blocks : FisherBlocks
        Per-sensor information in the requested parameterisation.
    identifiability : Identifiability
        Eigen-analysis of the log-EI information against the GMRF prior.
    supports_m : tuple of float
        Support positions [m] (for figures).
    ei_std_percent : tuple of float
        Per sensor: the EI standard deviation [%] it alone would leave on its
        best-informed element if every other element were known
        (100 / sqrt(max_j I_jj) of log EI, the Cramér-Rao bound).
    """

    blocks: FisherBlocks
    identifiability: "Identifiability"
    supports_m: tuple
    ei_std_percent: tuple = ()

    def summary(self):
        lines = [self.blocks.summary()]
        if self.ei_std_percent:
            lines.append("  alone, each sensor pins EI of its best element to a std of: " + ", ".join(
                f"{n} {p:.3g} %" for n, p in zip(self.blocks.sensors.names, self.ei_std_percent))
                + " (other elements known)")
        return "\n".join(lines + [self.identifiability.summary()])

    def to_dict(self):
        return {"blocks": self.blocks.to_dict(), "identifiability": self.identifiability.to_dict()}


def informativeness(case: "Case", *, positions: "Sequence[float] | None" = None, kind: str | None = None,
                    noise_std: float | None = None, n_crossings: int = 1, parameterisation: str = "ei",
                    prior: "GMRFPrior | None" = None) -> Informativeness:
    """Informativeness curves and identifiability of the case's sensors or of new ``positions``.

    Parameters
    ----------
    case : Case
    positions : sequence of float, optional
        Positions [m] of new sensors of ``kind`` (default: the case's sensors).
    kind : {"rotation", "deflection"}, optional
        Default: the case's kind (:attr:`Case.default_kind`).
    noise_std : float, optional
        Noise std of the new sensors [rad or m] (default :meth:`Case.noise_std_for`).
    n_crossings : int
    parameterisation : {"ei", "log_ei", "compliance"}
        Parameters of the curves; the identifiability is always in log EI.
    prior : GMRFPrior, optional
        Prior of the identifiability analysis (default ``GMRFPrior()``).

    Returns
    -------
    Informativeness
    """
    from .prior import GMRFPrior
    from .sensors import SensorLayout

    sensors = None
    if positions is not None:
        case.bridge.check_on_bridge(positions, "positions", "--positions")
        kind = case.default_kind if kind is None else kind
        noise = case.noise_std_for(kind, noise_std)
        sensors = SensorLayout.candidates(list(positions), kind, noise_std=[noise] * len(positions))
    blocks = fisher_blocks(case, sensors=sensors, parameterisation=parameterisation, n_crossings=n_crossings)
    log_blocks = blocks if parameterisation == "log_ei" else fisher_blocks(
        case, sensors=sensors, parameterisation="log_ei", n_crossings=n_crossings)
    prior = GMRFPrior() if prior is None else prior
    ident = identifiability(log_blocks, prior_precision=prior.precision(case.n_elements))
    with np.errstate(divide="ignore"):
        std = 100.0 / np.sqrt(log_blocks.curves.max(axis=1))
    return Informativeness(blocks, ident, tuple(float(x) for x in case.bridge.support_positions),
                           tuple(float(x) for x in std))
