"""``sensorplan report``: one self-contained HTML report."""

import sys
from pathlib import Path

from ._common import (
    COUNT,
    MAX_SCENARIOS,
    SEED,
    add_case_arguments,
    integer,
    load_case,
)

NAME = "report"
HELP = "one self-contained HTML report: model, layout, verification, data"
EPILOG = """example:
  sensorplan report --example openlab-like --count 3 --criterion D --out out/report
"""


def add_arguments(p):
    from ..design.criteria import CRITERIA

    add_case_arguments(p)
    p.add_argument("--data", type=Path, help="measured crossings CSV (adds identified EI and the gap diagnosis)")
    p.add_argument("--count", type=COUNT, help="number of sensors to place (default: as many as the case has)")
    p.add_argument("--criterion", choices=list(CRITERIA), default="D", help="design criterion (default D)")
    p.add_argument("--scenarios", type=integer(1, MAX_SCENARIOS), default=6,
                   help="damage locations in the verification (default 6)")
    p.add_argument("--seed", type=SEED, default=0, help="random seed (default 0)")
    p.add_argument("--out", type=Path, required=True, help="output folder (report.html)")


def run(args, out, files):
    from ..analysis import analyse
    from ..inference.screening import check_case_data_scale, check_not_noise_free
    from ..io.csvio import read_crossings
    from ..report import render_report

    case = load_case(args)
    data = read_crossings(args.data, case.sensors) if args.data is not None else None
    if data is not None:
        check_case_data_scale(case, data, source=str(args.data))
        check_not_noise_free(case, data, source=str(args.data), what="diagnose in the report")
    progress = None if args.quiet else (lambda msg: print(f"sensorplan report: {msg}", file=sys.stderr, flush=True))
    analysis = analyse(case, data=data, count=args.count, criterion=args.criterion, n_scenarios=args.scenarios,
                       seed=args.seed, progress=progress)
    report = render_report(analysis)
    path = files.write_text(args.out / "report.html", report.html)
    out(analysis.design.summary())
    out(f"report with {len(report.sections)} sections written to {path}")
    return 0
