"""The case's model extended by effects, as a problem for the inversion engine.

Parameters: log EI per element of the case's mesh, the elastic springs of
the case (log stiffness, as ``invert`` estimates them by default; only the
kinds no effect frees), then one block per effect.  Prior: the GMRF on log
EI (rough part scaled by tau), the spring prior of ``GMRFPrior`` and the
effects' own independent Gaussian priors (fixed part).  ``masks`` select
which rows (load positions) of each crossing enter the likelihood.

:meth:`JointProblem.rows` gives the whitened residuals and Jacobian row by
row (with the crossing and load index of each row), from which the
held-out folds are scored by exact rank updates of the linearised problem.
Binned crossings (:mod:`.binning`: dense records) are modelled at their
readings and mapped onto their whitened bins; the bins are then the rows.

Owns: :class:`JointProblem`.  May import: inference, model, the effects and the joint model's parts.
"""

import numpy as np

from ..._cache import value_key
from ..._errors import ConfigError
from ...inference.engine import NormalEquations, WhitenedProblem, rows_of
from ..effects.base import State
from ..effects.springs import CaseSprings
from .assembly import assemble
from .binning import model_rows
from .factored import add_factored_terms
from .source import LineSource

__all__ = ["ENTRY", "JointProblem"]

ENTRY = 0.1  # m over which an axle moved by an effect rolls onto the bridge (half a tyre contact length)


