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
