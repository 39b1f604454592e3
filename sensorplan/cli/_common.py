"""What every command shares: case arguments, value parsers, progress, staged output."""

import argparse
import dataclasses
import json
import math
import os
import re
import sys
from contextlib import contextmanager
from pathlib import Path

from .._errors import ConfigError, SensorplanError

__all__ = []


def show_default(value):
    """An option's default as its help and the user guide write it: 0.25, 2 (not 2.0), a,b for a list."""
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (list, tuple)):
        return ",".join(show_default(v) for v in value)
    return str(value)


def document_defaults(actions):
    """Append "(default X)" to the help of every option with a default that its help does not state.

    An option whose default is None or False (not given, a flag) states its
    meaning in its own words ("default: the case's sensors") or nothing.
    """
    for action in actions:
        default = action.default
        if (not action.option_strings or action.help in (None, argparse.SUPPRESS) or default is None
                or isinstance(default, bool) or default == argparse.SUPPRESS or "default" in action.help):
            continue
        action.help = f"{action.help} (default {show_default(default)})".replace("%", "%%")


def input_file(text):
    """An argparse type: the path of an existing file to read (a folder or a missing file is named)."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a folder; give the file to read")
    if not path.exists():
        raise argparse.ArgumentTypeError(f"no file {text!r}; check the path")
    return path


def output_file(text):
    """An argparse type: the path of a file to write (an existing folder is named)."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a folder; give a file name")
    return path


def add_common_arguments(parser):
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")


def add_case_arguments(parser):
    add_common_arguments(parser)
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--config", type=input_file, help="case file (TOML)")
    group.add_argument("--example", help="embedded example: simply-supported, openlab-like, three-span")


def add_speed_argument(parser):
    """``--speed``: the crossing speed [m/s] of a design or simulation under the noise model in time."""
    parser.add_argument("--speed", dest="crossing_speed", type=real(0.05, 100.0, what="a speed in m/s"),
                        help="crossing speed in m/s under the case's noise model in time (default: [noise] speed); "
                             "slower or more crossings buy information until the wander caps it")


def add_out_arguments(parser, *, json_default):
    parser.add_argument("--out", type=Path, default=Path("sensorplan-out"), help="output folder for figures")
    parser.add_argument("--json", type=output_file, help=f"JSON file (default OUT/{json_default})")


def load_case(args):
    from ..io.config import example_case
    from ..io.config import load_case as load

    case = load(args.config) if args.config is not None else example_case(args.example)
    if _dense_analysis(args) and getattr(args, "elements", None) is None:
        check_elements(case, args.command)
    speed = getattr(args, "crossing_speed", None)
    if speed is not None:
        if case.noise is None or not case.noise.in_time:
            raise ConfigError(f"--speed {speed:g} m/s: the case's noise has no part in time ([noise] correlated_std, "
                              "correlation_time_s, random_walk), so the speed changes nothing; estimate one with "
                              "'sensorplan noise --write-case' or drop --speed.")
        case = dataclasses.replace(case, noise=case.noise.at_speed(speed))
    return case


def read_data(path, case, command):
    """The crossings of ``path`` for ``case``; when the file lacks some of the case's sensors, one line on
    stderr says which it inverts and which it leaves out (a partial file is valid, the user should know)."""
    from ..io.csvio import read_crossings

    data = read_crossings(path, case.sensors)
    missing = [name for name in case.sensors.names if name not in data.sensor_names]
    if missing:
        print(f"sensorplan {command}: warning: {path} has no column for sensor(s) {', '.join(missing)} of the "
              f"case: using {', '.join(data.sensor_names)}, leaving out {', '.join(missing)}.",
              file=sys.stderr, flush=True)
    return data


def _dense_analysis(args):
    """Whether the command analyses on dense n_elements x n_elements algebra (inversions, posteriors).

    ``simulate`` only solves the forward model; a ``recommend`` without --verify or --target-power only
    designs, and its limit is the design's own memory and CPU estimate (:func:`check_design_resources`).
    """
    if args.command == "simulate":
        return False
    return args.command != "recommend" or bool(args.verify) or args.target_power is not None


