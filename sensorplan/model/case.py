"""A case: the bridge, its EI mesh and nominal EI, the vehicle, sensors, noise and sweep."""

from dataclasses import dataclass, replace

import numpy as np

from .forward import expand_ei, influence_lines
from .loads import LoadSweep, Vehicle
from .noise import NoiseModel
from .sensors import SensorLayout
from .structure import Bridge, Mesh

__all__ = ["Case", "NOISE_STD_RANGE"]

# Physical range of a sensor's noise std [rad or m]: below it the Fisher
# information overflows the algebra (and no instrument is that quiet), above
# it the value is a unit slip (mm/m or micro-radians given as rad, mm as m).
NOISE_STD_RANGE = {"rotation": (1e-10, 1e-3), "deflection": (1e-9, 5e-3)}
MAX_BYTES = 2 * 2**30  # memory budget of the influence lines of one case
NOISE_STD_HINT = {"rotation": "Give it in rad (1 mm/m = 1e-3 rad, 1 micro-radian = 1e-6 rad).",
                  "deflection": "Give it in m (1 mm = 1e-3 m)."}


@dataclass(frozen=True, eq=False)
class Case:
    """Everything needed to predict what the sensors see.

    Parameters
    ----------
    bridge : Bridge
    mesh : Mesh
    ei : array_like
        Nominal EI [N m^2]: scalar, one per span or one per element.
    vehicle : Vehicle
    sensors : SensorLayout
    noise : NoiseModel, optional
        Defaults to the sensors' ``noise_std`` with independent noise.
    sweep : LoadSweep, optional
        Defaults to moving the whole vehicle across in 0.25 m steps.
    name : str
    """

    bridge: Bridge
    mesh: Mesh
    ei: np.ndarray
    vehicle: Vehicle
    sensors: SensorLayout
    noise: NoiseModel | None = None
    sweep: LoadSweep = None  # type: ignore[assignment]  # None: filled in by __post_init__
    name: str = "case"

    def __post_init__(self):
        self.mesh.check_fits(self.bridge)
        self.bridge.check_on_bridge(self.sensors.positions, "positions", "SensorLayout")
        ei = expand_ei(self.bridge, self.mesh, self.ei)
        ei.setflags(write=False)
        object.__setattr__(self, "ei", ei)
        if self.noise is None and self.sensors.noise_std is not None:
            object.__setattr__(self, "noise", NoiseModel(self.sensors.noise_std))
        if self.noise is not None and self.noise.n_sensors != self.sensors.n_sensors:
            from .._errors import ConfigError

            raise ConfigError(
                f"The noise model has {self.noise.n_sensors} standard deviations for "
                f"{self.sensors.n_sensors} sensors.")
        if self.noise is not None and self.noise.in_time and self.noise.speed is None:
            from .._errors import ConfigError
            from .noise import NO_SPEED

            raise ConfigError(NO_SPEED)
        if self.sweep is None:
            object.__setattr__(self, "sweep", LoadSweep.covering(self.bridge, self.vehicle, 0.25))
        self._check_size()

    def _check_size(self):
        """Refuse a case whose influence lines would not fit in memory (estimated before allocating).

        The forward model holds about n_sensors + 12 arrays of n_loads x n_elements
        floats at its peak (measured with the openlab-like case).
        """
        from .._errors import ConfigError

        n_loads, n_elements, n_sensors = self.sweep.n_loads, self.mesh.n_elements, self.sensors.n_sensors
        needed = 8.0 * n_loads * n_elements * (n_sensors + 12)
        if needed > MAX_BYTES:
            raise ConfigError(
                f"The case needs about {needed / 2**30:.3g} GiB for its influence lines ({n_sensors} sensors x "
                f"{n_loads} load positions x {n_elements} elements), more than {MAX_BYTES / 2**30:g} GiB: use fewer "
                "elements ([bridge] elements, --elements), fewer load positions (a larger [loads] step) or fewer "
                "sensors/candidates (a larger --spacing).")

    @property
    def n_elements(self):
        return self.mesh.n_elements

    def with_mesh(self, mesh):
        """The same case on another EI mesh (nominal EI re-sampled at element midpoints)."""
        ei = self.ei_at(mesh.midpoints)
        return replace(self, mesh=mesh, ei=ei)

    def with_sensors(self, sensors, noise=None):
        """The same case with other sensors, and their noise by :meth:`noise_for` unless ``noise`` is given."""
        if noise is None:
            noise = self.noise_for(sensors)
        return replace(self, sensors=sensors, noise=noise)

    def noise_for(self, sensors):
        """The noise model of ``sensors`` under this case's noise: the one rule for sensors not in the case.

        The white std of each sensor is its ``noise_std`` if the layout has
        one, else :meth:`noise_std_for` its kind (the median of the case's
        sensors of that kind); the correlation (length, or time model with
        speed) is the case's (:meth:`NoiseModel.for_sensors`).  None when
        neither the sensors nor the case know a noise level.
        """
        if sensors is self.sensors and self.noise is not None:
            return self.noise
        if sensors.noise_std is not None:
            std = np.asarray(sensors.noise_std, dtype=float)
        elif self.noise is not None:
            std = np.array([self.noise_std_for(kind) for kind in sensors.kinds])
        else:
            return None
        if self.noise is None:
            return NoiseModel(std)
        return self.noise.for_sensors(self.sensors.kinds, sensors.kinds, std)

    @property
    def default_kind(self):
        """The kind of new sensors when none is given: the case's own kind, rotation if mixed."""
        kinds = set(self.sensors.kinds)
        return kinds.pop() if len(kinds) == 1 else "rotation"

    def noise_std_for(self, kind, noise_std=None):
        """Noise std of a new sensor of ``kind`` [rad or m].

        ``noise_std`` if given (checked positive), else the median noise of the
        case's sensors of the same kind; a ConfigError if there is none.
        """
        from .._errors import ConfigError

        unit = "rad" if kind == "rotation" else "m"
        if noise_std is not None:
            low, high = NOISE_STD_RANGE[kind]
            if not (np.isfinite(noise_std) and low <= noise_std <= high):
                raise ConfigError(f"The 'noise_std' (--noise-std) of new {kind} sensors must be from {low:g} to "
                                  f"{high:g} {unit}; got {noise_std!r}. {NOISE_STD_HINT[kind]}")
            return float(noise_std)
        same = ([s for k, s in zip(self.sensors.kinds, self.noise.std) if k == kind]
                if self.noise is not None else [])
        if not same:
            raise ConfigError(f"The case has no {kind} sensor to take the noise level from; give the noise std "
                              f"of the new sensors (--noise-std, in {unit}).")
        return float(np.median(same))

    def ei_at(self, x):
        """Nominal EI at positions ``x`` [m]."""
        return self.ei[self.mesh.element_of(x)]

    def influence_lines(self, ei=None, *, sensors=None, positions=None, bridge=None):
        """Influence lines of the case (any argument overrides the case's own)."""
        return influence_lines(
            self.bridge if bridge is None else bridge,
            self.mesh,
            self.ei if ei is None else ei,
            self.sensors if sensors is None else sensors,
            self.vehicle,
            self.sweep.positions if positions is None else positions,
        )
