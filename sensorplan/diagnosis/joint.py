"""The base model extended by candidate effects, as a problem for the inversion engine.

Parameters: log EI per element of the case's mesh, then one block per
effect.  Prior: the GMRF on log EI (rough part scaled by tau) and the
effects' own independent Gaussian priors (fixed part).  Springs of the
configuration stay fixed unless an effect frees them.  ``masks`` select
which rows (load positions) of each crossing enter the likelihood, so the
same problem serves fitting and held-out prediction.
"""


import numpy as np

from .._errors import ConfigError
from ..inference.laplace import Linearisation, WhitenedData
from ..model.forward import influence_lines
from ..model.loads import Vehicle
from ..model.sensors import SensorLayout
from .effects import State

__all__ = []


class JointProblem(WhitenedData):
    """The case's model extended by ``effects``, fitted jointly with log EI (rows in ``masks``)."""

    def __init__(self, case, crossings, effects, prior, *, masks=None):
        super().__init__(case, crossings, masks=masks)
        self.n_sensors = self.sensors.n_sensors
        self.sensor_names = self.sensors.names
        self.n_crossings = len(crossings)
        self.labels = crossings.labels
        peak = np.array([max(float(np.max(np.abs(c.values[i]))) for c in crossings) for i in range(self.n_sensors)])
        self.offset_scale = np.maximum(0.2 * peak, 3.0 * self.noise.std)
        self.effects = [e.configure(self) for e in effects]
        self.n_elements = case.mesh.n_elements
        sizes = [e.n_params for e in self.effects]
        self.slices = []
        start = self.n_elements
        for n in sizes:
            self.slices.append(slice(start, start + n))
            start += n
        self.n_params = start
        self.theta0 = np.concatenate([np.log(case.ei)] + [e.mean for e in self.effects])
        self.param_names = [f"log_ei_{j}" for j in range(self.n_elements)] + [
            f"{e.name}:{n}" for e in self.effects for n in e.names]
        self.rough = np.zeros((self.n_params, self.n_params))
        self.rough[:self.n_elements, :self.n_elements] = prior.structure(self.n_elements)
        diag = np.concatenate([np.full(self.n_elements, 1.0 / prior.marginal_std**2)]
                              + [1.0 / e.std**2 for e in self.effects])
        self.fixed = np.diag(diag)
        self._ei = None
        self._cache = {}
        self._last = None

    # -- context used by the effects -----------------------------------------------------
    def load_factor(self, c):
        return self.crossings.crossings[c].load_factor

    def lines(self, state, c, *, positions=None, sensor_positions=None):
        x = state.positions[c] if positions is None else positions
        r = state.sensor_positions if sensor_positions is None else sensor_positions
        key = (x.tobytes(), r.tobytes(), state.bridge, state.axle_factors.tobytes())
        if key not in self._cache:
            sensors = SensorLayout(r, self.sensors.kinds, self.sensors.names)
            vehicle = Vehicle(self.case.vehicle.axle_offsets,
                              tuple(np.asarray(self.case.vehicle.axle_loads) * state.axle_factors))
            self._cache[key] = influence_lines(state.bridge, self.case.mesh, self._ei, sensors, vehicle, x)
        return self._cache[key]

    def axle_lines(self, state, c, axle):
        """Response to axle ``axle`` alone (with its current load)."""
        x = state.positions[c] - self.case.vehicle.axle_offsets[axle]
        load = self.case.vehicle.axle_loads[axle] * state.axle_factors[axle]
        sensors = SensorLayout(state.sensor_positions, self.sensors.kinds, self.sensors.names)
        return influence_lines(state.bridge, self.case.mesh, self._ei, sensors, Vehicle.point_load(load),
                               x).predictions

    # -- evaluation ------------------------------------------------------------------------
    def predict(self, theta):
        """Unwhitened predictions and Jacobians per crossing: list of (y (S,K), J (S,K,P))."""
        self._ei = np.exp(theta[:self.n_elements])
        self._cache = {}
        state = State(self.case.bridge, self.sensors.positions.copy(),
                      [c.positions.copy() for c in self.crossings], np.ones(self.case.vehicle.n_axles))
        for e, sl in zip(self.effects, self.slices):
            if e.structural:
                e.apply(state, theta[sl])
        out = []
        for c in range(self.n_crossings):
            lines = self.lines(state, c)
            lf = self.load_factor(c)
            y = lines.predictions * lf[None, :]
            jac = np.zeros(y.shape + (self.n_params,))
            jac[:, :, :self.n_elements] = lines.jacobian("log_ei") * lf[None, :, None]
            for e, sl in zip(self.effects, self.slices):
                if e.structural:
                    jac[:, :, sl] = e.structural_jacobian(self, state, theta[sl], c, y)
            for e, sl in zip(self.effects, self.slices):
                if not e.structural:
                    y, block, mult = e.output(self, state, theta[sl], c, y)
                    if mult != 1.0:
                        jac *= mult
                    jac[:, :, sl] += block
            out.append((y, jac))
        return out

    def evaluate(self, theta, *, jacobian=True):
        key = theta.tobytes()
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        if not np.all(np.isfinite(theta)) or np.any(np.abs(theta[:self.n_elements]) > 60):
            return None
        try:
            preds = self.predict(theta)
        except ConfigError:  # an effect drove the model out of its domain (e.g. unstable springs)
            return None
        rr = 0.0
        jtj = np.zeros((self.n_params, self.n_params))
        jtr = np.zeros(self.n_params)
        for c, (y, jac) in enumerate(preds):
            m = self.masks[c]
            if not m.any():
                continue
            x = self.crossings[c].positions[m]
            r = (self.white_data[c] - self.noise.whiten(y[:, m], x)).ravel()
            wj = self.noise.whiten(jac[:, m], x).reshape(-1, self.n_params)
            rr += float(r @ r)
            jtj += wj.T @ wj
            jtr += wj.T @ r
        out = Linearisation(rr, jtj, jtr)
        self._last = (key, out)
        return out

    def heldout(self, theta, covariance, alpha, masks):
        """Log predictive density and squared residuals of the rows in ``masks``."""
        preds = self.predict(theta)
        logp, sq, count = 0.0, 0.0, 0
        for c, (y, jac) in enumerate(preds):
            m = masks[c]
            if not m.any():
                continue
            x = self.crossings[c].positions[m]
            data = self.crossings[c].values[:, m]
            r = (self.noise.whiten(data, x) - self.noise.whiten(y[:, m], x)).ravel()
            wj = self.noise.whiten(jac[:, m], x).reshape(-1, self.n_params)
            cov = alpha**2 * np.eye(r.size) + wj @ covariance @ wj.T
            chol = np.linalg.cholesky(cov)
            z = np.linalg.solve(chol, r)
            logp += float(-0.5 * z @ z - np.sum(np.log(np.diag(chol))) - 0.5 * r.size * np.log(2 * np.pi))
            logp -= float(self.noise.log_det_gamma(x) * self.n_sensors / 2 + m.sum() * np.sum(np.log(self.noise.std)))
            sq += float(np.sum((data - y[:, m]) ** 2))
            count += data.size
        return logp, sq, count

    def residuals(self, theta):
        """Unwhitened residuals per crossing (S, K)."""
        return [c.values - y for c, (y, _) in zip(self.crossings, self.predict(theta))]
