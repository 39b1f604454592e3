"""Case configuration files (TOML) and the embedded examples.

Non-SI units are accepted only here, through keys with an explicit suffix,
and converted on entry: ``noise_std_mm_per_m`` and ``noise_std_urad`` for
tiltmeters, ``noise_std_mm`` for deflection sensors.
"""

import math
import os
import tomllib
from contextlib import contextmanager
from importlib import resources
from pathlib import Path

from .._errors import ConfigError
from ..model.case import NOISE_STD_RANGE, Case
from ..model.loads import LoadSweep, Vehicle
from ..model.noise import NoiseModel
from ..model.sensors import SensorLayout, check_file_name
from ..model.structure import Bridge, Mesh
from ..model.timeseries import LoggerFormat
from . import plausibility

__all__ = ["load_case", "case_from_dict", "example_case", "load_logger_format", "EXAMPLES"]

EXAMPLES = ("simply-supported", "openlab-like", "three-span")
MAX_SENSORS = 1_000  # as many as --positions takes; every analysis is linear in the sensor count at best

TIME_KEYS = ("correlated_std", "correlation_time_s", "random_walk", "speed", "sample_rate")
_KEYS = {
    "bridge": {"spans", "ei", "elements", "element_length", "rotational_springs",
               "vertical_springs"},
    "vehicle": {"axle_offsets", "axle_loads"},
    "sensors": {"names", "positions", "kinds", "noise_std", "noise_std_mm_per_m",
                "noise_std_urad", "noise_std_mm"},
    "loads": {"start", "stop", "step"},
    "noise": {"correlation_length", *TIME_KEYS},
    "case": {"name"},
    "logger": {"temperature_columns", "tilt_unit", "deflection_unit", "time_unit"},
}
_REQUIRED = {"bridge": {"spans", "ei"}, "vehicle": {"axle_offsets", "axle_loads"},
             "sensors": {"positions"}}
_TILT_UNITS = {"noise_std_mm_per_m": 1e-3, "noise_std_urad": 1e-6}
_DEFLECTION_UNITS = {"noise_std_mm": 1e-3}


def load_case(path: "str | os.PathLike[str]") -> Case:
    """Read a case from a TOML file.

    Errors name the file, the section and the field, in one line.
    """
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8-sig")  # a byte-order mark (Windows editors) is dropped
    except FileNotFoundError:
        raise ConfigError(f"{path}: file not found. Give the path of a TOML case file.") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the file ({exc}).") from None
    return case_from_toml(text, source=str(path), name=path.stem)


def case_from_toml(text, *, source="config", name="case"):
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML ({exc}).") from None
    return case_from_dict(data, source=source, name=name)


def example_case(name: str) -> Case:
    """One of the embedded examples: ``simply-supported``, ``openlab-like``, ``three-span``."""
    if name not in EXAMPLES:
        raise ConfigError(f"Unknown example {name!r}. Choose one of: {', '.join(EXAMPLES)}.")
    text = resources.files("sensorplan.examples").joinpath(f"{name}.toml").read_text("utf-8")
    return case_from_toml(text, source=f"example {name}", name=name)


def example_text(name):
    """The TOML text of an embedded example (to copy and edit)."""
    example_case(name)
    return resources.files("sensorplan.examples").joinpath(f"{name}.toml").read_text("utf-8")


