"""CSV files of crossings: ``crossing,position_m,<sensor...>[,load_factor][,time_s]``.

``time_s`` (optional) is the time of each reading [s], as a logger recorded
it; the noise model in time then uses it instead of positions / speed.

Values are in rad (rotation) or m (deflection).  Reading validates columns,
sensor names, numbers, NaNs, increasing positions within a crossing and
magnitudes that look like a unit slip; every error names the row or column.
Writing is atomic: the file appears complete or not at all.
"""

import csv
import io
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._errors import DataError
from ..model.crossings import Crossing, Crossings
from .output import atomic_write_text

if TYPE_CHECKING:
    from ..model.sensors import SensorLayout

__all__ = ["read_crossings", "write_crossings", "format_crossings", "write_table", "format_table",
           "atomic_write_text"]

# Plausibility limits per reading (a traffic crossing never tilts a bridge by
# 0.02 rad = 20 mm/m, nor deflects it by 1 m): larger values are unit slips.
_LIMITS = {"rotation": (0.02, "rad", "mm/m or micro-radians given as rad? Convert to rad"),
           "deflection": (1.0, "m", "mm given as m? Convert to m")}
_LOAD_FACTOR = (1e-2, 1e2)
EXTRA_COLUMNS = ("load_factor", "time_s")  # optional columns after the sensors  # a crossing's vehicle is 1/100 to 100 times the case's vehicle


def write_crossings(path: "str | os.PathLike[str]", crossings: Crossings) -> None:
    """Write crossings to a CSV file (atomically)."""
    atomic_write_text(path, format_crossings(crossings))


def format_crossings(crossings):
    """The CSV text of ``crossings``."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    with_factor = any(np.any(c.load_factor != 1.0) for c in crossings)
    with_times = all(c.times is not None for c in crossings)
    header = ["crossing", "position_m", *crossings.sensor_names]
    writer.writerow(header + (["load_factor"] if with_factor else []) + (["time_s"] if with_times else []))
    for c in crossings:
        for k in range(c.n_loads):
            row = [c.label, repr(float(c.positions[k]))] + [repr(float(v)) for v in c.values[:, k]]
            if with_factor:
                row.append(repr(float(c.load_factor[k])))
            if with_times:
                row.append(repr(float(c.times[k])))
            writer.writerow(row)
    return buf.getvalue()


def read_crossings(path: "str | os.PathLike[str]", sensors: "SensorLayout | None" = None) -> Crossings:
    """Read crossings from ``path``.

    Parameters
    ----------
    path : str or Path
    sensors : SensorLayout, optional
        When given, every sensor column must be one of its names and the
        magnitudes are checked against each sensor's kind.
    """
    return parse_crossings(read_text(path), sensors, source=str(Path(path)))


def read_text(path):
    """The text of a data file (a UTF-8 byte-order mark dropped); a one-line DataError when it cannot be read."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise DataError(f"{path}: file not found.") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: cannot read the file ({exc}).") from None


def check_delimiter(header, source, columns):
    """A DataError naming the delimiter when a header of one field holds ';', tab or '|'."""
    for sep, label in ((";", "semicolon"), ("\t", "tab"), ("|", "pipe")):
        if len(header) == 1 and sep in header[0]:
            raise DataError(f"{source}: the file is {label}-delimited; sensorplan reads comma-separated values "
                            f"({columns}): save it as CSV with ',' as the delimiter and '.' as the decimal mark.")


def parse_crossings(text, sensors=None, *, source="data"):
    """Crossings from CSV ``text`` (see :func:`read_crossings`); errors name ``source`` and the row or column."""
    rows = _rows(text, source)
    header = [h.strip() for h in rows[0]]
    sensor_cols = _check_header(header, sensors, source)
    col = {h: i for i, h in enumerate(header)}
    extras = [h for h in EXTRA_COLUMNS if h in col]
    groups = {}
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise DataError(f"{source}: row {line} has {len(row)} fields, the header has {len(header)}.")
        label = row[col["crossing"]].strip()
        if not label:
            raise DataError(f"{source}: row {line}, column 'crossing' is empty.")
        numbers = [_number(row[col[h]], source, line, h)
                   for h in ["position_m", *sensor_cols, *extras]]
        groups.setdefault(label, []).append(numbers)
    if not groups:
        raise DataError(f"{source}: the file has a header but no data rows.")
    out = [_crossing(label, np.array(data), len(sensor_cols), extras, source) for label, data in groups.items()]
    crossings = Crossings(tuple(sensor_cols), tuple(out))
    if sensors is not None:
        _check_magnitudes(crossings, sensors, source)
    return crossings


