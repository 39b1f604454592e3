"""``sensorplan detectability``: where along the bridge a local EI loss can be detected at all."""

from ._common import (
    FALSE_ALARM,
    LENGTH,
    MAX_CROSSINGS,
    add_case_arguments,
    add_speed_argument,
    add_out_arguments,
    check_layouts,
    check_length,
    check_step,
    integer,
    load_case,
    parse_positions,
    real,
    stage_figure,
    stage_json,
)
from ._progress import Progress

NAME = "detectability"
HELP = "detection power and minimum detectable EI loss along the bridge"
EPILOG = """example:
  sensorplan detectability --example openlab-like --severity 0.25 --length 2 --crossings 10 --out out/detect
  sensorplan detectability --example three-span --layout 4,14,20,26,36 --nuisance levels
"""


def add_arguments(p):
    add_case_arguments(p)
    add_speed_argument(p)
    p.add_argument("--layout", type=parse_positions,
                   help="sensor positions in m, e.g. 3.5,8,12 (default: the case's sensors)")
    p.add_argument("--kind", choices=["rotation", "deflection"],
                   help="kind of the --layout sensors (default: the kind of the case's sensors)")
    p.add_argument("--severity", type=real(0.0, 1.0, what="a fraction of EI", low_open=True, high_open=True),
                   default=0.25,
                   help="fraction of EI lost over the damaged zone, in (0, 1) (default 0.25)")
    p.add_argument("--length", type=LENGTH, default=2.0, help="length of the damaged zone in m (default 2)")
    p.add_argument("--false-alarm", type=FALSE_ALARM, default=0.05,
                   help="false alarm rate of the detector, in (0, 0.5) (default 0.05)")
    p.add_argument("--crossings", type=integer(1, MAX_CROSSINGS), default=10,
                   help="number of identical crossings (default 10)")
    p.add_argument("--nuisance", choices=["smooth", "levels"], default="smooth",
                   help="what must not be mistaken for damage, besides elastic springs: a quadratic log-EI "
                        "trend per span (smooth, default) or one EI factor per span (levels)")
    p.add_argument("--step", type=LENGTH, default=0.5,
                   help="spacing of the damage centres in m (default 0.5)")
    add_out_arguments(p, json_default="detectability.json")


def run(args, out, files):
    from .. import plotting
    from ..detection.detectability import detectability

    case = load_case(args)
    if args.layout is not None:
        check_layouts(case, [args.layout], "--layout")
    check_step(case, args.step, "--step")
    check_length(case, args.length, "--length")
    sensors = "the case's sensors" if args.layout is None else f"{len(args.layout)} sensor(s)"
    Progress("detectability", quiet=args.quiet).stage(
        f"mapping the detection power of {sensors} for a {100 * args.severity:g} % loss over {args.length:g} m, "
        f"zone centres every {args.step:g} m")
    result = detectability(case, layout=args.layout, kind=args.kind, severity=args.severity, length=args.length,
                           false_alarm=args.false_alarm, n_crossings=args.crossings, nuisance=args.nuisance,
                           step=args.step)
    json_path = stage_json(files, args.json or args.out / "detectability.json", result.to_dict())
    axes = plotting.plot_detectability(result)
    figure = stage_figure(files, axes[0], args.out / "detectability.png")
    out(result.summary())
    out(f"detectability map written to {json_path}; figure: {figure}")
    return 0
