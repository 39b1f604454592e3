"""``sensorplan recommend``: certified layout, baselines, criterion versus R (and --verify, --target-power)."""

import sys

from .._errors import ConfigError
from ._common import (
    COUNT,
    DESIGN_FLAGS,
    DISTANCE,
    FALSE_ALARM,
    LENGTH,
    MAX_CROSSINGS,
    SEED,
    SEVERITY,
    add_case_arguments,
    add_out_arguments,
    add_speed_argument,
    check_grid,
    check_signal,
    integer,
    load_case,
    option_names,
    parse_zones,
    real,
    stage_figure,
    stage_json,
)
from ._kinds import (
    COUNTS,
    KINDS,
    PER_KIND,
    check_kind,
    kinds_and_noise,
    parse_counts,
    parse_per_kind,
    parse_sensors,
)
from .verify import add_verify_arguments, run_verification

NAME = "recommend"
HELP = "recommend where to put R sensors (certified layout + baselines)"
EPILOG = """example:
  sensorplan recommend --example openlab-like --count 3 --criterion D --exclude 14.5:15.5 --out out/design
  sensorplan recommend --example openlab-like --count 4 --criterion detect --crossings 10 --out out/detect
  sensorplan recommend --example simply-supported --target-power 0.8 --out out/target
"""
DETECT_OPTIONS = ("severity", "length", "nuisance", "step", "false_alarm")
POWER = real(0.0, 1.0, what="a detection power", low_open=True, high_open=True)
# the parameters of design_for_target and CandidateGrid as the options name them
FLAGS = DESIGN_FLAGS | {"support_margin": "--support-margin", "max_count": "--count", "power": "--target-power"}


def add_arguments(p):
    from ..design.criteria import CRITERIA

    add_case_arguments(p)
    add_speed_argument(p)
    p.add_argument("--count", type=COUNT, help="number of new sensors R (default: as many as the case has); with "
                   "--target-power the largest count tried (default 12)")
    p.add_argument("--criterion", choices=list(CRITERIA), default="D", help="design criterion (default D)")
    p.add_argument("--spacing", type=LENGTH, default=0.5, help="candidate grid spacing in m (default 0.5)")
    p.add_argument("--exclude", type=parse_zones, help="exclusion zones start:stop in m, e.g. 14:16,29:30")
    p.add_argument("--support-margin", type=DISTANCE, help="keep new sensors at least this distance in m from "
                   "every support (default 0)")
    p.add_argument("--fixed", type=parse_sensors,
                   help="existing sensors in m, each optionally with :kind, e.g. 11,19:deflection")
    p.add_argument("--keep-case-sensors", action="store_true",
                   help="treat the case's own sensors (their kinds and noise) as existing")
    p.add_argument("--min-spacing", type=DISTANCE, default=0.0,
                   help="minimum distance between sensors in m, whatever their kinds")
    p.add_argument("--kind", type=KINDS, help="sensor kind(s) of the new sensors, e.g. rotation or rotation,deflection "
                                  "(default: the kind of the case's sensors)")
    p.add_argument("--noise-std", type=PER_KIND, help="noise std of the new sensors in SI units (rad or m), per kind as "
                                       "rotation=5e-6,deflection=1e-4; default: the case's sensors' of that kind")
    p.add_argument("--cost", type=PER_KIND, help="cost of a new sensor per kind, e.g. rotation=1,deflection=3 (default 1; "
                                  "with --budget)")
    p.add_argument("--budget", type=real(0.0, 1e15, what="a total cost", low_open=True),
                   help="total cost of the new sensors")
    p.add_argument("--per-span-min", type=COUNTS, help="minimum number of new sensors in each span, e.g. 1,1")
    p.add_argument("--per-span-max", type=COUNTS, help="maximum number of new sensors in each span, e.g. 3,3")
    p.add_argument("--crossings", type=integer(1, MAX_CROSSINGS), default=1,
                   help="crossings per measurement campaign (default 1)")
    p.add_argument("--springs", action="store_true", help="treat the spring stiffnesses as nuisance parameters")
    p.add_argument("--solver", choices=["auto", "fast", "cvxpy"], default="auto", help="relaxation solver")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the random baseline (default 0)")
    p.add_argument("--region", type=parse_zones, help="detect: damage centres in start:stop m only; "
                   "A: elements in start:stop m (region of interest)")
    d = p.add_argument_group("detect criterion (worst-case detectability of a local loss)")
    d.add_argument("--severity", type=SEVERITY, help="fraction of EI lost over the damaged zone (default 0.25)")
    d.add_argument("--length", type=LENGTH, help="length of the damaged zone in m (default 2)")
    d.add_argument("--nuisance", choices=["smooth", "levels"], help="what must not be mistaken for damage "
                   "(default smooth, as in detectability)")
    d.add_argument("--step", type=LENGTH, help="spacing of the damage centres in m (default 0.5)")
    d.add_argument("--false-alarm", type=FALSE_ALARM, help="false-alarm rate of the reported power (default 0.05)")
    d.add_argument("--target-power", type=POWER, help="design to a requirement: the fewest sensors (with --cost "
                   "and --budget the cheapest layout) whose detect-optimal layout reaches this worst-case power, "
                   "e.g. 0.8; --count caps the count")
    add_out_arguments(p, json_default="design.json")
    add_verify_arguments(p, with_flag=True)


