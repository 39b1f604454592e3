"""Command line interface: ``sensorplan <command> ...``.

The CLI parses arguments and delegates; it computes nothing itself.  Exit
codes: 0 success, 1 user error (one line on stderr), 2 usage error.
Tracebacks are shown only with ``--debug``.
"""

import argparse
import os
import sys
from pathlib import Path

from ._errors import SensorplanError

__all__ = ["main"]

_EPILOG_SIMULATE = """example:
  sensorplan simulate --example openlab-like --crossings 5 --noise --seed 1 --out crossings.csv
"""


_EPILOG_INFORMATIVENESS = """example:
  sensorplan informativeness --example simply-supported --positions 0,5,10,15,20 --out out/info
"""


_EPILOG_INVERT = """example:
  sensorplan simulate --example openlab-like --crossings 10 --noise --seed 1 --out data.csv
  sensorplan invert --example openlab-like --data data.csv --elements 30 --json posterior.json --out out/invert
"""


_EPILOG_RECOMMEND = """example:
  sensorplan recommend --example openlab-like --count 3 --criterion D --exclude 14.5:15.5 --out out/design
"""


_EPILOG_VERIFY = """example:
  sensorplan verify --example openlab-like --layout 11,19 --layout 2,13,28.5 --scenarios 8 --workers 2 --seed 1
"""


_EPILOG_DIAGNOSE = """example:
  sensorplan simulate --example openlab-like --crossings 6 --noise --seed 1 --out data.csv
  sensorplan diagnose --example openlab-like --data data.csv --json diagnosis.json --out out/diagnose
"""


_EPILOG_REPORT = """example:
  sensorplan report --example openlab-like --count 3 --criterion D --out out/report
"""


def _add_common_arguments(parser):
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")


def _add_case_arguments(parser):
    _add_common_arguments(parser)
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--config", type=Path, help="case file (TOML)")
    group.add_argument("--example", help="embedded example: simply-supported, openlab-like, three-span")


def _load(args):
    from .io.config import example_case, load_case

    return load_case(args.config) if args.config is not None else example_case(args.example)


def _cmd_simulate(args, out):
    import numpy as np

    from .io.csvio import write_crossings
    from .model.simulate import simulate_crossings

    case = _load(args)
    if args.noise and args.seed is None:
        raise SensorplanError("--noise needs --seed S so that the data can be reproduced.")
    rng = None if args.seed is None else np.random.default_rng(args.seed)
    crossings = simulate_crossings(case, args.crossings, noise=args.noise, rng=rng)
    write_crossings(args.out, crossings)
    kind = "noisy synthetic" if args.noise else "predicted"
    out(f"wrote {len(crossings)} {kind} crossing(s) of '{case.name}' "
        f"({case.sweep.n_loads} load positions, sensors {', '.join(case.sensors.names)}; "
        f"rotation in rad, deflection in m) to {args.out}")
    return 0


def _parse_positions(text):
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated positions in m, e.g. 2.5,5,10; got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("give at least one position in m")
    return values


def _cmd_informativeness(args, out):
    from .io.csvio import write_table
    from .model.fisher import fisher_blocks, identifiability
    from .model.prior import GMRFPrior
    from .model.sensors import SensorLayout

    case = _load(args)
    sensors = None
    if args.positions is not None:
        case.bridge.check_on_bridge(args.positions, "positions", "--positions")
        kind, noise = _sensor_kind_and_noise(args, case)
        sensors = SensorLayout.candidates(args.positions, kind, noise_std=[noise] * len(args.positions))
    blocks = fisher_blocks(case, sensors=sensors, parameterisation=args.parameterisation,
                           n_crossings=args.crossings)
    log_blocks = fisher_blocks(case, sensors=sensors, parameterisation="log_ei",
                               n_crossings=args.crossings)
    ident = identifiability(log_blocks, prior_precision=GMRFPrior().precision(case.n_elements))
    outdir = Path(args.out)
    csv_path = outdir / "informativeness.csv"
    header = ["x_left_m", "x_right_m", *blocks.sensors.names]
    write_table(csv_path, header, [case.mesh.edges[:-1], case.mesh.edges[1:], *blocks.curves])
    figures = _informativeness_figures(case, blocks, ident, outdir)
    out(blocks.summary())
    out(ident.summary())
    out(f"curves ({args.parameterisation}, unit {blocks.unit}) written to {csv_path}")
    out("figures: " + ", ".join(str(p) for p in figures))
    return 0


