"""Command line interface: ``sensorplan <command> ...``.

The CLI parses arguments, calls one public function per command, prints
its ``summary()`` and writes its files through :class:`OutputFiles` (all
or nothing).  Each command is a module here with ``NAME``, ``HELP``,
``EPILOG``, ``add_arguments(parser)`` and ``run(args, out, files)``.
Exit codes: 0 success, 1 user error or usage error (one line on stderr
naming the option or the field and the fix).  Tracebacks are shown only
with ``--debug``.

Owns: argument parsing, console output, exit codes.
May import: every other layer (it is the top one).
"""

import argparse
import os
import sys
import warnings

from .._errors import SensorplanError
from . import (
    crossings,
    detectability,
    diagnose,
    informativeness,
    invert,
    recommend,
    report,
    simulate,
    verify,
)

__all__ = ["main", "build_parser", "COMMANDS"]

COMMANDS = (simulate, crossings, informativeness, detectability, invert, recommend, verify, diagnose, report)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line and exit code 1.

    argparse prints its usage block and exits with 2; the project's rule is
    one line on stderr naming the option and the fix, exit code 1.
    """

    def error(self, message):
        message = " ".join(str(message).split())
        self.exit(1, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def build_parser():
    from .. import __version__

    parser = _Parser(
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
    on a busy machine, stalls (studies/benchmarks/bench_inversion.py).
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
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning(args.command)
            with OutputFiles() as files:
                code = args.handler(args, out, files)
        if not args.quiet:
            print("\n".join(lines))
        return code
    except (SensorplanError, OSError) as exc:
        return _fail(args, _one_line(exc))
    except MemoryError:
        return _fail(args, "not enough memory for this problem; use fewer elements (--elements, [bridge] elements), "
                           "a coarser candidate grid (--spacing), fewer load positions ([loads] step) or fewer "
                           "crossings/scenarios.")
    except (ValueError, ArithmeticError, RuntimeError) as exc:
        # A last line of defence: an input that passed every check but broke a
        # numerical step.  Still one line, naming what failed.
        return _fail(args, f"numerical failure ({type(exc).__name__}: {_one_line(exc)}); the case or the options "
                           "are probably outside the range the model handles (see docs/limitations.md); rerun "
                           "with --debug for the traceback.")
    except KeyboardInterrupt:
        print("sensorplan: interrupted", file=sys.stderr)
        return 130


def _one_line(exc):
    return " ".join(str(exc).split())


def _fail(args, message):
    if args.debug:
        raise
    print(f"sensorplan {args.command}: error: {message}", file=sys.stderr)
    return 1


def _one_line_warning(command):
    def show(message, category, filename, lineno, file=None, line=None):
        text = " ".join(str(message).split())
        print(f"sensorplan {command}: warning: {text}", file=sys.stderr)

    return show
