"""Write a case as TOML (the format ``load_case`` reads), e.g. a case corrected by the diagnosis.

Owns: the case's TOML form.  May import: model and the foundations.
"""

import math

import numpy as np

from .._errors import ConfigError
from ..model.structure import Mesh

__all__ = ["case_to_toml"]


def _num(v):
    v = float(v)
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return repr(v)


def _list(values):
    return "[" + ", ".join(_num(v) for v in values) + "]"


def _noise_lines(noise):
    """The [noise] section's keys of ``noise`` (the time model's only when it has one)."""
    if not noise.in_time:
        return [f"correlation_length = {_num(noise.correlation_length)}"]
    lines = [f"correlated_std = {_list(noise.correlated_std)}",
             f"correlation_time_s = {_list(noise.correlation_time_s)}",
             f"random_walk = {_list(noise.random_walk)}"]
    lines.append(f"speed = {_num(noise.speed)}")
    return lines + ([] if noise.sample_rate is None else [f"sample_rate = {_num(noise.sample_rate)}"])


def _logger_lines(logger):
    """The [logger] section of a :class:`~sensorplan.model.timeseries.LoggerFormat` (none for the defaults)."""
    if logger is None or logger == type(logger)():
        return []
    lines = ["", "[logger]", f'tilt_unit = "{logger.tilt_unit}"', f'deflection_unit = "{logger.deflection_unit}"']
    if logger.temperature_columns:
        lines.append("temperature_columns = [" + ", ".join(f'"{c}"' for c in logger.temperature_columns) + "]")
    if logger.time_unit is not None:
        lines.append(f'time_unit = "{logger.time_unit}"')
    return lines


def case_to_toml(case, *, header="", logger=None):
    """TOML text of ``case``; reading it back gives the same case (uniform meshes and sweeps only).

    ``logger`` (a ``LoggerFormat``) is written as the ``[logger]`` section, so that a case
    written from a case file keeps how its logger exports are read.
    """
    bridge, mesh = case.bridge, case.mesh
    n = mesh.n_elements
    if not np.allclose(Mesh.uniform(bridge, n).edges, mesh.edges):
        raise ConfigError("The case's mesh is not uniform per span; a case file can only describe "
                          "'elements' per bridge. Use a uniform mesh.")
    lines = [f"# {line}" for line in header.splitlines()]
    lines += ["[case]", f"name = {case.name!r}".replace("'", '"'), "", "[bridge]", f"spans = {_list(bridge.spans)}",
              f"ei = {_list(case.ei)}", f"elements = {n}",
              f"rotational_springs = {_list(bridge.rotational_springs)}",
              f"vertical_springs = {_list(bridge.vertical_springs)}", "",
              "[vehicle]", f"axle_offsets = {_list(case.vehicle.axle_offsets)}",
              f"axle_loads = {_list(case.vehicle.axle_loads)}", "",
              "[sensors]", "names = [" + ", ".join(f'"{s}"' for s in case.sensors.names) + "]",
              f"positions = {_list(case.sensors.positions)}",
              "kinds = [" + ", ".join(f'"{k}"' for k in case.sensors.kinds) + "]"]
    if case.noise is not None:
        lines += [f"noise_std = {_list(case.noise.std)}", "", "[noise]"] + _noise_lines(case.noise)
    if case.sweep is not None:
        x = case.sweep.positions
        step = float(x[1] - x[0]) if x.size > 1 else 1.0
        if x.size > 1 and not np.allclose(np.diff(x), step):
            raise ConfigError("The case's load sweep is not evenly spaced; a case file describes start, stop, step.")
        lines += ["", "[loads]", f"start = {_num(x[0])}", f"stop = {_num(x[-1])}", f"step = {_num(step)}"]
    return "\n".join(lines + _logger_lines(logger)) + "\n"
