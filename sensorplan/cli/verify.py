"""``sensorplan verify``: score layouts by Bayesian inversion of synthetic damage."""

from argparse import Namespace

from .._errors import ConfigError
from ._common import (
    add_case_arguments,
    add_out_arguments,
    check_kind,
    kinds_and_noise,
    load_case,
    parse_sensors,
    progress,
    stage_figure,
    stage_json,
)

NAME = "verify"
HELP = "verify layouts by Bayesian inversion of synthetic damage"
EPILOG = """example:
  sensorplan verify --example openlab-like --layout 11,19 --layout 2,13,28.5 --scenarios 8 --workers 2 --seed 1
  sensorplan verify --example openlab-like --layout 2,13:deflection,28.5 --noise-std rotation=5e-6,deflection=2e-5
"""


def add_verify_arguments(p, *, with_flag):
    if with_flag:
        p.add_argument("--verify", action="store_true",
                       help="verify the layout and the baselines by inversion of synthetic damage")
    p.add_argument("--scenarios", type=int, default=8, help="damage locations scanned (default 8)")
    p.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    p.add_argument("--verify-crossings", type=int, default=10,
                   help="crossings simulated per scenario (default 10)")


def add_arguments(p):
    add_case_arguments(p)
    p.add_argument("--layout", type=parse_sensors, action="append", required=True,
                   help="sensor positions in m, each optionally with :kind, e.g. 3.5,8:deflection,12 "
                        "(repeat for several layouts)")
    p.add_argument("--kind", help="kind of the sensors given without :kind (default: the kind of the case's "
                                  "sensors)")
    p.add_argument("--noise-std", help="noise std of the sensors in SI units (rad or m), per kind as "
                                       "rotation=5e-6,deflection=1e-4; default: the case's sensors' of that kind")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    add_out_arguments(p, json_default="verification.json")
    add_verify_arguments(p, with_flag=False)


def run_verification(args, case, layouts, names, files, *, json_path):
    """Verify ``layouts``; stage the JSON and the figure; returns (result, json path, figure path)."""
    from .. import plotting
    from ..verification.verify import verify_layouts

    result = verify_layouts(case, layouts, names=names, n_locations=args.scenarios, n_crossings=args.verify_crossings,
                            seed=args.seed, workers=args.workers, progress=progress(args, args.command))
    json_path = stage_json(files, json_path, result.to_dict())
    axes = plotting.plot_verification(result, supports=case.bridge.support_positions)
    figure = stage_figure(files, axes[0], args.out / "verification.png")
    return result, json_path, figure


def run(args, out, files):
    from ..model.sensors import SensorLayout

    case = load_case(args)
    used = {check_kind(k, "--layout") for layout in args.layout for _, k in layout if k is not None}
    if args.kind and "," in args.kind:
        raise ConfigError("--kind: give one kind for the positions without :kind; mark the others, e.g. 4:deflection")
    default = args.kind or case.default_kind
    kind_arg = ",".join([default] + sorted(used - {default}))
    kinds, noise = kinds_and_noise(Namespace(kind=kind_arg, noise_std=args.noise_std), case)
    layouts = []
    for layout in args.layout:
        case.bridge.check_on_bridge([x for x, _ in layout], "layout", "--layout")
        sensor_kinds = tuple(default if k is None else k for _, k in layout)
        layouts.append(SensorLayout([x for x, _ in layout], sensor_kinds,
                                    tuple(f"S{i + 1}" for i in range(len(layout))),
                                    tuple(noise[k] for k in sensor_kinds)))
    result, json_path, figure = run_verification(args, case, layouts, None, files,
                                                 json_path=args.json or args.out / "verification.json")
    out(result.summary())
    out(f"verification written to {json_path}; figure: {figure}")
    return 0
