"""Command line interface: ``sensorplan <command> ...``.

The CLI parses arguments and delegates; it computes nothing itself.  Exit
codes: 0 success, 1 user error (one line on stderr), 2 usage error.
Tracebacks are shown only with ``--debug``.
"""

import argparse
import sys
from pathlib import Path

from ._errors import SensorplanError

__all__ = ["main"]

_EPILOG_SIMULATE = """example:
  sensorplan simulate --example openlab-like --crossings 5 --noise --seed 1 --out crossings.csv
"""


def _add_case_arguments(parser):
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--config", type=Path, help="case file (TOML)")
    group.add_argument("--example", help="embedded example: simply-supported, openlab-like, three-span")


def _load(args):
    from ._config import example_case, load_case

    return load_case(args.config) if args.config is not None else example_case(args.example)


def _cmd_simulate(args, out):
    import numpy as np

    from ._csvio import write_crossings
    from ._simulate import simulate_crossings

    case = _load(args)
    if args.noise and args.seed is None:
        raise SensorplanError("--noise needs --seed S so that the data can be reproduced.")
    rng = None if args.seed is None else np.random.default_rng(args.seed)
    crossings = simulate_crossings(case, args.crossings, noise=args.noise, rng=rng)
    write_crossings(args.out, crossings)
    kind = "noisy synthetic" if args.noise else "predicted"
    out(f"wrote {len(crossings)} {kind} crossing(s) of '{case.name}' "
        f"({case.sweep.n_loads} load positions, sensors {', '.join(case.sensors.names)}; "
        f"rotation in rad, deflection in m) to {args.out}")
    return 0


def build_parser():
    parser = argparse.ArgumentParser(
        prog="sensorplan",
        description="Sensor placement and Bayesian EI identification for bridges.")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("simulate", help="write predicted or noisy synthetic crossings (CSV)",
                       epilog=_EPILOG_SIMULATE, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(p)
    p.add_argument("--crossings", type=int, default=1, help="number of crossings (default 1)")
    p.add_argument("--noise", action="store_true", help="add noise from the case's noise model")
    p.add_argument("--seed", type=int, help="random seed (required with --noise)")
    p.add_argument("--out", type=Path, required=True, help="output CSV file")
    p.set_defaults(handler=_cmd_simulate)
    return parser


def main(argv=None):
    """Run the command line; returns the exit code."""
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code) if exc.code is not None else 0
    out = (lambda *a, **k: None) if args.quiet else (lambda *a, **k: print(*a, **k))
    try:
        return args.handler(args, out)
    except (SensorplanError, OSError) as exc:
        if args.debug:
            raise
        message = " ".join(str(exc).split())
        print(f"sensorplan {args.command}: error: {message}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("sensorplan: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