def _informativeness_figures(case, blocks, ident, outdir):
    from . import plotting

    supports = case.bridge.support_positions
    return [
        plotting.save_figure(plotting.plot_informativeness(blocks, supports=supports),
                             outdir / "informativeness.png"),
        plotting.save_figure(plotting.plot_spectrum(ident), outdir / "spectrum.png"),
        plotting.save_figure(plotting.plot_eigenvectors(ident, supports=supports),
                             outdir / "eigenvectors.png"),
    ]


def _cmd_invert(args, out):
    import json
    import warnings

    import numpy as np

    from .io.csvio import atomic_write_text, read_crossings
    from ._errors import SensorplanWarning
    from .inference.inversion import invert
    from .inference.screening import check_data_scale
    from .model.structure import Mesh

    case = _load(args)
    data = read_crossings(args.data, case.sensors)
    if args.elements is not None:
        case = case.with_mesh(Mesh.uniform(case.bridge, args.elements))
    nominal = case.influence_lines(sensors=case.sensors.subset(
        [case.sensors.names.index(n) for n in data.sensor_names]), positions=data.crossings[0].positions)
    check_data_scale(data, dict(zip(data.sensor_names, nominal.predictions)), data.sensor_names,
                     source=str(args.data))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SensorplanWarning)
        result = invert(case, data)
    for w in caught:
        print(f"sensorplan invert: warning: {w.message}", file=sys.stderr)
    outdir = Path(args.out)
    figures = _invert_figures(case, result, outdir)
    payload = json.dumps(result.to_dict(), indent=2)
    json_path = args.json if args.json is not None else outdir / "posterior.json"
    atomic_write_text(json_path, payload + "\n")
    out(result.summary())
    out(f"posterior written to {json_path}; figures: " + ", ".join(str(p) for p in figures))
    return 0


def _invert_figures(case, result, outdir):
    from . import plotting

    paths = [plotting.save_figure(plotting.plot_ei_posterior(result, supports=case.bridge.support_positions),
                                  outdir / "ei_posterior.png")]
    for name in result.sensor_names:
        paths.append(plotting.save_figure(plotting.plot_fit(result, name), outdir / f"fit_{name}.png"))
    return paths


def _parse_zones(text):
    zones = []
    for part in text.split(","):
        try:
            a, b = (float(v) for v in part.split(":"))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected zones as start:stop in m, e.g. 14:16,29:30; got {part!r}") from None
        zones.append((a, b))
    return zones


def _sensor_kind_and_noise(args, case):
    """The kind of the new sensors and their noise std, refusing a silent unit mix-up."""
    import numpy as np

    from ._errors import ConfigError

    kinds = set(case.sensors.kinds)
    kind = args.kind or (kinds.pop() if len(kinds) == 1 else "rotation")
    noise = args.noise_std
    if noise is not None and not noise > 0:
        raise ConfigError(f"--noise-std must be positive (SI units: rad or m). Got {noise!r}.")
    if noise is None:
        same = [s for k, s in zip(case.sensors.kinds, case.noise.std) if k == kind] if case.noise is not None else []
        if not same:
            raise ConfigError(f"The case has no {kind} sensor to take the noise level from; give --noise-std "
                              f"in {'rad' if kind == 'rotation' else 'm'}.")
        noise = float(np.median(same))
    return kind, noise


