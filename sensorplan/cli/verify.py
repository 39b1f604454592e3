"""``sensorplan verify``: score layouts by Bayesian inversion of synthetic damage."""

from ._common import (
    MAX_SCENARIOS,
    MAX_WORKERS,
    NOISE_STD,
    SEED,
    add_case_arguments,
    add_out_arguments,
    check_layouts,
    integer,
    kind_and_noise,
    load_case,
    parse_positions,
    progress,
    stage_figure,
    stage_json,
)

NAME = "verify"
HELP = "verify layouts by Bayesian inversion of synthetic damage"
EPILOG = """example:
  sensorplan verify --example openlab-like --layout 11,19 --layout 2,13,28.5 --scenarios 8 --workers 2 --seed 1
"""


def add_verify_arguments(p, *, with_flag):
    if with_flag:
        p.add_argument("--verify", action="store_true",
                       help="verify the layout and the baselines by inversion of synthetic damage")
    p.add_argument("--scenarios", type=integer(1, MAX_SCENARIOS), default=8,
                   help="damage locations scanned (default 8)")
    p.add_argument("--workers", type=integer(1, MAX_WORKERS), default=1, help="worker processes (default 1)")
    p.add_argument("--verify-crossings", type=integer(1, 1000), default=10,
                   help="crossings simulated per scenario (default 10)")


def add_arguments(p):
    add_case_arguments(p)
    p.add_argument("--layout", type=parse_positions, action="append", required=True,
                   help="sensor positions in m, e.g. 3.5,8,12 (repeat for several layouts)")
    p.add_argument("--kind", choices=["rotation", "deflection"],
                   help="sensor kind (default: the kind of the case's sensors)")
    p.add_argument("--noise-std", type=NOISE_STD,
                   help="noise std of the new sensors in SI units (rad or m); default: the case's sensors'")
    p.add_argument("--seed", type=SEED, default=0, help="random seed (default 0)")
    add_out_arguments(p, json_default="verification.json")
    add_verify_arguments(p, with_flag=False)


def run_verification(args, case, layouts, names, files, *, json_path):
    """Verify ``layouts``; stage the JSON and the figure; returns (result, json path, figure path)."""
    from .. import plotting
    from ..verification.verify import verify_layouts

    result = verify_layouts(case, layouts, names=names, n_locations=args.scenarios, n_crossings=args.verify_crossings,
                            seed=args.seed, workers=args.workers, kind=args.kind, noise_std=args.noise_std,
                            progress=progress(args, args.command))
    json_path = stage_json(files, json_path, result.to_dict())
    axes = plotting.plot_verification(result, supports=case.bridge.support_positions)
    figure = stage_figure(files, axes[0], args.out / "verification.png")
    return result, json_path, figure


def run(args, out, files):
    case = load_case(args)
    args.kind, args.noise_std = kind_and_noise(args, case)
    check_layouts(case, args.layout, "--layout")
    result, json_path, figure = run_verification(args, case, args.layout, None, files,
                                                 json_path=args.json or args.out / "verification.json")
    out(result.summary())
    out(f"verification written to {json_path}; figure: {figure}")
    return 0
