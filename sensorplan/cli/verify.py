"""``sensorplan verify``: score layouts by Bayesian inversion of synthetic damage."""

import argparse
from argparse import Namespace

from .._errors import ConfigError
from ._common import (
    FALSE_ALARM,
    LENGTH,
    MAX_SCENARIOS,
    MAX_WORKERS,
    SEED,
    add_case_arguments,
    add_out_arguments,
    add_speed_argument,
    check_layouts,
    check_length,
    integer,
    load_case,
    real,
    stage_figure,
    stage_json,
)
from ._kinds import (
    KINDS,
    PER_KIND,
    SCHEDULER,
    check_kind,
    kinds_and_noise,
    parse_sensors,
)
from ._progress import Progress

NAME = "verify"
HELP = "verify layouts by Bayesian inversion of synthetic damage"
EPILOG = """example:
  sensorplan verify --example openlab-like --layout 11,19 --layout 2,13,28.5 --scenarios 8 --workers 2 --seed 1
  sensorplan verify --example three-span --layout 4,14,20,26,36 --severity 0.1,0.25 --scheduler local --workers 2
  sensorplan verify --example openlab-like --layout 2,13:deflection,28.5 --noise-std rotation=5e-6,deflection=2e-5
"""


def add_verify_arguments(p, *, with_flag):
    if with_flag:
        p.add_argument("--verify", action="store_true",
                       help="verify the layout and the baselines by inversion of synthetic damage")
    p.add_argument("--scenarios", type=integer(1, MAX_SCENARIOS), default=8,
                   help="damage locations scanned (default %(default)s)")
    p.add_argument("--workers", type=integer(1, MAX_WORKERS), default=1, help="worker processes (default 1)")
    p.add_argument("--scheduler", type=SCHEDULER, metavar="ADDRESS",
                   help="run the scenarios on a Dask cluster: a scheduler address such as tcp://127.0.0.1:8786, "
                        "or 'local' for a local cluster of --workers processes (needs the dask extra); "
                        "results are identical to --workers 1")
    p.add_argument("--scheduler-timeout", type=real(0.0, 3600.0, what="a time in s", low_open=True), default=10.0,
                   metavar="S", help="seconds to wait for the Dask scheduler to answer (default 10)")
    p.add_argument("--verify-crossings", type=integer(1, 1000), default=10,
                   help="crossings simulated per scenario (default 10)")


def parse_severities(text):
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated fractions of EI lost, e.g. 0.1,0.25; got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("give at least one severity, e.g. 0.25")
    bad = [v for v in values if not 0.0 < v < 1.0]
    if bad:
        raise argparse.ArgumentTypeError(f"expected fractions of EI lost in (0, 1), e.g. 0.1,0.25; got {bad[0]!r}")
    return values


def add_arguments(p):
    add_case_arguments(p)
    add_speed_argument(p)
    p.add_argument("--layout", type=parse_sensors, action="append", required=True,
                   help="sensor positions in m, each optionally with :kind, e.g. 3.5,8:deflection,12 "
                        "(repeat for several layouts)")
    p.add_argument("--kind", type=KINDS, help="kind of the sensors given without :kind (default: the kind of the case's "
                                  "sensors)")
    p.add_argument("--noise-std", type=PER_KIND, help="noise std of the sensors in SI units (rad or m), per kind as "
                                       "rotation=5e-6,deflection=1e-4; default: the case's sensors' of that kind")
    p.add_argument("--seed", type=SEED, default=0, help="random seed (default 0)")
    p.add_argument("--severity", type=parse_severities, default=[0.25],
                   help="fraction(s) of EI lost by the local damage, in (0, 1), e.g. 0.1,0.25: one verification "
                        "per severity (default 0.25)")
    p.add_argument("--length", type=LENGTH, default=2.0, help="length of the local damage in m (default 2)")
    p.add_argument("--false-alarm", type=FALSE_ALARM, default=0.05,
                   help="false alarm rate of the detector, in (0, 0.5) (default 0.05)")
    p.add_argument("--nuisance", choices=["smooth", "levels"], default="smooth",
                   help="what the detector must not mistake for damage: a quadratic log-EI trend per span "
                        "(smooth, default) or one EI factor per span (levels)")
    add_out_arguments(p, json_default="verification.json")
    add_verify_arguments(p, with_flag=False)


def _given(args, name, default):
    value = getattr(args, name, None)
    return default if value is None else value


def run_verification(args, case, layouts, names, files, *, json_path):
    """Verify ``layouts`` at one severity; stage the JSON and the figure; returns (result, json path, figure path)."""
    results, json_path, figures = run_verifications(args, case, layouts, names, files, json_path=json_path)
    return results[0], json_path, figures[0]


def run_verifications(args, case, layouts, names, files, *, json_path):
    """Verify ``layouts`` once per severity; stage the JSON and the figure(s).

    Returns (results, json path, figure paths).  The JSON is the result's dict
    for one severity, {"severities": [...], "verifications": [...]} for several.
    """
    from .. import plotting
    from .._executors import executor_for
    from ..verification.verify import verify_layouts

    # recommend may have options of the same names (one value, None when not given): the defaults apply then
    severity = _given(args, "severity", 0.25)
    severities = list(severity) if isinstance(severity, (list, tuple)) else [severity]
    options = dict(length=_given(args, "length", 2.0), false_alarm=_given(args, "false_alarm", 0.05),
                   nuisance=_given(args, "nuisance", "smooth"))
    check_length(case, options["length"], "--length")
    results, progress = [], Progress(args.command, quiet=args.quiet)
    with executor_for(args.workers, args.scheduler, timeout=args.scheduler_timeout, name="--scheduler") as runner:
        for sev in severities:
            progress.stage(f"verifying {len(layouts)} layout(s) by inversion of synthetic damage ({100 * sev:g} % "
                           f"loss over {options['length']:g} m at {args.scenarios} locations, span softenings, "
                           f"undamaged controls; {args.verify_crossings} crossings each)",
                           unit="scenario inversions")
            results.append(verify_layouts(case, layouts, names=names, n_locations=args.scenarios,
                                          n_crossings=args.verify_crossings, seed=args.seed, executor=runner,
                                          severity=sev, **options, progress=progress.count))
    if len(results) == 1:
        payload = results[0].to_dict()
        paths = [args.out / "verification.png"]
    else:
        payload = {"severities": severities, "verifications": [r.to_dict() for r in results]}
        paths = [args.out / f"verification-{100 * sev:g}pct.png" for sev in severities]
    json_path = stage_json(files, json_path, payload)
    figures = [stage_figure(files, plotting.plot_verification(r, supports=case.bridge.support_positions)[0], path)
               for r, path in zip(results, paths)]
    return results, json_path, figures


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
    check_layouts(case, args.layout, "--layout")
    for layout in args.layout:
        sensor_kinds = tuple(default if k is None else k for _, k in layout)
        layouts.append(SensorLayout([x for x, _ in layout], sensor_kinds,
                                    tuple(f"S{i + 1}" for i in range(len(layout))),
                                    tuple(noise[k] for k in sensor_kinds)))
    results, json_path, figures = run_verifications(args, case, layouts, None, files,
                                                    json_path=args.json or args.out / "verification.json")
    for result in results:
        out(result.summary())
    out(f"verification written to {json_path}; figure{'s' if len(figures) > 1 else ''}: "
        + ", ".join(str(f) for f in figures))
    return 0