def _cmd_recommend(args, out):
    import json

    from .io.csvio import atomic_write_text
    from .design.recommend import recommend
    from .model.fisher import fisher_blocks
    from .model.sensors import SensorLayout

    case = _load(args)
    args.kind, args.noise_std = _sensor_kind_and_noise(args, case)
    count = case.sensors.n_sensors if args.count is None else args.count
    if args.fixed:
        case.bridge.check_on_bridge(args.fixed, "fixed", "--fixed")
    result = recommend(case, count, args.criterion, spacing=args.spacing, exclude=args.exclude or (),
                       fixed=args.fixed or (), kind=args.kind, noise_std=args.noise_std,
                       n_crossings=args.crossings,
                       min_spacing=args.min_spacing, springs=args.springs, solver=args.solver,
                       rng=args.seed)
    outdir = Path(args.out)
    from . import plotting

    layout = SensorLayout.candidates(list(result.layout_m), args.kind, noise_std=[args.noise_std] * result.count)
    blocks = fisher_blocks(case, sensors=layout, parameterisation="ei", n_crossings=args.crossings)
    figures = [
        plotting.save_figure(plotting.plot_layout(result), outdir / "layout.png"),
        plotting.save_figure(plotting.plot_informativeness(blocks, supports=case.bridge.support_positions),
                             outdir / "layout_informativeness.png"),
        plotting.save_figure(plotting.plot_posterior_std(result), outdir / "posterior_std.png"),
    ]
    if result.curve:
        figures.append(plotting.save_figure(plotting.plot_criterion_curve(result), outdir / "criterion_vs_R.png"))
    payload = result.to_dict()
    verification = None
    if args.verify:
        names = ["recommended"] + [n for n, b in result.baselines.items() if b is not None]
        layouts = [result.layout_m] + [b["layout_m"] for b in result.baselines.values() if b is not None]
        args.verify_json = outdir / "verification.json"
        verification, vpath, vfig = _run_verification(args, case, layouts, names, outdir)
        payload["verification"] = verification.to_dict()
        figures.append(vfig)
    json_path = args.json if args.json is not None else outdir / "design.json"
    atomic_write_text(json_path, json.dumps(payload, indent=2) + "\n")
    out(result.summary())
    if verification is not None:
        out(verification.summary())
    out(f"design written to {json_path}; figures: " + ", ".join(str(p) for p in figures))
    return 0


