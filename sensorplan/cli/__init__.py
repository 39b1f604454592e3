"""Command line interface: ``sensorplan <command> ...``.

The CLI parses arguments, calls one public function per command, prints
its ``summary()`` and writes its files through :class:`OutputFiles` (all
or nothing).  Each command is a module here with ``NAME``, ``HELP``,
``EPILOG``, ``add_arguments(parser)`` and ``run(args, out, files)``.
Exit codes: 0 success, 1 user error or usage error (one line on stderr
naming the option or the field and the fix; an unknown option with the
closest known one, abbreviations refused).  Tracebacks are shown only with
``--debug``.  A command's output folder keeps the files of its last run
only (:mod:`sensorplan.io.manifest`).

Owns: argument parsing, console output, exit codes.
May import: every other layer (it is the top one).
"""

import argparse
import difflib
import os
import sys
import warnings

from .._allocator import keep_freed_memory
from .._errors import SensorplanError
from . import (
    crossings,
    detectability,
    diagnose,
    informativeness,
    invert,
    noise,
    recommend,
    report,
    simulate,
    verify,
)
from ._common import document_defaults

__all__ = ["main", "build_parser", "COMMANDS"]

COMMANDS = (simulate, crossings, noise, informativeness, detectability, invert, recommend, verify, diagnose, report)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line and exit code 1, that refuses abbreviated options
    and keeps a list of its optional arguments (``option_actions``, those of its groups included).

    argparse prints its usage block and exits with 2; the project's rule is
    one line on stderr naming the option and the fix, exit code 1.  argparse
    takes a unique prefix of an option for the option (``--cross 10`` for
    ``--crossings 10``); here an option is spelled out or refused.
    """

    def __init__(self, *args, **kwargs):
        self.option_actions = []
        kwargs["allow_abbrev"] = False
        super().__init__(*args, **kwargs)

    def error(self, message):
        message = " ".join(str(message).split())
        self.exit(1, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")

    def add_argument(self, *args, **kwargs):
        action = super().add_argument(*args, **kwargs)
        self.option_actions.append(action)
        return action

    def add_argument_group(self, *args, **kwargs):
        return self._recording(super().add_argument_group(*args, **kwargs))

    def add_mutually_exclusive_group(self, **kwargs):
        return self._recording(super().add_mutually_exclusive_group(**kwargs))

    def _recording(self, group):
        """``group`` with its add_argument recording the new action in ``option_actions``."""
        add = group.add_argument

        def add_argument(*args, **kwargs):
            action = add(*args, **kwargs)
            self.option_actions.append(action)
            return action

        group.add_argument = add_argument
        return group

    @property
    def option_strings(self):
        return [s for action in self.option_actions for s in action.option_strings]


def build_parser():
    from .. import __version__

    parser = _Parser(
        prog="sensorplan",
        description="Sensor placement and Bayesian EI identification for bridges.")
    parser.add_argument("--version", action="version", version=f"sensorplan {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    parser.commands = {}
    for command in COMMANDS:
        p = sub.add_parser(command.NAME, help=command.HELP, epilog=command.EPILOG,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        command.add_arguments(p)
        document_defaults(p.option_actions)
        p.set_defaults(handler=command.run)
        parser.commands[command.NAME] = p
    return parser


def check_spelling(parser, argv):
    """Refuse an unknown command or option before argparse parses ``argv``, suggesting the closest one.

    argparse would report an unknown option only after its other checks
    (a missing --config first), and without a suggestion.
    """
    command = next((a for a in argv if not a.startswith("-")), None)
    if command is None:
        return
    if command not in parser.commands:
        parser.error(f"unknown command {command!r}" + _suggestion(command, list(parser.commands)))
    sub = parser.commands[command]
    known = sub.option_strings
    for token in argv[argv.index(command) + 1:]:
        if token == "--":
            break
        name = token.split("=", 1)[0]
        if name.startswith("--") and name not in known:
            sub.error(f"unknown option {name}" + _suggestion(name, known))


def _suggestion(name, known):
    """'; did you mean X?' with the one known name that starts with or contains ``name``, else the most
    similar one (difflib), else ''."""
    for rule in (lambda k: k.startswith(name), lambda k: name.lstrip("-") in k):
        matches = [k for k in known if rule(k)]
        if len(matches) == 1:
            return f"; did you mean {matches[0]}?"
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.7)
    return f"; did you mean {close[0]}?" if close else ""


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
    keep_freed_memory()  # the command line owns its process: reuse freed pages (sensorplan._allocator)
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv:  # a bare `sensorplan`: what it can do
        parser.print_help()
        return 0
    try:
        check_spelling(parser, argv)
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code) if exc.code is not None else 0
    lines = []  # printed once every file is in place

    def out(*parts):
        lines.append(" ".join(str(p) for p in parts))

    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning(args.command)
            with OutputFiles(folder=output_folder(args), keep=input_paths(args)) as files:
                code = args.handler(args, out, files)
        if files.removed:
            out(f"removed {len(files.removed)} file(s) of the previous run in {args.out} that this run did not "
                "rewrite: " + ", ".join(files.removed))
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


def output_folder(args):
    """The run's output folder (``--out`` of a command that writes a folder), else None."""
    command = next(c for c in COMMANDS if c.NAME == args.command)
    out = getattr(args, "out", None)
    return None if out is None or getattr(command, "OUT_IS_FILE", False) else out


def input_paths(args):
    """The files the run reads (never removed as a previous run's output)."""
    return tuple(getattr(args, name) for name in ("config", "data", "timeseries", "axle_times")
                 if getattr(args, name, None) is not None)


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