class JointProblem(WhitenedProblem, LineSource):
    """The case's model extended by ``effects`` (effect objects), fitted jointly with log EI (rows in ``masks``).

    A :class:`~sensorplan.inference.engine.WhitenedProblem` (the whitened
    data, the evidence's data count and noise determinant, the cached
    :meth:`evaluate`, the normal equations): this class gives the
    parameters, the model and its linearisation (:meth:`linearise`).
    ``blocks``: the configured effects (:class:`~..effects.base.EffectBlock`,
    the case's springs first when they are estimated) and ``slices`` their
    parameters.  ``cache`` (the engine's one value-keyed cache) holds the
    linearisations, the lines at each EI, the interpolation maps, the bin
    layouts and the grams; :meth:`clear_cache` empties it.
    """

    def __init__(self, case, crossings, effects, prior, *, masks=None, estimate_springs=True):
        # entries of the one cache: an evaluation writes at most (axles + 8) per crossing (lines, slopes, axle
        # responses, lines at shifted sensors, interpolants, maps, layouts, grams) and a few more; it holds
        # four evaluations, so that nothing an evaluation wrote is dropped before the evaluation ends
        self.cache_size = 4 * (len(crossings) * (case.vehicle.n_axles + 8) + 16)
        super().__init__(case, crossings, masks=masks)
        self.prior = prior
        self.n_sensors = self.sensors.n_sensors
        for c, m in zip(crossings, self.masks):  # bins in time: their maps marginalise the offsets (binning.py)
            if getattr(c, "n_offsets", 0) and m.any():
                self.n_data -= c.n_offsets
                self.log_det_noise += c.offset_log_det
        self.sensor_names = self.sensors.names
        self.n_crossings = len(crossings)
        self.labels = crossings.labels
        self.n_elements = case.mesh.n_elements
        self._set_rows(crossings)
        self.blocks = self._configure(list(effects), estimate_springs)
        # loads moved by an effect enter the bridge over a short ramp (see entry.py); else as point loads
        self.entry_moves = any(b.effect.moves_loads for b in self.blocks)
        self.entry = ENTRY if self.entry_moves else 0.0
        self.axle_responses = any(b.effect.needs_axle_lines for b in self.blocks)
        self.log_prior_constant = float(sum(b.log_prior_constant for b in self.blocks))
        self._set_layout()
        self._set_prior(case, prior)
        # the crossings whose fitted rows are the same (whitened together; their Jacobians may share J^T J)
        self.row_keys = [value_key(c.positions[m], m, c.times) for c, m in zip(crossings, self.masks)]
        self.row_groups = {}
        for c, m in enumerate(self.masks):
            if m.any():
                self.row_groups.setdefault(self.row_keys[c], []).append(c)
        self.current_ei = None
        self.ei_key = None  # value key of the current log EI: part of the key of everything computed at it
        self.n_evaluations = 0

    def _set_rows(self, crossings):
        """Where the model is evaluated, the binned crossings and their bin maps, the noise scales of the readings."""
        # binned crossings (binning.py): the model is evaluated at the readings and mapped onto the whitened bins
        self.binned = [c if hasattr(c, "to_bins") else None for c in crossings]
        groups = {}  # the binned crossings with one bin map (their model is mapped in one product)
        for c, binned in enumerate(self.binned):
            if binned is not None:
                groups.setdefault(binned.map_key, []).append(c)
        self.map_groups = list(groups.values())
        rows = [model_rows(c) for c in crossings]
        self.model_positions = [x for x, _ in rows]
        self.load_factors = [lf for _, lf in rows]
        # the readings' noise std in the sensors' units (held-out rms are reported in them)
        binned = next((c for c in self.binned if c is not None), None)
        self.sensor_std = self.noise.std if binned is None else binned.noise.std
        self.unit_noise = bool(self.noise.correlation_length < 1e-12 and np.all(self.noise.std == 1.0))
        self.bin_size = 1 if binned is None else binned.size  # readings per fitted row
        values = [getattr(c, "raw_values", c.values) for c in crossings]
        peak = np.array([max(float(np.max(np.abs(v[i]))) for v in values) for i in range(self.n_sensors)])
        self.offset_scale = np.maximum(0.2 * peak, 3.0 * self.sensor_std)

    def _configure(self, effects, estimate_springs):
        """The effects' blocks, after the case's springs (those no effect frees) when they are estimated."""
        if estimate_springs:
            freed = {k for e in effects for k in e.frees}
            springs = CaseSprings(freed)
            if springs.configure(self).n_params:
                effects.insert(0, springs)
        return [e.configure(self) for e in effects]

    def _set_layout(self):
        """Parameter slices of the blocks, the order of their outputs, and each crossing's columns."""
        self.slices = []
        start = self.n_elements
        for b in self.blocks:
            self.slices.append(slice(start, start + b.n_params))
            start += b.n_params
        self.n_params = start
        # outputs that scale the response act first, then the additive ones (whatever order they were selected in)
        self.outputs = sorted([(b, sl) for b, sl in zip(self.blocks, self.slices) if b.effect.output_order()],
                              key=lambda item: item[0].effect.output_order())
        # per crossing: the parameters that can act on it (log EI and each effect's columns(c)), and where each
        # effect's block sits among them; a crossing's Jacobian is formed on these columns only
        self.columns, self.places = [], []
        for c in range(self.n_crossings):
            cols, places, at = [np.arange(self.n_elements)], {}, self.n_elements
            for b, sl in zip(self.blocks, self.slices):
                local = b.effect.columns(b, self, c)
                local = np.arange(b.n_params) if local is None else np.asarray(local)
                cols.append(sl.start + local)
                places[b.name] = slice(at - self.n_elements, at - self.n_elements + local.size)
                at += local.size
            self.columns.append(np.concatenate(cols))
            self.places.append(places)

    def _set_prior(self, case, prior):
        """The prior mean ``theta0``, the rough (GMRF) and fixed precisions, the parameters' names."""
        self.theta0 = np.concatenate([np.log(case.ei)] + [b.mean for b in self.blocks])
        self.param_names = [f"log_ei_{j}" for j in range(self.n_elements)] + [
            f"{b.name}:{n}" for b in self.blocks for n in b.names]
        self.rough = np.zeros((self.n_params, self.n_params))
        self.rough[:self.n_elements, :self.n_elements] = prior.structure(self.n_elements)
        # log EI: the elements' marginal prior and the overall level (GMRFPrior.ei_fixed_precision); effects: diagonal
        diag = np.concatenate([np.zeros(self.n_elements)] + [1.0 / b.std**2 for b in self.blocks])
        self.fixed = np.diag(diag)
        self.fixed[:self.n_elements, :self.n_elements] = prior.ei_fixed_precision(self.n_elements)

    def block(self, name):
        """The block and parameter slice of effect ``name``."""
        for b, sl in zip(self.blocks, self.slices):
            if b.name == name:
                return b, sl
        raise KeyError(name)

    # -- what the effects use (EffectContext) -------------------------------------------------
    def load_factor(self, c):
        return self.load_factors[c]

    def to_bins(self, c, y):
        """Model ``y`` of crossing ``c`` at its readings as it enters the fit (whitened bins if binned)."""
        return y if self.binned[c] is None else self.binned[c].to_bins(y)

    # -- evaluation ------------------------------------------------------------------------
    def initial_state(self):
        """The case's model state before any effect acts."""
        return State(self.case.bridge, self.sensors.positions.copy(), [x.copy() for x in self.model_positions],
                     np.ones(self.case.vehicle.n_axles), np.zeros(self.n_crossings))

    def state_at(self, theta):
        """The model state at ``theta``: every block applied in order (output effects leave it as it is)."""
        state = self.initial_state()
        for b, sl in zip(self.blocks, self.slices):
            b.effect.apply(b, state, theta[sl])
        return state

    def predict(self, theta, *, jacobian=True):
        """Unwhitened predictions and Jacobians per crossing: list of (y (S,K), J (S,K,P) or None)."""
        out = []
        for c, (y, jac) in enumerate(self.predict_columns(theta, jacobian=jacobian)):
            if jac is not None:
                full = np.zeros(y.shape + (self.n_params,))
                full[:, :, self.columns[c]] = jac
                jac = full
            out.append((y, jac))
        return out

    def predict_columns(self, theta, *, jacobian=True):
        """As :meth:`predict`, each crossing's Jacobian on its own columns only (``self.columns[c]``)."""
        return [(y, jac) for y, jac, _ in self._assemble(theta, jacobian, factored=False)]

    def _assemble(self, theta, jacobian, factored):
        """Per crossing (y, Jacobian on its columns, None), or with ``factored`` (y, effects' columns, log-EI factor)."""
        self.ei_key = value_key(theta[:self.n_elements])
        self.current_ei = np.exp(theta[:self.n_elements])
        self.n_evaluations += 1
        return assemble(self, theta, jacobian, factored)

    def predicted(self, theta, jacobian, factored=False):
        """:meth:`_assemble`, or None out of the model's domain (non-finite, EI beyond e^60, unstable springs)."""
        if not np.all(np.isfinite(theta)) or np.any(np.abs(theta[:self.n_elements]) > 60):
            return None
        try:
            return self._assemble(theta, jacobian, factored)
        except ConfigError:  # an effect drove the model out of its domain (e.g. unstable springs)
            return None

    def in_domain(self, theta):
        """Whether the model can be evaluated at ``theta``."""
        return self.predicted(theta, False) is not None

    def linearise(self, theta, *, jacobian=True):
        """Residual sum of squares, J^T J and J^T r of the whitened problem at ``theta`` (None: out of domain).

        Called by the engine's cached :meth:`evaluate`.  A crossing's
        Jacobian is zero in the columns of the other crossings' own
        parameters (offsets, drift, shifts, amplification): it is formed,
        whitened and multiplied on its own columns only (``self.columns``).
        When every crossing is binned (one map for all its sensors) the log-EI blocks are never formed:
        their share of J^T J and J^T r comes from the factors (:mod:`.factored`).
        """
        factored = jacobian and all(b is not None and b.shared for b in self.binned)
        preds = self.predicted(theta, jacobian, factored)
        if preds is None:
            return None
        white = self._whitened_predictions(preds)
        equations = NormalEquations(self.n_params, jacobian=jacobian)
        shared = {}  # crossings with the same rows and Jacobian share J^T J (the base model, output-free effects)
        terms = []  # the factored crossings' (factor, mask, residuals, effects' columns, their columns)
        for c, (y, jac, factor) in enumerate(preds):
            m = self.masks[c]
            if not m.any():
                continue
            r = (self.white_data[c] - white[c]).ravel()
            if jacobian:
                self._add_crossing(equations, c, r, jac, factor, shared, terms)
            else:
                equations.add_residual(r)
        if terms:
            add_factored_terms(terms, equations.jtj, equations.jtr, self.cache)
        return equations.linearisation()

    def _whitened_predictions(self, preds):
        """The whitened predictions of every crossing with rows (those with the same rows whitened together)."""
        white = {}
        for members in self.row_groups.values():
            m, first = self.masks[members[0]], self.crossings[members[0]]
            stacked = self.noise.whiten(np.stack([preds[c][0][:, m] for c in members]), first.positions[m],
                                        sensor_axis=1, times=rows_of(first.times, m))
            white.update(zip(members, stacked))
        return white

    def _add_crossing(self, equations, c, r, jac, factor, shared, terms):
        """Add crossing ``c``'s share (its whitened residuals ``r``) to the normal equations, on its own columns."""
        m = self.masks[c]
        x, t = self.crossings[c].positions[m], rows_of(self.crossings[c].times, m)
        cols = self.columns[c]
        if factor is not None:
            cols = cols[self.n_elements:]
        key = self.row_keys[c]
        hit = shared.get(key)
        if hit is not None and np.array_equal(hit[0], cols) and np.array_equal(hit[1], jac):
            wj, block = hit[2], hit[3]
        else:
            # whitened bins (binning.py) are their own whitened rows: no copy of the Jacobian
            wj = ((jac if m.all() else jac[:, m]) if self.unit_noise
                  else self.noise.whiten(jac[:, m], x, times=t)).reshape(r.size, cols.size)
            block = wj.T @ wj
            shared[key] = (cols, jac, wj, block)
        equations.add_residual(r, wj, columns=cols)
        equations.add_gram(block, columns=cols)
        if factor is not None:
            terms.append((factor, m, r, jac, cols))

    def rows(self, theta):
        """Whitened residuals (N,), Jacobian (N, P), and the crossing, load index and sensor of each row.

        Whitening is along the load positions of each sensor in each crossing
        (AR(1): a row depends on its predecessor); the whitened rows are
        independent standard normals under the model, so any partition of them
        is a valid split into training and held-out data.
        """
        preds = self.predict(theta)
        res, jacs, cross, load, sensor = [], [], [], [], []
        for c, (y, jac) in enumerate(preds):
            x, t = self.crossings[c].positions, self.crossings[c].times
            s, k = y.shape
            res.append((self.noise.whiten(self.crossings[c].values, x, times=t) - self.noise.whiten(y, x, times=t)).ravel())
            jacs.append(self.noise.whiten(jac, x, times=t).reshape(-1, self.n_params))
            cross.append(np.full(s * k, c))
            load.append(np.tile(np.arange(k), s))
            sensor.append(np.repeat(np.arange(s), k))
        return (np.concatenate(res), np.concatenate(jacs), np.concatenate(cross), np.concatenate(load),
                np.concatenate(sensor))

    def residuals(self, theta):
        """Unwhitened residuals per crossing (S, K)."""
        return [c.values - y for c, (y, _) in zip(self.crossings, self.predict(theta, jacobian=False))]
