"""``sensorplan informativeness``: Fisher informativeness curves and identifiability."""

from ._common import (
    MAX_CROSSINGS,
    NOISE_STD,
    add_case_arguments,
    add_speed_argument,
    check_layouts,
    integer,
    load_case,
    parse_positions,
    stage_figure,
)

NAME = "informativeness"
HELP = "Fisher informativeness curves and identifiability"
EPILOG = """example:
  sensorplan informativeness --example simply-supported --positions 0,5,10,15,20 --out out/info
"""


def add_arguments(p):
    from pathlib import Path

    add_case_arguments(p)
    add_speed_argument(p)
    p.add_argument("--positions", type=parse_positions,
                   help="candidate tiltmeter positions in m, e.g. 2.5,5,10 (default: the case's sensors)")
    p.add_argument("--crossings", type=integer(1, MAX_CROSSINGS), default=1, help="number of crossings (default 1)")
    p.add_argument("--parameterisation", choices=["ei", "log_ei", "compliance"], default="ei",
                   help="parameters of the curves (default ei, as in the paper)")
    p.add_argument("--kind", choices=["rotation", "deflection"],
                   help="kind of the --positions sensors (default: the kind of the case's sensors)")
    p.add_argument("--noise-std", type=NOISE_STD, help="noise std of the --positions sensors (SI: rad or m)")
    p.add_argument("--out", type=Path, default=Path("sensorplan-out"), help="output folder")


def run(args, out, files):
    from .. import plotting
    from ..io.csvio import format_table
    from ..model.fisher import informativeness

    case = load_case(args)
    if args.positions is not None:
        check_layouts(case, [args.positions], "--positions")
    result = informativeness(case, positions=args.positions, kind=args.kind, noise_std=args.noise_std,
                             n_crossings=args.crossings, parameterisation=args.parameterisation)
    blocks, ident = result.blocks, result.identifiability
    csv_path = args.out / "informativeness.csv"
    header = ["x_left_m", "x_right_m", *blocks.sensors.names]
    files.write_text(csv_path, format_table(header, [blocks.edges[:-1], blocks.edges[1:], *blocks.curves]))
    supports = result.supports_m
    figures = [
        stage_figure(files, plotting.plot_informativeness(blocks, supports=supports, ei=case.ei), args.out / "informativeness.png"),
        stage_figure(files, plotting.plot_spectrum(ident), args.out / "spectrum.png"),
        stage_figure(files, plotting.plot_eigenvectors(ident, supports=supports), args.out / "eigenvectors.png"),
    ]
    out(result.summary())
    out(f"curves ({args.parameterisation}, unit {blocks.unit}) written to {csv_path}")
    out("figures: " + ", ".join(str(p) for p in figures))
    return 0