def check_elements(case, command):
    """Analyses use dense n_elements x n_elements algebra: at most MAX_INVERSION_ELEMENTS elements."""
    if case.n_elements > MAX_INVERSION_ELEMENTS:
        advice = {"invert": ", or give --elements.",
                  "recommend": ", or drop --verify and --target-power (a design alone is limited by its memory "
                               "and CPU estimate, not by the element count)."}.get(command, ".")
        raise ConfigError(f"the case has {case.n_elements} elements; {command} handles at most "
                          f"{MAX_INVERSION_ELEMENTS} (dense algebra on n_elements^2 matrices): lower 'elements' or "
                          "raise 'element_length' in [bridge]" + advice)


def number(text, what, error=argparse.ArgumentTypeError):
    """The one number parser of the options: ``text`` as a finite float, else ``error(message)`` saying ``what``.

    ``error`` is argparse's ArgumentTypeError for option types, or a function
    building a ConfigError that names the option for values parsed later.
    """
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise error(f"expected {what}; got {text!r}") from None
    if not math.isfinite(value):
        raise error(f"expected a finite number ({what}); got {text!r}")
    return value


def integer(low, high, what="an integer"):
    """An argparse type: an integer in [low, high], with a message naming the range."""

    def parse(text):
        try:
            value = int(text.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what} from {low} to {high}; got {text!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected {what} from {low} to {high}; got {text!r}")
        return value

    parse.__name__ = "integer"
    parse.bounds = (low, high, False, False)  # read by the robustness tests
    return parse


def real(low, high, *, what, low_open=False, high_open=False):
    """An argparse type: a finite float in [low, high] (ends open when asked)."""
    left, right = "(" if low_open else "[", ")" if high_open else "]"
    interval = f"in {left}{low:g}, {high:g}{right}"

    def parse(text):
        value = number(text, f"{what} {interval}")
        if value < low or value > high or (low_open and value == low) or (high_open and value == high):
            raise argparse.ArgumentTypeError(f"expected {what} {interval}; got {text!r}")
        return value

    parse.__name__ = "real"
    parse.bounds = (low, high, low_open, high_open)  # read by the robustness tests
    return parse


SEED = integer(0, 2**63 - 1, "a non-negative integer seed")
COUNT = integer(1, 1000)
FALSE_ALARM = real(0.0, 0.5, what="a false-alarm rate", low_open=True, high_open=True)
LENGTH = real(0.0, 2000.0, what="a length in m", low_open=True)
SEVERITY = real(0.0, 1.0, what="a fraction of EI lost", low_open=True, high_open=True)
DISTANCE = real(0.0, 2000.0, what="a distance in m")
NOISE_STD = real(0.0, 1.0, what="a noise std in SI units (rad or m)", low_open=True)
MAX_POSITIONS = 1_000


def parse_positions(text):
    parts = [v for v in text.split(",") if v.strip()]
    values = [number(v, "comma-separated positions in m, e.g. 2.5,5,10") for v in parts]
    if not values:
        raise argparse.ArgumentTypeError("give at least one position in m, e.g. 2.5,5,10")
    if len(values) > MAX_POSITIONS:
        raise argparse.ArgumentTypeError(f"give at most {MAX_POSITIONS} positions; got {len(values)}")
    if len(set(values)) != len(values):
        dup = next(v for v in values if values.count(v) > 1)
        raise argparse.ArgumentTypeError(f"position {dup:g} m is given twice; give each position once")
    return values


def parse_zones(text):
    zones = []
    for part in text.split(","):
        ends = part.split(":")
        if len(ends) != 2:
            raise argparse.ArgumentTypeError(f"expected zones as start:stop in m, e.g. 14:16,29:30; got {part!r}")
        a, b = (number(v, f"zones as start:stop with finite ends in m, e.g. 14:16,29:30 (zone {part!r})")
                for v in ends)
        if b < a:
            raise argparse.ArgumentTypeError(f"zone {part!r} ends before it starts; write it as {b:g}:{a:g}")
        zones.append((a, b))
    return zones


MAX_CROSSINGS = 10_000
MAX_WORKERS = min(16, max(4, os.cpu_count() or 1))  # each worker holds its own copy of the case
MAX_SCENARIOS = 200
MAX_INVERSION_ELEMENTS = 400
MAX_CENTRES = 2_000
MIN_SNR = 3.0


def positions_of(items):
    """Positions [m] of option values that are positions or (position, kind) pairs (:func:`parse_sensors`)."""
    return [x[0] if isinstance(x, tuple) else x for x in items]


def check_layouts(case, layouts, option):
    """Every position of every layout on the bridge; the error names ``option``."""
    for layout in layouts:
        case.bridge.check_on_bridge(positions_of(layout), option.lstrip("-"), option)


def _count(length, step):
    return length / step if step > 0 else math.inf


def check_step(case, step, option):
    """A step along the bridge: at most the bridge length, at most MAX_CENTRES steps."""
    length = case.bridge.length
    if step > length:
        raise ConfigError(f"{option} {step:g} m is longer than the bridge ({length:g} m); give a step below "
                          f"{length:g} m.")
    if _count(length, step) > MAX_CENTRES:
        raise ConfigError(f"{option} {step:g} m gives {_count(length, step):.3g} positions on the "
                          f"{length:g} m bridge, more than {MAX_CENTRES}; use {option} >= {length / MAX_CENTRES:.3g}.")


def check_length(case, length, option):
    """A damaged zone's length: from MIN_ZONE_LENGTH (1 mm) to the bridge length."""
    from .._validation import MIN_ZONE_LENGTH

    if length >= case.bridge.length:
        raise ConfigError(f"{option} {length:g} m is not shorter than the bridge ({case.bridge.length:g} m).")
    if length < MIN_ZONE_LENGTH:
        raise ConfigError(f"{option} {length:g} m is shorter than {1e3 * MIN_ZONE_LENGTH:g} mm, no physical "
                          f"damaged zone; give {option} in m, e.g. {option} 2.")


def check_grid(case, args):
    """The recommend options against the bridge: candidate count, zones, --fixed, --min-spacing."""
    length = case.bridge.length
    if args.spacing > length:
        raise ConfigError(f"--spacing {args.spacing:g} m is longer than the bridge ({length:g} m); give a spacing "
                          f"below {length:g} m.")
    if getattr(args, "length", None) is not None:
        check_length(case, args.length, "--length")
    check_design_resources(case, args)
    if args.min_spacing > length:
        raise ConfigError(f"--min-spacing {args.min_spacing:g} m is longer than the bridge ({length:g} m).")
    zones = tuple(args.exclude or ())
    for a, b in zones:
        if b < 0.0 or a > length:
            raise ConfigError(f"--exclude zone {a:g}:{b:g} lies off the bridge (0 to {length:g} m).")
    fixed = positions_of(args.fixed or ())
    if not fixed:
        return
    case.bridge.check_on_bridge(fixed, "fixed", "--fixed")
    for x in fixed:
        for a, b in zones:
            if a <= x <= b:
                raise ConfigError(f"--fixed sensor at {x:g} m lies inside the --exclude zone {a:g}:{b:g}; an "
                                  "existing sensor cannot sit in an excluded zone: correct --fixed or --exclude.")
    ordered = sorted(fixed)
    for a, b in zip(ordered, ordered[1:]):
        if b - a < args.min_spacing:
            raise ConfigError(f"--fixed sensors at {a:g} and {b:g} m are closer than --min-spacing "
                              f"{args.min_spacing:g} m; lower --min-spacing or correct --fixed.")


def check_design_resources(case, args):
    """Refuse a candidate grid whose estimated memory or CPU time is beyond the machine
    (:mod:`sensorplan.design.resources`), naming both estimates and a --spacing that fits."""
    from ..design.detect_problem import detection_resources
    from ..design.resources import check_resources, estimate_resources, largest_fitting, spacing_for

    length = case.bridge.length
    kinds = getattr(args, "kind", None) or ()
    n_kinds = max(1, len(kinds) if isinstance(kinds, tuple) else len([k for k in kinds.split(",") if k.strip()]))
    n_candidates = int(min(_count(length, args.spacing) + 1.0, 1e15)) * n_kinds
    n_params = case.n_elements + (len(case.bridge.spring_parameters) if getattr(args, "springs", False) else 0)
    count = getattr(args, "count", None) or case.sensors.n_sensors
    detection = getattr(args, "criterion", None) == "detect" or getattr(args, "target_power", None) is not None

    opts = {k: getattr(args, k) for k in ("length", "step", "nuisance") if getattr(args, k, None) is not None}

    def estimate(c):  # detect builds no Fisher blocks: its estimate is the packed information's
        return (detection_resources(case, c, count, **opts) if detection
                else estimate_resources(c, n_params, count, n_loads=case.sweep.n_loads))

    fitting = largest_fitting(estimate)
    fits = (f"use --spacing >= {spacing_for(length, fitting, n_kinds):.3g}" if fitting >= n_kinds
            else "use fewer elements or a larger [loads] step")
    check_resources(estimate(n_candidates), what=f"--spacing {args.spacing:g} m gives about {n_candidates:.3g} "
                    "candidates", fits=fits)


def check_signal(case, noise, n_crossings):
    """Refuse a design where no sensor position sees the vehicle above the noise.

    The Fisher information a sensor adds about log EI is about the sum of its
    squared predicted readings over the noise variance (the readings are
    homogeneous of degree -1 in EI); below 3^2 for the best position over all
    crossings, the prior dominates and every layout is "certified" trivially.
    """
    import numpy as np

    from ..model.forward import readings
    from ..model.sensors import SensorLayout

    grid = np.linspace(0.0, case.bridge.length, 201)
    snrs = {}
    for kind, noise_std in noise.items():  # noise: kind -> noise std of new sensors of that kind
        y = readings(case.bridge, case.mesh, case.ei, SensorLayout.candidates(grid, kind), case.vehicle,
                     case.sweep.positions)
        snrs[kind] = float(np.max(np.sqrt(np.sum(y**2, axis=1) * n_crossings)) / noise_std)
    kind = max(snrs, key=snrs.__getitem__)
    snr, noise_std = snrs[kind], noise[kind]
    if snr < MIN_SNR:
        raise ConfigError(f"with a noise std of {noise_std:g} and {n_crossings} crossing(s) no {kind} sensor "
                          f"position sees the vehicle above the noise (best signal-to-noise {snr:.2g}, below "
                          f"{MIN_SNR:g}): every layout would be certified by the prior alone; lower --noise-std or "
                          "raise --crossings.")


def safe_name(name):
    """``name`` as a file-name part: anything but letters, digits, '.', '-' and '_' becomes '_'."""
    return "".join(ch if ch.isascii() and (ch.isalnum() or ch in "._-") else "_" for ch in name)


def _finite_json(value):
    """``value`` with non-finite floats as strict JSON allows: NaN -> null, +-inf -> "inf" / "-inf" (e.g. rigid
    springs), so that any JSON reader takes the file (Python's json would write NaN and Infinity)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: _finite_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_json(v) for v in value]
    return value


def file_names(names):
    """:func:`safe_name` of each name, made distinct even on case-insensitive file systems ('a b' and 'A_b'
    both give 'a_b': the second becomes 'A_b-2')."""
    out, seen = [], set()
    for name in names:
        base = candidate = safe_name(name)
        k = 1
        while candidate.casefold() in seen:
            k += 1
            candidate = f"{base}-{k}"
        seen.add(candidate.casefold())
        out.append(candidate)
    return out


def stage_json(files, path, payload):
    return files.write_text(path, json.dumps(_finite_json(payload), indent=2, allow_nan=False) + "\n")


def stage_figure(files, ax_or_fig, path):
    """Save a figure through the staged output; returns the final path."""
    from .. import plotting

    plotting.save_figure(ax_or_fig, files.stage(path, suffix=".png"))
    return Path(path)


# the parameters of sensorplan.design.recommend as the options of recommend/report name them
DESIGN_FLAGS = {"count": "--count", "min_spacing": "--min-spacing", "span_min": "--per-span-min",
                "span_max": "--per-span-max", "budget": "--budget", "costs": "--cost", "fixed": "--fixed",
                "spacing": "--spacing", "exclude": "--exclude", "noise_std": "--noise-std", "kind": "--kind",
                "region": "--region", "solver": "--solver"}


def rename_parameters(message, names):
    """``message`` with every quoted parameter name ('min_spacing') replaced by ``names[...]`` (--min-spacing)."""
    def swap(match):
        return names.get(match.group(1), match.group(0))

    renamed = re.sub(r"'(\w+)'(?: parameter)?", swap, message)
    for flag in set(names.values()):  # "The 'noise_std' (--noise-std) ..." names the option once
        renamed = renamed.replace(f"{flag} ({flag})", flag)
    return renamed


@contextmanager
def option_names(names=None):
    """Re-raise a sensorplan error with the parameters it names as the options (``DESIGN_FLAGS``) name them."""
    try:
        yield
    except SensorplanError as exc:
        raise type(exc)(rename_parameters(str(exc), DESIGN_FLAGS if names is None else names)) from exc
