"""Command line interface: ``sensorplan <command> ...``.

The CLI parses arguments, calls one public function per command, prints
its ``summary()`` and writes its files through :class:`OutputFiles` (all
or nothing).  Each command is a module here with ``NAME``, ``HELP``,
``EPILOG``, ``add_arguments(parser)`` and ``run(args, out, files)``.
Exit codes: 0 success, 1 user error (one line on stderr), 2 usage error.
Tracebacks are shown only with ``--debug``.

Owns: argument parsing, console output, exit codes.
May import: every other layer (it is the top one).
"""

import argparse
import os
import sys

from .._errors import SensorplanError
from . import crossings, detectability, diagnose, informativeness, invert, recommend, report, simulate, verify

__all__ = ["main", "build_parser", "COMMANDS"]

COMMANDS = (simulate, crossings, informativeness, detectability, invert, recommend, verify, diagnose, report)


def build_parser():
    from .. import __version__

    parser = argparse.ArgumentParser(
        prog="sensorplan",
        description="Sensor placement and Bayesian EI identification for bridges.")
    parser.add_argument("--version", action="version", version=f"sensorplan {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        p = sub.add_parser(command.NAME, help=command.HELP, epilog=command.EPILOG,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        command.add_arguments(p)
        p.set_defaults(handler=command.run)
    return parser


def _limit_blas_threads():
    """One BLAS thread unless the user chose otherwise (before numpy loads).

    sensorplan's dense algebra works on small matrices (tens to a few
    hundred parameters), where multi-threaded BLAS only adds overhead and,
    on a busy machine, stalls (measured 10-100x slower in
    studies/benchmarks/bench_inversion.py).
    """
    if "numpy" in sys.modules:
        return
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def main(argv=None):
    """Run the command line; returns the exit code."""
    from ..io.output import OutputFiles

    _limit_blas_threads()
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code) if exc.code is not None else 0
    lines = []  # printed once every file is in place

    def out(*parts):
        lines.append(" ".join(str(p) for p in parts))

    try:
        with OutputFiles() as files:
            code = args.handler(args, out, files)
        if not args.quiet:
            print("\n".join(lines))
        return code
    except (SensorplanError, OSError) as exc:
        if args.debug:
            raise
        message = " ".join(str(exc).split())
        print(f"sensorplan {args.command}: error: {message}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("sensorplan: interrupted", file=sys.stderr)
        return 130