def run(args, out, files):
    from .. import plotting
    from ..design.recommend import recommend
    from ..design.target import design_for_target
    from ..verification.ranking import rank_layouts

    case = load_case(args)
    count = case.sensors.n_sensors if args.count is None else args.count
    with option_names(FLAGS):
        options = design_options(args, case) if args.target_power is None else target_options(args, case)
        check_grid(case, args)
        check_signal(case, options["noise_std"], args.crossings)
        if args.target_power is None:
            answer = result = recommend(case, count, args.criterion, **options)
        else:
            answer = design_for_target(case, progress=_progress(args), **options)
            result = answer.design
    outdir = args.out
    figures = [
        stage_figure(files, plotting.plot_layout(result, exclude=args.exclude or ()), outdir / "layout.png"),
        stage_figure(files, plotting.plot_informativeness(result.informativeness, supports=result.supports_m, ei=case.ei),
                     outdir / "layout_informativeness.png"),
        stage_figure(files, plotting.plot_posterior_std(result), outdir / "posterior_std.png"),
    ]
    if result.curve:
        figures.append(stage_figure(files, plotting.plot_criterion_curve(result), outdir / "criterion_vs_R.png"))
    payload = answer.to_dict()
    verification = None
    if args.verify:
        names = ["recommended"] + [b.name for b in result.baselines if b.feasible]
        layouts = [_sensors(result.layout_m, result.layout_kind, result.noise_std)] + [
            _sensors(b.layout_m, b.layout_kind, result.noise_std) for b in result.baselines if b.feasible]
        verification, _, vfig = run_verification(args, case, layouts, names, files,
                                                 json_path=outdir / "verification.json")
        payload["verification"] = verification.to_dict()
        ranking = rank_layouts(verification, criterion=result.criterion,
                               values={"recommended": result.value} | {b.name: b.value for b in result.baselines})
        payload.update(ranking.to_dict())
        figures.append(vfig)
    trade = _crossing_trade(case, result)
    if trade is not None:
        payload["crossing_trade"] = trade.to_dict()
    json_path = stage_json(files, args.json or outdir / "design.json", payload)
    out(answer.summary())
    if trade is not None:
        out(trade.summary())
    if verification is not None:
        out(verification.summary())
        out(ranking.summary())
    out(f"design written to {json_path}; figures: " + ", ".join(str(p) for p in figures))
    return 0


def _region(args):
    if args.region is None:
        return None
    if len(args.region) != 1:
        raise ConfigError(f"--region takes one start:stop in m. Got {len(args.region)} zones instead.")
    return args.region[0]


def _progress(args):
    """One line per count tried on stderr (nothing with --quiet)."""
    if args.quiet:
        return None
    return lambda message: print(f"sensorplan recommend: {message}", file=sys.stderr, flush=True)


def _detection_target(args, criterion):
    """The --severity ... options as a DetectionTarget (criteria on detection information, e.g. detect;
    None for the other criteria)."""
    from ..design.criteria import criterion_class
    from ..design.recommend import DetectionTarget

    given = {k: getattr(args, k) for k in DETECT_OPTIONS if getattr(args, k) is not None}
    if criterion_class(criterion).information != "detection":
        if given:
            names = ", ".join("--" + k.replace("_", "-") for k in given)
            raise ConfigError(f"{names} apply to --criterion detect only. Got --criterion {criterion}.")
        return None
    return DetectionTarget(**given)


def target_options(args, case):
    """The keyword arguments of :func:`sensorplan.design.target.design_for_target` given by the options
    (--target-power; the layouts are detect-optimal, --count is the largest count tried)."""
    if args.criterion not in ("D", "detect"):
        raise ConfigError(f"--target-power designs detect-optimal layouts; drop --criterion {args.criterion} (or "
                          "give --criterion detect)")
    if args.springs:
        raise ConfigError("--springs applies to the information criteria; --target-power designs detect layouts "
                          "(their nuisance always includes the elastic springs): drop --springs")
    options = design_options(args, case, criterion="detect")
    del options["springs"]
    return {"power": args.target_power, "max_count": args.count, **options}


