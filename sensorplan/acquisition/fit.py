"""Entry time and constant speed of a crossing by fitting the model's influence lines.

A vehicle entering at ``t0`` with speed ``v`` has its reference axle at
``z = v (t - t0)``; channel ``c`` reads ``IL_c(z) + a_c + b_c (t - t_m)``.
The offsets and slow drift ``a_c, b_c`` enter linearly and are projected
out (variable projection, Golub & Pereyra 1973), so they are fitted by the
quiet samples around the vehicle, where the influence lines are zero.  The
nonlinear part is started on a grid of speeds and entry times and refined
by ``scipy.optimize.least_squares``.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["Template", "VehicleFit", "fit_vehicles"]


@dataclass(frozen=True, eq=False)
class Template:
    """Influence lines of the logged channels on a fine grid of reference-axle positions.

    Attributes
    ----------
    positions : ndarray (n_grid,)
        Reference-axle positions [m] from 0 to ``length``.
    lines : ndarray (n_channels, n_grid)
        Readings [rad or m]; zero outside the grid (no axle on the bridge).
    length : float
        Bridge length plus vehicle length [m]: the distance the reference
        axle travels while an axle is on the bridge.
    """

    positions: np.ndarray
    lines: np.ndarray
    length: float

    @classmethod
    def from_case(cls, case, names, *, step=None):
        """Template of the sensors ``names`` of ``case`` (default step: length / 2000, at most 0.02 m)."""
        sensors = case.sensors.subset([case.sensors.names.index(n) for n in names])
        length = case.bridge.length + case.vehicle.length
        step = min(0.02, length / 2000.0) if step is None else step
        positions = np.linspace(0.0, length, int(np.ceil(length / step)) + 1)
        lines = case.influence_lines(sensors=sensors, positions=positions).predictions
        return cls(positions, np.array(lines), float(length))

    def predict(self, z):
        """Readings at reference-axle positions ``z`` (any shape): shape (n_channels, *z.shape)."""
        return np.stack([np.interp(z, self.positions, line, left=0.0, right=0.0) for line in self.lines])


@dataclass(frozen=True, eq=False, kw_only=True)
class VehicleFit:
    """Least-squares fit of one or more vehicles to a window of the record.

    Attributes
    ----------
    entry_times, speeds : ndarray (n_vehicles,)
        [s] and [m/s].
    speed_ci95 : ndarray (n_vehicles,)
        Half-width of the 95 % confidence interval of each speed [m/s].
    entry_ci95 : ndarray (n_vehicles,)
        The same for the entry times [s].
    rms : float
        Root mean square of the residuals in noise standard deviations (1 = noise level).
    model : ndarray (n_channels, n_samples)
        Fitted readings including the offset lines [rad or m].
    offsets : ndarray (n_channels, n_samples)
        The fitted offset lines alone [rad or m].
    """

    entry_times: np.ndarray
    speeds: np.ndarray
    speed_ci95: np.ndarray
    entry_ci95: np.ndarray
    rms: float
    model: np.ndarray
    offsets: np.ndarray


class _Problem:
    """Residuals of a window with the offset lines projected out."""

    def __init__(self, template, time, values, noise_std):
        self.template, self.time = template, time
        self.scale = 1.0 / np.asarray(noise_std, dtype=float)[:, None]
        span = max(time[-1] - time[0], 1e-9)
        basis = np.column_stack([np.ones_like(time), (time - time.mean()) / span])
        self.q = np.linalg.qr(basis)[0]
        self.data = self.project(values * self.scale)
        self.stride = max(1, time.size // 400)  # the grid search looks at <= 800 samples per channel
        self.q_grid = np.linalg.qr(basis[::self.stride])[0]

    def project(self, x):
        """``x`` without its offset lines (the projection on the complement of the offset basis)."""
        return x - (x @ self.q) @ self.q.T

    def signal(self, params):
        entry, speed = params[0::2], params[1::2]
        total = 0.0
        for t0, v in zip(entry, speed):
            total = total + self.template.predict(v * (self.time - t0))
        return total

    def residual(self, params):
        return (self.data - self.project(self.signal(params) * self.scale)).ravel()

    def grid_costs(self, data, speeds, entries):
        """Cost of one vehicle at every (speed, entry time) of the grid against ``data``."""
        best = (np.inf, None)
        time, q = self.time[::self.stride], self.q_grid
        data = data[:, ::self.stride]
        data = data - (data @ q) @ q.T
        for v in speeds:
            t0 = entries(v)
            pred = self.template.predict(v * (time[None, :] - t0[:, None])) * self.scale[:, :, None]
            pred = pred - (pred @ q) @ q.T
            cost = np.sum((data[:, None, :] - pred) ** 2, axis=(0, 2))
            k = int(np.argmin(cost))
            if cost[k] < best[0]:
                best = (float(cost[k]), (float(t0[k]), float(v)))
        return best


def _grid_speeds(speed_range, fixed_speed):
    if fixed_speed is not None:
        return np.array([float(fixed_speed)])
    lo, hi = speed_range
    return np.geomspace(lo, hi, int(np.ceil(np.log(hi / lo) / np.log(1.08))) + 1)


def fit_vehicles(template, time, values, noise_std, *, active, speed_range, n_vehicles=1, fixed_speed=None,
                 fixed_entry=None):
    """Fit ``n_vehicles`` vehicles (1 or 2) to ``values`` sampled at ``time``.

    Parameters
    ----------
    template : Template
    time : ndarray (n_samples,)
        [s]
    values : ndarray (n_channels, n_samples)
        [rad or m]
    noise_std : ndarray (n_channels,)
        Noise standard deviation per channel [rad or m].
    active : (float, float)
        Start and end of the detected activity [s]; the vehicle must be on the bridge in between.
    speed_range : (float, float)
        Plausible speeds [m/s]; the grid covers it, the refinement may leave it by a factor 2.
    fixed_speed, fixed_entry : float, optional
        Known speed [m/s] or entry time [s] (single vehicle only).
    """
    problem = _Problem(template, np.asarray(time, float), np.asarray(values, float), noise_std)
    x0 = _grid_start(problem, active=active, speeds=_grid_speeds(speed_range, fixed_speed), n_vehicles=n_vehicles,
                     fixed_entry=fixed_entry)
    free = np.ones(x0.size, bool)
    if fixed_entry is not None:
        free[0::2] = False
    if fixed_speed is not None:
        free[1::2] = False
    x, fun, jac = _refine(problem, x0, free, speed_range)
    dof = max(fun.size - 2 * problem.data.shape[0] - int(free.sum()), 1)
    chi2 = float(fun @ fun)
    ci = np.zeros(x.size)
    jtj = jac.T @ jac
    if np.all(np.isfinite(jtj)) and np.linalg.matrix_rank(jtj) == jtj.shape[0]:
        cov = np.linalg.inv(jtj) * max(1.0, chi2 / dof)
        ci[free] = 1.96 * np.sqrt(np.clip(np.diag(cov), 0.0, None))
    else:
        ci[free] = np.inf
    signal = problem.signal(x)
    raw = np.asarray(values, float) - signal
    offsets = (raw @ problem.q) @ problem.q.T
    return VehicleFit(entry_times=x[0::2], speeds=x[1::2], speed_ci95=ci[1::2], entry_ci95=ci[0::2],
                      rms=float(np.sqrt(chi2 / dof)), model=signal + offsets, offsets=offsets)


def _grid_start(problem, *, active, speeds, n_vehicles, fixed_entry):
    """(entry time, speed) of each vehicle from the grid, one vehicle at a time against what is left."""
    dt = float(np.median(np.diff(problem.time)))
    template = problem.template

    def entries(v):
        if fixed_entry is not None:
            return np.array([float(fixed_entry)])
        duration = template.length / v
        n = int(min(400, max(20, (active[1] - active[0] + duration) / dt)))
        return np.linspace(active[0] - duration, active[1], n)

    params = []
    data = problem.data
    for _ in range(n_vehicles):
        _, start = problem.grid_costs(data, speeds, entries)
        params.extend(start)
        data = problem.data - problem.project(problem.signal(np.array(params)) * problem.scale)
    return np.array(params)


def _refine(problem, x0, free, speed_range):
    """Least-squares refinement of the free parameters from ``x0``; returns (x, residual, Jacobian)."""
    from scipy.optimize import least_squares

    lo_v, hi_v = speed_range[0] / 2.0, speed_range[1] * 2.0
    lower = np.where(np.arange(x0.size) % 2 == 0, -np.inf, lo_v)[free]
    upper = np.where(np.arange(x0.size) % 2 == 0, np.inf, hi_v)[free]
    x0[1::2] = np.clip(x0[1::2], lo_v * 1.001, hi_v * 0.999)

    def residual(p):
        full = x0.copy()
        full[free] = p
        return problem.residual(full)

    x = x0.copy()
    if not free.any():
        return x, problem.residual(x), np.zeros((problem.data.size, 0))
    sol = least_squares(residual, x0[free], bounds=(lower, upper),
                        x_scale=np.maximum(np.abs(x0[free]), 1.0), diff_step=1e-7)
    x[free] = sol.x
    return x, sol.fun, sol.jac
