"""``sensorplan recommend``: certified layout, baselines, criterion versus R (and --verify)."""


from .._errors import ConfigError
from ._common import (
    COUNT,
    DISTANCE,
    FALSE_ALARM,
    LENGTH,
    MAX_CROSSINGS,
    NOISE_STD,
    SEED,
    SEVERITY,
    add_case_arguments,
    add_out_arguments,
    check_grid,
    check_signal,
    integer,
    kind_and_noise,
    load_case,
    parse_positions,
    parse_zones,
    stage_figure,
    stage_json,
)
from .verify import add_verify_arguments, run_verification

NAME = "recommend"
HELP = "recommend where to put R sensors (certified layout + baselines)"
EPILOG = """example:
  sensorplan recommend --example openlab-like --count 3 --criterion D --exclude 14.5:15.5 --out out/design
  sensorplan recommend --example openlab-like --count 4 --criterion detect --crossings 10 --out out/detect
"""
DETECT_OPTIONS = ("severity", "length", "nuisance", "step", "false_alarm")


def add_arguments(p):
    from ..design.criteria import CRITERIA

    add_case_arguments(p)
    p.add_argument("--count", type=COUNT, help="number of new sensors R (default: as many as the case has)")
    p.add_argument("--criterion", choices=list(CRITERIA), default="D", help="design criterion (default D)")
    p.add_argument("--spacing", type=LENGTH, default=0.5, help="candidate grid spacing in m (default 0.5)")
    p.add_argument("--exclude", type=parse_zones, help="exclusion zones start:stop in m, e.g. 14:16,29:30")
    p.add_argument("--fixed", type=parse_positions, help="existing sensors in m, e.g. 11,19")
    p.add_argument("--min-spacing", type=DISTANCE, default=0.0, help="minimum distance between sensors in m")
    p.add_argument("--kind", choices=["rotation", "deflection"],
                   help="sensor kind (default: the kind of the case's sensors)")
    p.add_argument("--noise-std", type=NOISE_STD,
                   help="noise std of the new sensors in SI units (rad or m); default: the case's sensors'")
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
    add_out_arguments(p, json_default="design.json")
    add_verify_arguments(p, with_flag=True)


def run(args, out, files):
    from .. import plotting
    from ..design.recommend import recommend

    case = load_case(args)
    args.kind, args.noise_std = kind_and_noise(args, case)
    count = case.sensors.n_sensors if args.count is None else args.count
    check_grid(case, args)
    check_signal(case, args.kind, args.noise_std, args.crossings)
    result = recommend(case, count, args.criterion, **design_options(args))
    outdir = args.out
    figures = [
        stage_figure(files, plotting.plot_layout(result, exclude=args.exclude or ()), outdir / "layout.png"),
        stage_figure(files, plotting.plot_informativeness(result.informativeness, supports=result.supports_m, ei=case.ei),
                     outdir / "layout_informativeness.png"),
        stage_figure(files, plotting.plot_posterior_std(result), outdir / "posterior_std.png"),
    ]
    if result.curve:
        figures.append(stage_figure(files, plotting.plot_criterion_curve(result), outdir / "criterion_vs_R.png"))
    payload = result.to_dict()
    verification = None
    if args.verify:
        names = ["recommended"] + [b.name for b in result.baselines if b.feasible]
        layouts = [result.layout_m] + [b.layout_m for b in result.baselines if b.feasible]
        verification, _, vfig = run_verification(args, case, layouts, names, files,
                                                 json_path=outdir / "verification.json")
        payload["verification"] = verification.to_dict()
        figures.append(vfig)
    json_path = stage_json(files, args.json or outdir / "design.json", payload)
    out(result.summary())
    if verification is not None:
        out(verification.summary())
    out(f"design written to {json_path}; figures: " + ", ".join(str(p) for p in figures))
    return 0


def _region(args):
    if args.region is None:
        return None
    if len(args.region) != 1:
        raise ConfigError(f"--region takes one start:stop in m. Got {len(args.region)} zones instead.")
    return args.region[0]


def _detection_target(args):
    """The --severity ... options as a DetectionTarget (detect only; None for the other criteria)."""
    from ..design.recommend import DetectionTarget

    given = {k: getattr(args, k) for k in DETECT_OPTIONS if getattr(args, k) is not None}
    if args.criterion != "detect":
        if given:
            names = ", ".join("--" + k.replace("_", "-") for k in given)
            raise ConfigError(f"{names} apply to --criterion detect only. Got --criterion {args.criterion}.")
        return None
    return DetectionTarget(**given)


def design_options(args):
    """The keyword arguments of :func:`sensorplan.design.recommend.recommend` given by the options
    (``args.kind`` and ``args.noise_std`` resolved by ``kind_and_noise`` first)."""
    from ..design.recommend import CandidateGrid, Constraints

    return {"grid": CandidateGrid(spacing=args.spacing, exclude=tuple(args.exclude or ())),
            "constraints": Constraints(fixed=tuple(args.fixed or ()), min_spacing=args.min_spacing),
            "kind": args.kind, "noise_std": args.noise_std, "n_crossings": args.crossings,
            "springs": args.springs, "solver": args.solver, "rng": args.seed,
            "region": _region(args), "target": _detection_target(args)}


_NOT_DESIGN = {"help", "out", "json", "verify", "quiet", "debug", "scenarios", "workers", "verify_crossings"}


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
            argv += [flag, ",".join(":".join(repr(float(v)) for v in x) if isinstance(x, (list, tuple))
                                    else repr(float(x)) for x in value)]
        else:
            argv += [flag, repr(value) if isinstance(value, float) else str(value)]
    return argv
