"""``sensorplan diagnose``: where model and measurements disagree, and why."""

import sys

from ._common import (
    MAX_WORKERS,
    add_case_arguments,
    add_out_arguments,
    input_file,
    integer,
    load_case,
    output_file,
    read_data,
    real,
    stage_figure,
    stage_json,
)
from ._kinds import SCHEDULER

NAME = "diagnose"
HELP = "diagnose the sim-to-real gap between the model and crossings (CSV)"
EPILOG = """example:
  sensorplan simulate --example openlab-like --crossings 6 --noise --seed 1 --out data.csv
  sensorplan diagnose --example openlab-like --data data.csv --json diagnosis.json --out out/diagnose
"""


def add_arguments(p):
    add_case_arguments(p)
    p.add_argument("--data", type=input_file, required=True, help="crossings CSV (crossing,position_m,<sensors>)")
    p.add_argument("--workers", type=integer(1, MAX_WORKERS), default=1, help="processes for screening the candidate effects (default 1)")
    p.add_argument("--scheduler", type=SCHEDULER, metavar="ADDRESS",
                   help="screen the effects on a Dask cluster: a scheduler address such as tcp://127.0.0.1:8786, "
                        "or 'local' for a local cluster of --workers processes (needs the dask extra)")
    p.add_argument("--scheduler-timeout", type=real(0.0, 3600.0, what="a time in s", low_open=True), default=10.0,
                   metavar="S", help="seconds to wait for the Dask scheduler to answer (default 10)")
    p.add_argument("--fixed-springs", action="store_true",
                   help="hold the case's elastic springs at their configured values (default: estimate them, "
                        "as invert does)")
    p.add_argument("--write-case", type=output_file, metavar="FILE",
                   help="write the case (TOML) with the identified springs, sensor positions and axle loads, "
                        "for rerunning invert")
    add_out_arguments(p, json_default="diagnosis.json")


def _progress(args):
    """Stage lines on stderr (base fit, effect k of n, selection round), or None with --quiet."""
    if args.quiet:
        return None
    return lambda text: print(f"sensorplan diagnose: {text}", file=sys.stderr, flush=True)


def run(args, out, files):
    from .. import plotting
    from .._errors import ConfigError
    from ..diagnosis.diagnose import diagnose
    from ..inference.screening import check_not_noise_free
    if args.workers < 1:
        raise ConfigError(f"The '--workers' option must be a positive integer. Got {args.workers} instead.")
    case = load_case(args)
    data = read_data(args.data, case, "diagnose")
    check_not_noise_free(case, data, source=str(args.data))
    result = diagnose(case, data, progress=_progress(args), workers=args.workers, scheduler=args.scheduler,
                      scheduler_timeout=args.scheduler_timeout,
                      estimate_springs=not args.fixed_springs, check_scale=str(args.data))
    supports = case.bridge.support_positions
    figures = [
        stage_figure(files, plotting.plot_residual_map(result), args.out / "residual_map.png"),
        stage_figure(files, plotting.plot_shrinkage(result), args.out / "shrinkage.png"),
        stage_figure(files, plotting.plot_ei_before_after(result, supports=supports), args.out / "ei_before_after.png"),
    ]
    json_path = stage_json(files, args.json or args.out / "diagnosis.json", result.to_dict())
    out(result.summary())
    out(f"diagnosis written to {json_path}; figures: " + ", ".join(str(p) for p in figures))
    if args.write_case is not None:
        from ..diagnosis.corrected import corrected_case
        from ..io.case_writer import case_to_toml

        kept_out = [] if result.corrected_model is None else list(result.corrected_model.not_in_case)
        header = (f"{case.name} corrected by `sensorplan diagnose` ({result.statement})"
                  + (f"\nnot in the case (properties of the data): {', '.join(kept_out)}" if kept_out else ""))
        from ..io.config import load_logger_format

        text = case_to_toml(corrected_case(case, result), header=header, logger=load_logger_format(args.config))
        path = files.write_text(args.write_case, text)
        out(f"corrected case written to {path}" + (f" (not in it: {', '.join(kept_out)})" if kept_out else ""))
    return 0