def load_logger_format(path: "str | os.PathLike[str] | None") -> LoggerFormat:
    """The ``[logger]`` section of a case file (the defaults when ``path`` is None or has none)."""
    if path is None:
        return LoggerFormat()
    path = Path(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the case file ({exc}).") from None
    try:
        return _logger_format(data, str(path))
    except ConfigError as exc:
        raise ConfigError(f"{path}: [logger] {exc}") from None


def _logger_format(data, source):
    lg = _section(data, "logger", source)
    return LoggerFormat(lg.get("temperature_columns", ()), lg.get("tilt_unit", "rad"),
                        lg.get("deflection_unit", "m"), lg.get("time_unit"))


def _section(data, name, source):
    value = data.get(name, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{source}: [{name}] must be a table (a [{name}] section).")
    unknown = set(value) - _KEYS[name]
    if unknown:
        raise ConfigError(
            f"{source}: [{name}] has an unknown key {sorted(unknown)[0]!r}; "
            f"expected one of {', '.join(sorted(_KEYS[name]))}.")
    missing = _REQUIRED.get(name, set()) - set(value)
    if missing:
        raise ConfigError(f"{source}: [{name}] is missing the required key {sorted(missing)[0]!r}.")
    return value


def _inf(value):
    """TOML has inf; also accept the strings "inf" / "infinity"."""
    if isinstance(value, list):
        return [_inf(v) for v in value]
    if isinstance(value, str) and value.strip().lower() in {"inf", "infinity", "+inf"}:
        return math.inf
    return value


def case_from_dict(data, *, source="config", name="case"):
    """Build a :class:`Case` from a parsed TOML document.

    Each section is read by its own function; an error names the file and the section it arose in.
    """
    unknown = set(data) - set(_KEYS)
    if unknown:
        raise ConfigError(
            f"{source}: unknown section [{sorted(unknown)[0]}]; expected "
            f"{', '.join('[' + k + ']' for k in _KEYS)}.")
    with _in_section("bridge", source):
        bridge, mesh, ei = _bridge(_section(data, "bridge", source))
    with _in_section("vehicle", source):
        vehicle = _vehicle(_section(data, "vehicle", source))
    with _in_section("sensors", source):
        sensors = _sensors(_section(data, "sensors", source), bridge)
    with _in_section("noise", source):
        noise = _noise(_section(data, "noise", source), sensors)
    with _in_section("loads", source):
        sweep = _sweep(_section(data, "loads", source))
    with _in_section("logger", source):
        _logger_format(data, source)
    with _in_section("case", source):
        name = _section(data, "case", source).get("name", name)
    with _in_section("bridge", source):
        case = Case(bridge=bridge, mesh=mesh, ei=ei, vehicle=vehicle, sensors=sensors, noise=noise, sweep=sweep,
                    name=str(name))
        plausibility.check_ei(case.ei)
    with _in_section("loads", source):
        plausibility.check_sweep(case)
    with _in_section("bridge", source):
        lines = plausibility.check_case(case)
    with _in_section("vehicle", source):
        plausibility.check_signal(case, lines)
    return case


@contextmanager
def _in_section(section, source):
    """Prefix a ConfigError raised inside with the file and ``[section]`` (unless it names the file already)."""
    try:
        yield
    except ConfigError as exc:
        message = str(exc)
        if message.startswith(source):
            raise
        raise ConfigError(f"{source}: [{section}] {message}") from None


def _bridge(b):
    """The bridge, its EI mesh and the EI values of the [bridge] section."""
    bridge = Bridge(b["spans"], _inf(b.get("rotational_springs")), _inf(b.get("vertical_springs")))
    plausibility.check_bridge(bridge)
    if "elements" in b and "element_length" in b:
        raise ConfigError("give either 'elements' or 'element_length', not both.")
    if "element_length" in b:
        mesh = Mesh.from_length(bridge, b["element_length"])
    else:
        mesh = Mesh.uniform(bridge, b.get("elements", 10 * bridge.n_spans))
    return bridge, mesh, b["ei"]


def _vehicle(v):
    """The vehicle of the [vehicle] section."""
    vehicle = Vehicle(v["axle_offsets"], v["axle_loads"])
    plausibility.check_vehicle(vehicle)
    return vehicle


def _noise(n, sensors):
    """The noise model of the sensors' noise std and the [noise] section (None without a noise std).

    The time model's keys (``correlated_std`` [rad or m], ``correlation_time_s``
    [s], ``random_walk`` [rad or m per sqrt(s)]) take one number or one per
    sensor; ``speed`` [m/s] maps load positions to times; ``sample_rate`` [Hz] is the logger's rate the
    white std refers to.
    """
    noise = None
    if sensors.noise_std is not None:
        time = {key: _number_or_list(n[key], key) for key in TIME_KEYS if key in n}
        noise = NoiseModel(sensors.noise_std, n.get("correlation_length", 0.0), **time)
    elif n.keys() & {"correlation_length", *TIME_KEYS}:
        key = sorted(n.keys() & {"correlation_length", *TIME_KEYS})[0]
        raise ConfigError(f"'{key}' needs a noise standard deviation in [sensors] (noise_std).")
    plausibility.check_noise(noise, sensors.kinds)
    return noise


def _number_or_list(raw, key):
    """A number, or a list of numbers, of the [noise] section."""
    try:
        return float(raw) if not isinstance(raw, list) else [float(x) for x in raw]
    except (TypeError, ValueError):
        raise ConfigError(f"The '{key}' parameter must be a number or a list of numbers (one per sensor). "
                          f"Got {raw!r} instead.") from None


def _sweep(lo):
    """The load sweep of the [loads] section (None without one: the case's default)."""
    if not lo:
        return None
    missing = {"start", "stop", "step"} - set(lo)
    if missing:
        raise ConfigError(f"the key {sorted(missing)[0]!r} is missing (give start, stop and step).")
    return LoadSweep.from_range(lo["start"], lo["stop"], lo["step"])


def _sensors(s, bridge):
    positions = s["positions"]
    if not isinstance(positions, list):
        positions = [positions]
    if len(positions) > MAX_SENSORS:
        raise ConfigError(f"'positions' lists {len(positions)} sensors, more than {MAX_SENSORS}; give the "
                          "sensors of one monitoring system.")
    kinds = s.get("kinds")
    layout = SensorLayout(positions, kinds, s.get("names"))
    for sensor in layout.names:
        check_file_name(sensor)
    bridge.check_on_bridge(layout.positions, "positions", "SensorLayout")
    given = [k for k in ("noise_std", *_TILT_UNITS, *_DEFLECTION_UNITS) if k in s]
    if len(given) > 1:
        raise ConfigError(f"give the noise in one key only; got {', '.join(given)}.")
    if not given:
        return layout
    key = given[0]
    factor = 1.0
    if key in _TILT_UNITS:
        if any(k != "rotation" for k in layout.kinds):
            raise ConfigError(f"'{key}' applies to tiltmeters only; use 'noise_std' in SI units "
                              "(rad, m) for mixed sensor kinds.")
        factor = _TILT_UNITS[key]
    elif key in _DEFLECTION_UNITS:
        if any(k != "deflection" for k in layout.kinds):
            raise ConfigError(f"'{key}' applies to deflection sensors only; use 'noise_std' in SI "
                              "units (rad, m) for mixed sensor kinds.")
        factor = _DEFLECTION_UNITS[key]
    raw = s[key]
    try:
        values = [float(x) * factor for x in (raw if isinstance(raw, list) else [raw])]
    except (TypeError, ValueError):
        raise ConfigError(f"The '{key}' parameter must be a number or a list of numbers. "
                          f"Got {raw!r} instead.") from None
    if len(values) == 1:
        values = values * layout.n_sensors
    layout = SensorLayout(layout.positions, layout.kinds, layout.names, values)
    _check_noise_units(layout, key)
    return layout


def _check_noise_units(layout, key):
    """Reject noise levels that only make sense in another unit (a unit slip) or for no instrument."""
    for name, kind, std in zip(layout.names, layout.kinds, layout.noise_std):
        low, high = NOISE_STD_RANGE[kind]
        if kind == "rotation" and std > high:
            raise ConfigError(
                f"The '{key}' of sensor {name} is {std:g} rad, far above any tiltmeter noise. "
                "Give it in rad, or use 'noise_std_mm_per_m' / 'noise_std_urad'.")
        if kind == "deflection" and std > high:
            raise ConfigError(
                f"The '{key}' of sensor {name} is {std:g} m, far above any deflection noise. "
                "Give it in m, or use 'noise_std_mm'.")
        if std < low:
            unit = "rad" if kind == "rotation" else "m"
            raise ConfigError(
                f"The '{key}' of sensor {name} is {std:g} {unit}, below any {kind} sensor's noise (at least "
                f"{low:g} {unit}); give the noise of the instrument (noise-free data are not a model).")