def design_options(args, case, *, criterion=None):
    """The keyword arguments of :func:`sensorplan.design.recommend.recommend` given by the options
    (``criterion`` default ``args.criterion``)."""
    from ..design.recommend import CandidateGrid, Constraints

    kinds, noise = kinds_and_noise(args, case, extra={k for _, k in args.fixed or () if k is not None})
    costs = parse_per_kind(args.cost, "--cost", allow_plain=False, low_open=False)
    if costs is not None and args.budget is None:
        raise ConfigError("--cost: sensor costs only matter with a --budget; give --budget B")
    if costs is not None and set(costs) - set(kinds):
        raise ConfigError(f"--cost: kind {sorted(set(costs) - set(kinds))[0]} is not among the kinds of --kind "
                          f"({','.join(kinds)})")
    constraints = Constraints(fixed=_existing(args, case, kinds[0], noise), min_spacing=args.min_spacing,
                              span_min=_spans(args.per_span_min, "--per-span-min", case),
                              span_max=_spans(args.per_span_max, "--per-span-max", case), costs=costs,
                              budget=args.budget)
    grid = CandidateGrid(spacing=args.spacing, exclude=tuple(args.exclude or ()), kinds=kinds,
                         support_margin=args.support_margin or 0.0)
    return {"grid": grid,
            "noise_std": {k: noise[k] for k in kinds}, "constraints": constraints, "n_crossings": args.crossings,
            "springs": args.springs, "solver": args.solver, "rng": args.seed,
            "region": _region(args), "target": _detection_target(args, criterion or args.criterion)}


_NOT_DESIGN = {"help", "out", "json", "verify", "quiet", "debug", "scenarios", "workers", "verify_crossings"}


def _item(x):
    """One item of a list option as the CLI reads it: a position, a zone a:b or a position with :kind."""
    if isinstance(x, (list, tuple)):
        if len(x) == 2 and (x[1] is None or isinstance(x[1], str)):  # (position, kind) of parse_sensors
            return repr(float(x[0])) + ("" if x[1] is None else f":{x[1]}")
        return ":".join(repr(float(v)) for v in x)
    return repr(float(x))


def recommend_argv(args):
    """``sensorplan recommend`` arguments that redo the design of ``args`` (every design option explicit)."""
    import argparse

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    argv = ["recommend"]
    for action in parser._actions:
        if action.dest in _NOT_DESIGN or not action.option_strings:
            continue
        value = getattr(args, action.dest, None)
        if value is None or value is False:
            continue
        flag = action.option_strings[-1]
        if value is True:
            argv.append(flag)
        elif isinstance(value, (list, tuple)):
            argv += [flag, ",".join(_item(x) for x in value)]
        else:
            argv += [flag, repr(value) if isinstance(value, float) else str(value)]
    return argv


def _spans(text, flag, case):
    counts = parse_counts(text, flag)
    if counts is not None and len(counts) != case.bridge.n_spans:
        raise ConfigError(f"{flag}: give one count per span ({case.bridge.n_spans}); got {text!r}")
    return counts


def _existing(args, case, kind, noise):
    """Existing sensors: --fixed (positions with optional :kind) and, with --keep-case-sensors, the case's own."""
    from ..model.sensors import SensorLayout

    positions, kinds, stds = [], [], []
    if args.keep_case_sensors:
        positions += list(case.sensors.positions)
        kinds += list(case.sensors.kinds)
        stds += [float(s) for s in case.noise.std] if case.noise is not None else [
            case.noise_std_for(k) for k in case.sensors.kinds]
    for x, k in args.fixed or ():
        k = kind if k is None else check_kind(k, "--fixed")
        positions.append(x)
        kinds.append(k)
        stds.append(noise[k] if k in noise else _existing_noise(case, k))
    if not positions:
        return ()
    case.bridge.check_on_bridge(positions, "fixed", "--fixed")
    return SensorLayout(positions, tuple(kinds), tuple(f"F{i + 1}" for i in range(len(positions))), tuple(stds))


def _existing_noise(case, kind):
    try:
        return case.noise_std_for(kind)
    except ConfigError:
        unit = "rad" if kind == "rotation" else "m"
        raise ConfigError(f"--fixed: the case has no {kind} sensor to take the noise of the existing {kind} "
                          f"sensors from; give it as --noise-std {kind}=VALUE in {unit}") from None


def _crossing_trade(case, result):
    """What slower or more crossings buy for the recommended layout (and the existing sensors), under a
    noise model in time; None otherwise."""
    from ..design.crossing_trade import crossing_trade
    from ..model.sensors import SensorLayout

    if case.noise is None or not case.noise.in_time:
        return None
    n_new, n_fixed = len(result.layout_m), len(result.fixed_m)
    layout = SensorLayout(list(result.layout_m) + list(result.fixed_m),
                          tuple(result.layout_kind) + tuple(result.fixed_kind),
                          tuple(f"S{i + 1}" for i in range(n_new + n_fixed)),
                          tuple(result.noise_std[k] for k in result.layout_kind) + tuple(result.fixed_noise_std))
    return crossing_trade(case, layout)


def _sensors(positions, kinds, noise):
    from ..model.sensors import SensorLayout

    return SensorLayout(list(positions), tuple(kinds), tuple(f"S{i + 1}" for i in range(len(positions))),
                        tuple(noise[k] for k in kinds))
