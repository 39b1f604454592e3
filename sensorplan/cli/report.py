"""``sensorplan report``: one self-contained HTML report and the design inputs (design.json)."""

from pathlib import Path

from ._common import check_grid, input_file, load_case, option_names, read_data, stage_json
from ._progress import Progress
from .recommend import add_arguments as add_recommend_arguments
from .recommend import design_options, recommend_argv

NAME = "report"
HELP = "one self-contained HTML report: conclusion, model, layout, verification, data, provenance"
EPILOG = """example:
  sensorplan report --example openlab-like --count 3 --criterion D --exclude 14:16 --out out/report

Takes every design option of `sensorplan recommend`; writes OUT/report.html and
OUT/design.json (the inputs of the design: rerun `sensorplan recommend` with its
"recommend_argv" to reproduce the layout).
"""


# options of recommend that the report takes but does not use (it always verifies, in this process)
_COMPATIBILITY = {"verify": "accepted for compatibility with recommend; the report always verifies",
                  "workers": "accepted for compatibility with recommend; the report verifies in one process",
                  "scheduler": "accepted for compatibility with recommend; the report verifies in one process",
                  "scheduler_timeout": "accepted for compatibility with recommend"}


def add_arguments(p):
    add_recommend_arguments(p)
    p.set_defaults(scenarios=6)
    p.add_argument("--data", type=input_file, help="measured crossings CSV (adds identified EI and the gap diagnosis)")
    for action in p.option_actions:
        if action.dest in _COMPATIBILITY:
            action.help = _COMPATIBILITY[action.dest]
        elif action.dest == "seed":
            action.help = "random seed of the random baseline and of the verification's noise"
        elif action.dest == "verify_crossings":
            action.help = "crossings simulated per verification scenario, and in the detectability map"
        elif action.dest == "target_power":
            action.help = ("the requirement the report opens with: Sufficient or Not sufficient for this "
                           "worst-case power of detecting the --severity loss over --length (default 0.9)")


def _inputs(args):
    """Input files (name -> path) whose hashes the provenance records."""
    files = {}
    if args.config is not None:
        files["config"] = args.config
    if args.data is not None:
        files["data"] = args.data
    return files


def run(args, out, files):
    from ..analysis import analyse
    from ..inference.screening import check_case_data_scale, check_not_noise_free
    from ..detection.results import POWER_TARGET
    from ..report import provenance, render_report
    from ..report.conclusion import sufficiency_sentence

    case = load_case(args)
    with option_names():
        check_grid(case, args)
        design = design_options(args, case)
        wanted = design_options(args, case, criterion="detect")
    requirement = {"target": wanted["target"], "region": wanted["region"]}
    data = read_data(args.data, case, "report") if args.data is not None else None
    if data is not None:
        check_case_data_scale(case, data, source=str(args.data))
        check_not_noise_free(case, data, source=str(args.data), what="diagnose in the report")
    progress = Progress("report", quiet=args.quiet)
    with option_names():
        analysis = analyse(case, data=data, count=args.count, criterion=args.criterion, n_scenarios=args.scenarios,
                           n_crossings=args.verify_crossings, seed=args.seed, progress=progress.stage,
                           progress_units=progress.count, design_options=design,
                           target_power=POWER_TARGET if args.target_power is None else args.target_power,
                           requirement=requirement)
    argv = recommend_argv(args)
    options = {k: (str(v) if isinstance(v, Path) else v) for k, v in sorted(vars(args).items())
               if k not in ("handler", "quiet", "debug")}
    record = provenance(options, _inputs(args), ["sensorplan", "report", *argv[1:],
                                                 *(["--data", str(args.data)] if args.data else []),
                                                 "--scenarios", str(args.scenarios), "--out", str(args.out)],
                        example=args.example)
    progress.stage("drawing the figures and writing the report")
    report = render_report(analysis, provenance=record)
    path = files.write_text(args.out / "report.html", report.html)
    json_path = stage_json(files, args.json or args.out / "design.json",
                           {"recommend_argv": argv, "provenance": record.to_dict(),
                            "layout_m": list(analysis.design.layout_m), "design": analysis.design.to_dict(),
                            "sufficiency": sufficiency_sentence(analysis),
                            "target": None if analysis.target is None else analysis.target.answer.to_dict(),
                            "verdict": None if analysis.verdict is None else analysis.verdict.to_dict()})
    out(sufficiency_sentence(analysis))
    out(analysis.design.summary())
    out(f"report with {len(report.sections)} sections written to {path}; design inputs: {json_path}")
    return 0
