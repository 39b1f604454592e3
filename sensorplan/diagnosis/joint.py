"""The base model extended by candidate effects, as a problem for the inversion engine.

Parameters: log EI per element of the case's mesh, the elastic springs of
the case (log stiffness, as ``invert`` estimates them by default; only the
kinds no effect frees), then one block per effect.  Prior: the GMRF on log
EI (rough part scaled by tau), the spring prior of ``GMRFPrior`` and the
effects' own independent Gaussian priors (fixed part).  ``masks`` select
which rows (load positions) of each crossing enter the likelihood.

:meth:`JointProblem.rows` gives the whitened residuals and Jacobian row by
row (with the crossing and load index of each row), from which the
held-out folds are scored by exact rank updates of the linearised problem.
Binned crossings (``binning.py``: dense records) are modelled at their
readings and mapped onto their whitened bins; the bins are then the rows.
"""

from collections import OrderedDict
import numpy as np

from .._errors import ConfigError
from ..inference.laplace import Linearisation, WhitenedData
from .binning import model_rows
from ._base import Outer
from .effects import CaseSprings, State
from .factored import add_factored_terms, log_ei_factors
from .lines import LineSource, log_ei_blocks

__all__ = []

ENTRY = 0.1  # m over which an axle moved by an effect rolls onto the bridge (half a tyre contact length)


def _shifted(place, start):
    """The slice ``place`` moved ``start`` columns to the left."""
    return slice(place.start - start, place.stop - start)


def _put(extra, place, block, add=False):
    """Write (or with ``add`` add) an effect's ``block`` into the columns ``place`` (a slice) of ``extra`` (S, K, m).

    An array is written as it is; a :class:`~._base.PerSensor`,
    :class:`~._base.Outer` or :class:`~._base.Columns` block writes itself
    (only the columns it acts on, without forming the block).
    """
    target = extra[:, :, place]
    if isinstance(block, np.ndarray):
        if add:
            target += block
        else:
            target[...] = block
    else:
        block.write(target, add)