def _progress(args, label):
    if args.quiet:
        return None

    def report(done, total):
        if total >= 20 and (done == total or done % max(1, total // 10) == 0):
            print(f"sensorplan {label}: {done}/{total} scenarios", file=sys.stderr, flush=True)

    return report


def _run_verification(args, case, layouts, names, outdir):
    import json

    from . import plotting
    from .io.csvio import atomic_write_text
    from .verification.verify import verify_layouts

    result = verify_layouts(case, layouts, names=names, n_locations=args.scenarios, n_crossings=args.verify_crossings,
                            seed=args.seed, workers=args.workers, kind=args.kind, noise_std=args.noise_std,
                            progress=_progress(args, args.command))
    json_path = getattr(args, "verify_json", None) or outdir / "verification.json"
    atomic_write_text(json_path, json.dumps(result.to_dict(), indent=2) + "\n")
    axes = plotting.plot_verification(result, supports=case.bridge.support_positions)
    figure = plotting.save_figure(axes[0], outdir / "verification.png")
    return result, json_path, figure


def _cmd_verify(args, out):
    case = _load(args)
    args.kind, args.noise_std = _sensor_kind_and_noise(args, case)
    layouts = args.layout
    for layout in layouts:
        case.bridge.check_on_bridge(layout, "layout", "--layout")
    outdir = Path(args.out)
    args.verify_json = args.json
    result, json_path, figure = _run_verification(args, case, layouts, None, outdir)
    out(result.summary())
    out(f"verification written to {json_path}; figure: {figure}")
    return 0


def _cmd_diagnose(args, out):
    import json

    from . import plotting
    from .io.csvio import atomic_write_text, read_crossings
    from .diagnosis.diagnose import diagnose
    from .inference.screening import check_data_scale

    case = _load(args)
    data = read_crossings(args.data, case.sensors)
    nominal = case.influence_lines(sensors=case.sensors.subset(
        [case.sensors.names.index(n) for n in data.sensor_names]), positions=data.crossings[0].positions)
    check_data_scale(data, dict(zip(data.sensor_names, nominal.predictions)), data.sensor_names,
                     source=str(args.data))
    result = diagnose(case, data, progress=_progress(args, "diagnose") if len(data) * 8 >= 20 else None)
    outdir = Path(args.out)
    supports = case.bridge.support_positions
    figures = [
        plotting.save_figure(plotting.plot_residual_map(result), outdir / "residual_map.png"),
        plotting.save_figure(plotting.plot_shrinkage(result), outdir / "shrinkage.png"),
        plotting.save_figure(plotting.plot_ei_before_after(result, supports=supports), outdir / "ei_before_after.png"),
    ]
    json_path = args.json if args.json is not None else outdir / "diagnosis.json"
    atomic_write_text(json_path, json.dumps(result.to_dict(), indent=2) + "\n")
    out(result.summary())
    out(f"diagnosis written to {json_path}; figures: " + ", ".join(str(p) for p in figures))
    return 0


def _cmd_report(args, out):
    from .io.csvio import atomic_write_text, read_crossings
    from .report import build_report

    case = _load(args)
    data = read_crossings(args.data, case.sensors) if args.data is not None else None
    progress = None if args.quiet else (lambda msg: print(f"sensorplan report: {msg}", file=sys.stderr, flush=True))
    report = build_report(case, data=data, count=args.count, criterion=args.criterion, n_scenarios=args.scenarios,
                          seed=args.seed, progress=progress)
    path = Path(args.out) / "report.html"
    atomic_write_text(path, report.html)
    out(report.design.summary())
    out(f"report with {len(report.sections)} sections written to {path}")
    return 0


def build_parser():
    parser = argparse.ArgumentParser(
        prog="sensorplan",
        description="Sensor placement and Bayesian EI identification for bridges.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("simulate", help="write predicted or noisy synthetic crossings (CSV)",
                       epilog=_EPILOG_SIMULATE, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(p)
    p.add_argument("--crossings", type=int, default=1, help="number of crossings (default 1)")
    p.add_argument("--noise", action="store_true", help="add noise from the case's noise model")
    p.add_argument("--seed", type=int, help="random seed (required with --noise)")
    p.add_argument("--out", type=Path, required=True, help="output CSV file")
    p.set_defaults(handler=_cmd_simulate)

    p = sub.add_parser("informativeness", help="Fisher informativeness curves and identifiability",
                       epilog=_EPILOG_INFORMATIVENESS,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(p)
    p.add_argument("--positions", type=_parse_positions,
                   help="candidate tiltmeter positions in m, e.g. 2.5,5,10 (default: the case's sensors)")
    p.add_argument("--crossings", type=int, default=1, help="number of crossings (default 1)")
    p.add_argument("--parameterisation", choices=["ei", "log_ei", "compliance"], default="ei",
                   help="parameters of the curves (default ei, as in the paper)")
    p.add_argument("--kind", choices=["rotation", "deflection"],
                   help="kind of the --positions sensors (default: the kind of the case's sensors)")
    p.add_argument("--noise-std", type=float, help="noise std of the --positions sensors (SI: rad or m)")
    p.add_argument("--out", type=Path, default=Path("sensorplan-out"), help="output folder")
    p.set_defaults(handler=_cmd_informativeness)

    p = sub.add_parser("invert", help="Bayesian identification of EI(x) from crossings (CSV)",
                       epilog=_EPILOG_INVERT, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(p)
    p.add_argument("--data", type=Path, required=True, help="crossings CSV (crossing,position_m,<sensors>)")
    p.add_argument("--elements", type=int, help="number of elements of the inversion mesh")
    p.add_argument("--out", type=Path, default=Path("sensorplan-out"), help="output folder for figures")
    p.add_argument("--json", type=Path, help="JSON file of the posterior (default OUT/posterior.json)")
    p.set_defaults(handler=_cmd_invert)

    p = sub.add_parser("recommend", help="recommend where to put R sensors (certified layout + baselines)",
                       epilog=_EPILOG_RECOMMEND, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(p)
    p.add_argument("--count", type=int, help="number of new sensors R (default: as many as the case has)")
    p.add_argument("--criterion", choices=["D", "A", "E", "Ds"], default="D", help="design criterion (default D)")
    p.add_argument("--spacing", type=float, default=0.5, help="candidate grid spacing in m (default 0.5)")
    p.add_argument("--exclude", type=_parse_zones, help="exclusion zones start:stop in m, e.g. 14:16,29:30")
    p.add_argument("--fixed", type=_parse_positions, help="existing sensors in m, e.g. 11,19")
    p.add_argument("--min-spacing", type=float, default=0.0, help="minimum distance between sensors in m")
    p.add_argument("--kind", choices=["rotation", "deflection"],
                   help="sensor kind (default: the kind of the case's sensors)")
    p.add_argument("--noise-std", type=float,
                   help="noise std of the new sensors in SI units (rad or m); default: the case's sensors'")
    p.add_argument("--crossings", type=int, default=1, help="crossings per measurement campaign (default 1)")
    p.add_argument("--springs", action="store_true", help="treat the spring stiffnesses as nuisance parameters")
    p.add_argument("--solver", choices=["auto", "fast", "cvxpy"], default="auto", help="relaxation solver")
    p.add_argument("--seed", type=int, default=0, help="seed of the random baseline (default 0)")
    p.add_argument("--out", type=Path, default=Path("sensorplan-out"), help="output folder for figures")
    p.add_argument("--json", type=Path, help="JSON file of the design (default OUT/design.json)")
    _add_verify_arguments(p, with_flag=True)
    p.set_defaults(handler=_cmd_recommend)

    p = sub.add_parser("verify", help="verify layouts by Bayesian inversion of synthetic damage",
                       epilog=_EPILOG_VERIFY, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(p)
    p.add_argument("--layout", type=_parse_positions, action="append", required=True,
                   help="sensor positions in m, e.g. 3.5,8,12 (repeat for several layouts)")
    p.add_argument("--kind", choices=["rotation", "deflection"],
                   help="sensor kind (default: the kind of the case's sensors)")
    p.add_argument("--noise-std", type=float,
                   help="noise std of the new sensors in SI units (rad or m); default: the case's sensors'")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--out", type=Path, default=Path("sensorplan-out"), help="output folder for figures")
    p.add_argument("--json", type=Path, help="JSON file (default OUT/verification.json)")
    _add_verify_arguments(p, with_flag=False)
    p.set_defaults(handler=_cmd_verify)

    p = sub.add_parser("diagnose", help="diagnose the sim-to-real gap between the model and crossings (CSV)",
                       epilog=_EPILOG_DIAGNOSE, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(p)
    p.add_argument("--data", type=Path, required=True, help="crossings CSV (crossing,position_m,<sensors>)")
    p.add_argument("--out", type=Path, default=Path("sensorplan-out"), help="output folder for figures")
    p.add_argument("--json", type=Path, help="JSON file (default OUT/diagnosis.json)")
    p.set_defaults(handler=_cmd_diagnose)

    p = sub.add_parser("report", help="one self-contained HTML report: model, layout, verification, data",
                       epilog=_EPILOG_REPORT, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_case_arguments(p)
    p.add_argument("--data", type=Path, help="measured crossings CSV (adds identified EI and the gap diagnosis)")
    p.add_argument("--count", type=int, help="number of sensors to place (default: as many as the case has)")
    p.add_argument("--criterion", choices=["D", "A", "E", "Ds"], default="D", help="design criterion (default D)")
    p.add_argument("--scenarios", type=int, default=6, help="damage locations in the verification (default 6)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--out", type=Path, required=True, help="output folder (report.html)")
    p.set_defaults(handler=_cmd_report)
    return parser


def _add_verify_arguments(p, *, with_flag):
    if with_flag:
        p.add_argument("--verify", action="store_true",
                       help="verify the layout and the baselines by inversion of synthetic damage")
    p.add_argument("--scenarios", type=int, default=8, help="damage locations scanned (default 8)")
    p.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    p.add_argument("--verify-crossings", type=int, default=10,
                   help="crossings simulated per scenario (default 10)")


def _limit_blas_threads():
    """One BLAS thread unless the user chose otherwise (before numpy loads).

    sensorplan's dense algebra works on small matrices (tens to a few
    hundred parameters), where multi-threaded BLAS only adds overhead and,
    on a busy machine, stalls (measured 10-100x slower in
    studies/benchmarks/bench_inversion.py).
    """
    if "numpy" in sys.modules:
        return
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def main(argv=None):
    """Run the command line; returns the exit code."""
    _limit_blas_threads()
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code) if exc.code is not None else 0
    out = (lambda *a, **k: None) if args.quiet else (lambda *a, **k: print(*a, **k))
    try:
        return args.handler(args, out)
    except (SensorplanError, OSError) as exc:
        if args.debug:
            raise
        message = " ".join(str(exc).split())
        print(f"sensorplan {args.command}: error: {message}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("sensorplan: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