def _rows(text, source):
    """The non-blank CSV rows of ``text``, at least the header."""
    reader = csv.reader(io.StringIO(text))
    try:
        rows = [r for r in reader if r and any(cell.strip() for cell in r)]
    except csv.Error as exc:
        raise DataError(f"{source}: line {reader.line_num}: malformed CSV ({exc}); "
                        "check for an unbalanced quote.") from None
    if not rows:
        raise DataError(f"{source}: the file is empty; expected a header "
                        "'crossing,position_m,<sensor names>'.")
    return rows


def _check_header(header, sensors, source):
    """The sensor columns of a valid header (every one a sensor of ``sensors`` when given)."""
    check_delimiter(header, source, "crossing,position_m,<sensors>")
    for required in ("crossing", "position_m"):
        if required not in header:
            raise DataError(f"{source}: missing column '{required}'; the header must start "
                            "'crossing,position_m,' followed by one column per sensor.")
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise DataError(f"{source}: column '{dup}' appears twice.")
    sensor_cols = [h for h in header if h not in ("crossing", "position_m", *EXTRA_COLUMNS)]
    if not sensor_cols:
        raise DataError(f"{source}: no sensor column; add one column per sensor name.")
    if sensors is not None:
        unknown = [h for h in sensor_cols if h not in sensors.names]
        if unknown:
            raise DataError(f"{source}: column '{unknown[0]}' is not a sensor of the case; "
                            f"sensor names are {', '.join(sensors.names)}.")
    return sensor_cols


def _crossing(label, arr, n_s, extras, source):
    """One crossing from its rows (position, ``n_s`` readings[, load factor][, time]), positions increasing."""
    pos = arr[:, 0]
    if np.any(np.diff(pos) <= 0.0):
        raise DataError(f"{source}: positions of crossing '{label}' must be strictly increasing; "
                        "sort the rows of each crossing by position_m.")
    times = arr[:, 1 + n_s + extras.index("time_s")] if "time_s" in extras else None
    if times is not None and np.any(np.diff(times) <= 0.0):
        raise DataError(f"{source}: column 'time_s' of crossing '{label}' must increase with position_m "
                        "(one vehicle moving forward); check the time column.")
    factor = arr[:, 1 + n_s] if "load_factor" in extras else np.ones(pos.size)
    if np.any(factor <= 0.0):
        raise DataError(f"{source}: column 'load_factor' of crossing '{label}' must be positive.")
    if np.any(factor < _LOAD_FACTOR[0]) or np.any(factor > _LOAD_FACTOR[1]):
        bad = float(factor[(factor < _LOAD_FACTOR[0]) | (factor > _LOAD_FACTOR[1])][0])
        raise DataError(f"{source}: column 'load_factor' of crossing '{label}' is {bad:g}; a load factor (vehicle "
                        f"weight / the case's vehicle) is {_LOAD_FACTOR[0]:g} to {_LOAD_FACTOR[1]:g}.")
    return Crossing(label, pos, arr[:, 1:1 + n_s].T.copy(), factor, times=times)


def _number(cell, source, line, column):
    try:
        value = float(cell)
    except ValueError:
        raise DataError(f"{source}: row {line}, column '{column}': {cell.strip()!r} is not a number.") from None
    if math.isnan(value) or math.isinf(value):
        raise DataError(f"{source}: row {line}, column '{column}' is {cell.strip() or 'empty'}; "
                        "remove the row or fill in the value.")
    return value


def _check_magnitudes(crossings, sensors, source):
    for i, name in enumerate(crossings.sensor_names):
        kind = sensors.kinds[sensors.names.index(name)]
        limit, unit, hint = _LIMITS[kind]
        peak = max(float(np.max(np.abs(c.values[i]))) for c in crossings)
        if peak > limit:
            raise DataError(f"{source}: column '{name}' reaches {peak:g} {unit}, implausible for a "
                            f"{kind} sensor ({hint}).")


def write_table(path, header, columns):
    """Write named columns of numbers to a CSV file (atomically)."""
    atomic_write_text(path, format_table(header, columns))


def format_table(header, columns):
    """CSV text of named columns of numbers."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in zip(*columns):
        writer.writerow([repr(float(v)) for v in row])
    return buf.getvalue()