class JointProblem(WhitenedData, LineSource):
    """The case's model extended by ``effects``, fitted jointly with log EI (rows in ``masks``)."""

    def __init__(self, case, crossings, effects, prior, *, masks=None, estimate_springs=True):
        super().__init__(case, crossings, masks=masks)
        self.prior = prior
        self.n_sensors = self.sensors.n_sensors
        self.sensor_names = self.sensors.names
        self.n_crossings = len(crossings)
        self.labels = crossings.labels
        # binned crossings (binning.py): the model is evaluated at the readings and mapped onto the whitened bins
        self._binned = [c if hasattr(c, "to_bins") else None for c in crossings]
        groups = {}  # the binned crossings with one bin map (their model is mapped in one product)
        for c, binned in enumerate(self._binned):
            if binned is not None:
                groups.setdefault(binned.map_key, []).append(c)
        self._map_groups = list(groups.values())
        rows = [model_rows(c) for c in crossings]
        self.model_positions = [x for x, _ in rows]
        self._load_factors = [lf for _, lf in rows]
        # the readings' noise std in the sensors' units (held-out rms are reported in them)
        binned = next((c for c in self._binned if c is not None), None)
        self.sensor_std = self.noise.std if binned is None else binned.noise.std
        self._unit_noise = bool(self.noise.correlation_length < 1e-12 and np.all(self.noise.std == 1.0))
        self.bin_size = 1 if binned is None else binned.size  # readings per fitted row
        values = [getattr(c, "raw_values", c.values) for c in crossings]
        peak = np.array([max(float(np.max(np.abs(v[i]))) for v in values) for i in range(self.n_sensors)])
        self.offset_scale = np.maximum(0.2 * peak, 3.0 * self.sensor_std)
        effects = list(effects)
        if estimate_springs:
            freed = {k for e in effects for k in getattr(e, "frees", ())}
            springs = CaseSprings(freed)
            if springs.configure(self).n_params:
                effects.insert(0, springs)
        self.effects = [e.configure(self) for e in effects]
        # loads moved by an effect enter the bridge over a short ramp (see _entry); else as point loads
        self.entry_moves = any(e.moves_loads for e in self.effects)
        self.entry = ENTRY if self.entry_moves else 0.0
        self.axle_responses = any(e.needs_axle_lines for e in self.effects)
        self.log_prior_constant = float(sum(e.log_prior_constant for e in self.effects))
        self.n_elements = case.mesh.n_elements
        self.slices = []
        start = self.n_elements
        for e in self.effects:
            self.slices.append(slice(start, start + e.n_params))
            start += e.n_params
        self.n_params = start
        # output effects: gains and amplifications act on the response, then offsets and drift are added in the
        # sensor's output, whatever order the effects were selected in (a gain applied after a drift scaled the
        # drift too, and was chosen for shrinking the drift's prior cost: a false second cause)
        self._outputs = sorted([(e, sl) for e, sl in zip(self.effects, self.slices) if not e.structural],
                               key=lambda item: item[0].additive)
        # per crossing: the parameters that can act on it (log EI and each effect's columns(c)), and where each
        # effect's block sits among them; a crossing's Jacobian is formed on these columns only
        self.columns, self._places = [], []
        for c in range(self.n_crossings):
            cols, places, at = [np.arange(self.n_elements)], {}, self.n_elements
            for e, sl in zip(self.effects, self.slices):
                local = e.columns(self, c)
                local = np.arange(e.n_params) if local is None else np.asarray(local)
                cols.append(sl.start + local)
                places[e.name] = slice(at, at + local.size)
                at += local.size
            self.columns.append(np.concatenate(cols))
            self._places.append(places)
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
        self._cache_ei = None
        self._weight_maps = OrderedDict()  # interpolation maps of the load positions (independent of EI)
        self._bin_layouts = {}  # the bin maps of the crossings side by side, per layout of their rows (lines.py)
        self._grams = OrderedDict()  # R^T diag(w) R of the mapped weights (factored.py)
        self._last = None
        self.n_evaluations = 0

    def block(self, name):
        """The effect object and parameter slice of effect ``name``."""
        for e, sl in zip(self.effects, self.slices):
            if e.name == name:
                return e, sl
        raise KeyError(name)

    # -- context used by the effects -----------------------------------------------------
    def load_factor(self, c):
        return self._load_factors[c]

    def to_bins(self, c, y):
        """Model ``y`` of crossing ``c`` at its readings as it enters the fit (whitened bins if binned)."""
        return y if self._binned[c] is None else self._binned[c].to_bins(y)

    # -- evaluation ------------------------------------------------------------------------
    def initial_state(self):
        """The case's model state before any effect acts."""
        return State(self.case.bridge, self.sensors.positions.copy(), [x.copy() for x in self.model_positions],
                     np.ones(self.case.vehicle.n_axles), np.zeros(self.n_crossings))

    def drop_caches(self):
        """Forget the kept lines, interpolation maps, grams and last evaluation (they are rebuilt on demand)."""
        self._cache, self._weight_maps, self._grams, self._last = {}, OrderedDict(), OrderedDict(), None

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
        """Per crossing (y, Jacobian on its columns, None), or with ``factored`` (y, effects' columns, log-EI factor).

        ``factored`` (every crossing binned): the log-EI block stays a
        :class:`~.factored.LogEIFactor` and the Jacobian holds the effects'
        columns only (``self.columns[c][n_elements:]``).
        """
        # the lines depend on EI and on the state (positions, springs, loads: in the cache keys); kept while EI
        # is unchanged, so that the Jacobian at an accepted trial point reuses the trial's forward solve
        ei_key = theta[:self.n_elements].tobytes()
        if ei_key != self._cache_ei or len(self._cache) > 256:
            self._cache, self._cache_ei = {}, ei_key
        self._ei = np.exp(theta[:self.n_elements])
        self.n_evaluations += 1
        state = self.initial_state()
        for e, sl in zip(self.effects, self.slices):
            if e.structural:
                e.apply(state, theta[sl])
        self.prefetch(state, jacobian)
        every = [self.lines(state, c) for c in range(self.n_crossings)]
        # the log-EI block of every crossing, mapped onto the bins together (crossings at the same positions
        # share it; binning.py; gains, amplifications and the map act on it linearly, in any order)
        log_ei = None
        if jacobian:
            items = [(lines, self.load_factor(c), self._binned[c]) for c, lines in enumerate(every)]
            log_ei = (log_ei_factors if factored else log_ei_blocks)(items, self._bin_layouts)
        n_el = self.n_elements
        # every crossing's predictions and effects' columns at the readings, written straight into the array
        # that its bin map acts on (readings first: one sparse product per map, without copies)
        buffers, views = self._buffers(jacobian)
        scaled_blocks = []
        on_bins = [[] for _ in every]  # per crossing: (place, Outer) written on the bins, after the map
        for c, lines in enumerate(every):
            lf = self.load_factor(c)
            y = lines.predictions * lf[None, :]
            extra = block = None  # the effects' columns at the readings; the mapped log-EI block and its factor
            places = self._places[c]
            if jacobian:
                block, scale = log_ei[c], 1.0
                extra = views[c][:, :, 1:]  # zeros
                for e, sl in zip(self.effects, self.slices):
                    if e.structural:
                        cols = e.structural_jacobian(self, state, theta[sl], c, y)
                        place = _shifted(places[e.name], n_el)
                        if isinstance(cols, Outer) and self._binned[c] is not None:
                            # a sensor factor times a reading factor: the bin map acts on the reading factor
                            # alone (spring columns: bins x springs instead of readings x sensors x springs)
                            on_bins[c].append((place, cols))
                        else:
                            _put(extra, place, cols)
            for e, sl in self._outputs:
                y, out_block, mult = e.output(self, state, theta[sl], c, y)
                if extra is not None:
                    if np.ndim(mult) or mult != 1.0:  # offsets and drift multiply nothing
                        mult = np.reshape(mult, (-1, 1, 1)) if np.ndim(mult) else mult
                        extra *= mult
                        scale = scale * mult
                    _put(extra, _shifted(places[e.name], n_el), out_block, add=True)
            views[c][:, :, 0] = y
            scaled_blocks.append(None if block is None else (block, scale))
        mapped = self._map_rows(buffers, views)
        out = []
        for c, (rows, scaled) in enumerate(zip(mapped, scaled_blocks)):
            y = rows[:, :, 0]
            jac = factor = None
            if scaled is not None:
                block, scale = scaled
                for place, cols in on_bins[c]:  # times the outputs' factors, as the columns at the readings are
                    sensors, loads = self._binned[c].outer_to_bins(cols.sensors, cols.loads)
                    Outer(sensors * np.reshape(scale, (-1, 1)), loads).write(rows[:, :, 1:][:, :, place], False)
                if factored:
                    jac, factor = rows[:, :, 1:], block
                    factor.scale = factor.scale * np.ravel(scale)
                else:
                    jac = np.empty(block.shape[:2] + (self.columns[c].size,))
                    np.multiply(block, scale, out=jac[:, :, :n_el])
                    jac[:, :, n_el:] = rows[:, :, 1:]
            out.append((y, jac, factor))
        return out

    def _buffers(self, jacobian):
        """Arrays (readings, S, columns) of each bin map's crossings side by side, and each crossing's view.

        A crossing's view is (S, readings, 1 + its effects' columns with
        ``jacobian``): predictions first; all zeros.  Crossings fitted row by
        row get an array of their own.
        """
        widths = [1 + (self.columns[c].size - self.n_elements if jacobian else 0) for c in range(self.n_crossings)]
        buffers, views = [], [None] * self.n_crossings
        for members in self._map_groups:
            n_readings = self.model_positions[members[0]].size
            buffer = np.zeros((n_readings, self.n_sensors, sum(widths[c] for c in members)))
            start = 0
            for c in members:
                views[c] = buffer[:, :, start:start + widths[c]].transpose(1, 0, 2)
                start += widths[c]
            buffers.append(buffer)
        for c in range(self.n_crossings):
            if views[c] is None:
                views[c] = np.zeros((self.n_sensors, self.model_positions[c].size, widths[c]))
        return buffers, views

    def _map_rows(self, buffers, views):
        """The crossings' ``views`` on the fitted rows: the bins of each buffer in one product (``_buffers``)."""
        out = list(views)
        for members, buffer in zip(self._map_groups, buffers):
            rows = self._binned[members[0]].to_bins_first(buffer)  # (bins, S, columns)
            start = 0
            for c in members:
                width = views[c].shape[2]
                out[c] = rows[:, :, start:start + width].transpose(1, 0, 2)
                start += width
        return out

    def _safe_predict(self, theta, jacobian, factored=False):
        if not np.all(np.isfinite(theta)) or np.any(np.abs(theta[:self.n_elements]) > 60):
            return None
        try:
            return self._assemble(theta, jacobian, factored)
        except ConfigError:  # an effect drove the model out of its domain (e.g. unstable springs)
            return None

    def evaluate(self, theta, *, jacobian=True):
        """Residual sum of squares, J^T J and J^T r of the whitened problem at ``theta`` (None: out of domain).

        A crossing's Jacobian is zero in the columns of the other crossings'
        own parameters (offsets, drift, shifts, amplification): it is formed,
        whitened and multiplied on its own columns only (``self.columns``; with
        per-crossing drift on six sensors and ten crossings a tenth of the
        drift columns).  When every crossing is binned the log-EI blocks are
        never formed: their share of J^T J and J^T r comes from the factors
        (:mod:`.factored`).
        """
        theta_key = theta.tobytes()
        if (self._last is not None and self._last[0] == theta_key
                and (self._last[1].jtj is not None or not jacobian)):
            return self._last[1]
        factored = jacobian and all(b is not None for b in self._binned)
        preds = self._safe_predict(theta, jacobian, factored)
        if preds is None:
            return None
        rr = 0.0
        jtj = np.zeros((self.n_params, self.n_params)) if jacobian else None
        jtr = np.zeros(self.n_params) if jacobian else None
        # the predictions of crossings with the same rows are whitened together (one call instead of one each)
        groups = {}
        for c in range(len(preds)):
            m = self.masks[c]
            if m.any():
                groups.setdefault(self.crossings[c].positions[m].tobytes() + m.tobytes(), []).append(c)
        white = {}
        for members in groups.values():
            m = self.masks[members[0]]
            stacked = self.noise.whiten(np.stack([preds[c][0][:, m] for c in members]),
                                        self.crossings[members[0]].positions[m], sensor_axis=1)
            white.update(zip(members, stacked))
        shared = {}  # crossings with the same rows and Jacobian share J^T J (the base model, output-free effects)
        terms = []  # the factored crossings' (factor, mask, residuals, effects' columns, their columns)
        for c, (y, jac, factor) in enumerate(preds):
            m = self.masks[c]
            if not m.any():
                continue
            x = self.crossings[c].positions[m]
            r = (self.white_data[c] - white[c]).ravel()
            rr += float(r @ r)
            if not jacobian:
                continue
            cols = self.columns[c]
            if factor is not None:
                cols = cols[self.n_elements:]
            key = x.tobytes() + m.tobytes()
            hit = shared.get(key)
            if hit is not None and np.array_equal(hit[0], cols) and np.array_equal(hit[1], jac):
                wj, block = hit[2], hit[3]
            else:
                # whitened bins (binning.py) are their own whitened rows: no copy of the Jacobian
                wj = ((jac if m.all() else jac[:, m]) if self._unit_noise
                      else self.noise.whiten(jac[:, m], x)).reshape(r.size, cols.size)
                block = wj.T @ wj
                shared[key] = (cols, jac, wj, block)
            jtj[np.ix_(cols, cols)] += block
            jtr[cols] += wj.T @ r
            if factor is not None:
                terms.append((factor, m, r, jac, cols))
        if terms:
            add_factored_terms(terms, jtj, jtr, self._grams)
        out = Linearisation(rr, jtj, jtr)
        self._last = (theta_key, out)
        return out

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
            x = self.crossings[c].positions
            s, k = y.shape
            res.append((self.noise.whiten(self.crossings[c].values, x) - self.noise.whiten(y, x)).ravel())
            jacs.append(self.noise.whiten(jac, x).reshape(-1, self.n_params))
            cross.append(np.full(s * k, c))
            load.append(np.tile(np.arange(k), s))
            sensor.append(np.repeat(np.arange(s), k))
        return (np.concatenate(res), np.concatenate(jacs), np.concatenate(cross), np.concatenate(load),
                np.concatenate(sensor))

    def residuals(self, theta):
        """Unwhitened residuals per crossing (S, K)."""
        return [c.values - y for c, (y, _) in zip(self.crossings, self.predict(theta, jacobian=False))]
