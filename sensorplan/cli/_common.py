"""What every command shares: case arguments, value parsers, progress, staged output."""

import argparse
import json
import sys
from pathlib import Path

__all__ = []


def add_common_arguments(parser):
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")


def add_case_arguments(parser):
    add_common_arguments(parser)
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--config", type=Path, help="case file (TOML)")
    group.add_argument("--example", help="embedded example: simply-supported, openlab-like, three-span")


def add_out_arguments(parser, *, json_default):
    parser.add_argument("--out", type=Path, default=Path("sensorplan-out"), help="output folder for figures")
    parser.add_argument("--json", type=Path, help=f"JSON file (default OUT/{json_default})")


def load_case(args):
    from ..io.config import example_case
    from ..io.config import load_case as load

    return load(args.config) if args.config is not None else example_case(args.example)


def parse_positions(text):
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated positions in m, e.g. 2.5,5,10; got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("give at least one position in m")
    return values


def parse_zones(text):
    zones = []
    for part in text.split(","):
        try:
            a, b = (float(v) for v in part.split(":"))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected zones as start:stop in m, e.g. 14:16,29:30; got {part!r}") from None
        zones.append((a, b))
    return zones


def kind_and_noise(args, case):
    """The kind of new sensors and their noise std (the case's rule, see Case.noise_std_for)."""
    kind = args.kind or case.default_kind
    return kind, case.noise_std_for(kind, args.noise_std)


def progress(args, label, unit="scenarios"):
    """A progress callback (done, total) printing to stderr, or None with --quiet."""
    if args.quiet:
        return None

    def report(done, total):
        if total >= 20 and (done == total or done % max(1, total // 10) == 0):
            print(f"sensorplan {label}: {done}/{total} {unit}", file=sys.stderr, flush=True)

    return report


def stage_json(files, path, payload):
    return files.write_text(path, json.dumps(payload, indent=2) + "\n")


def stage_figure(files, ax_or_fig, path):
    """Save a figure through the staged output; returns the final path."""
    from .. import plotting

    plotting.save_figure(ax_or_fig, files.stage(path, suffix=".png"))
    return Path(path)


def parse_sensors(text):
    """Positions in m, each optionally followed by ``:kind`` (e.g. 4,10:deflection,16): [(x, kind or None)]."""
    out = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        x, _, kind = part.partition(":")
        try:
            out.append((float(x), kind.strip() or None))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected comma-separated positions in m, each optionally with :kind, e.g. 4,10:deflection,16; "
                f"got {text!r}") from None
    if not out:
        raise argparse.ArgumentTypeError("give at least one position in m")
    return out


def _flag_error(flag, message):
    from .._errors import ConfigError

    return ConfigError(f"{flag}: {message}")


def check_kind(kind, flag):
    from ..model.sensors import SENSOR_KINDS

    if kind not in SENSOR_KINDS:
        raise _flag_error(flag, f"unknown sensor kind {kind!r}; use {' or '.join(SENSOR_KINDS)}")
    return kind


def parse_kinds(text, flag="--kind"):
    """Comma-separated sensor kinds, distinct and known (a ConfigError naming ``flag`` otherwise)."""
    kinds = tuple(check_kind(k.strip(), flag) for k in text.split(",") if k.strip())
    if not kinds or len(set(kinds)) != len(kinds):
        raise _flag_error(flag, f"give distinct sensor kinds, e.g. rotation,deflection; got {text!r}")
    return kinds


def parse_per_kind(text, flag, *, allow_plain=True, low_open=True):
    """``value`` or ``kind=value,...`` (positive, or non-negative with ``low_open=False``); None stays None."""
    if text is None:
        return None
    bound = "positive" if low_open else "non-negative"
    if "=" not in text and allow_plain:
        return _number(text, flag, bound, low_open)
    out = {}
    for part in text.split(","):
        kind, sep, value = part.partition("=")
        if not sep:
            raise _flag_error(flag, f"expected kind=value pairs, e.g. rotation=1,deflection=3; got {part!r}")
        out[check_kind(kind.strip(), flag)] = _number(value, flag, bound, low_open)
    return out


def _number(text, flag, bound, low_open):
    import math

    try:
        value = float(text)
    except ValueError:
        raise _flag_error(flag, f"expected a number, got {text!r}") from None
    if not math.isfinite(value) or value < 0 or (low_open and value == 0):
        raise _flag_error(flag, f"must be {bound}; got {text!r}")
    return value


def parse_counts(text, flag):
    """Comma-separated whole counts per span, e.g. 1,0,1 (None stays None)."""
    if text is None:
        return None
    try:
        counts = [int(v) for v in text.split(",")]
    except ValueError:
        raise _flag_error(flag, f"expected one whole count per span, e.g. 1,1; got {text!r}") from None
    if any(c < 0 for c in counts):
        raise _flag_error(flag, f"counts must be non-negative; got {text!r}")
    return counts


def kinds_and_noise(args, case, extra=()):
    """Kinds of new sensors (``--kind``, default the case's) and their noise std per kind (``--noise-std``).

    ``--noise-std`` may also name the ``extra`` kinds (e.g. of existing sensors); their values are
    returned too when given.
    """
    kinds = parse_kinds(args.kind) if args.kind else (case.default_kind,)
    noise = parse_per_kind(args.noise_std, "--noise-std")
    if isinstance(noise, float):
        if len(kinds) > 1:
            raise _flag_error("--noise-std", f"give one value per kind, e.g. {kinds[0]}=5e-6,{kinds[1]}=1e-4")
        noise = {kinds[0]: noise}
    unknown = sorted(set(noise or {}) - set(kinds) - set(extra))
    if unknown:
        raise _flag_error("--noise-std", f"kind {unknown[0]} is not among the kinds of --kind ({','.join(kinds)})")
    out = {k: _kind_noise(case, k, (noise or {}).get(k), len(kinds) > 1) for k in kinds}
    return kinds, out | {k: case.noise_std_for(k, v) for k, v in (noise or {}).items() if k not in out}


def _kind_noise(case, kind, value, several):
    if value is not None or not several:
        return case.noise_std_for(kind, value)
    from .._errors import ConfigError

    try:
        return case.noise_std_for(kind)
    except ConfigError:
        unit = "rad" if kind == "rotation" else "m"
        raise _flag_error("--noise-std", f"no noise std for the new {kind} sensors (the case has none to take it "
                                         f"from); give it as {kind}=VALUE in {unit}") from None
