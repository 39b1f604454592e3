"""``sensorplan simulate``: predicted or noisy synthetic crossings (CSV)."""

from .._errors import SensorplanError
from ._common import (
    MAX_CROSSINGS,
    SEED,
    add_case_arguments,
    add_speed_argument,
    integer,
    load_case,
    output_file,
)

NAME = "simulate"
OUT_IS_FILE = True  # --out is the CSV file, not a folder
HELP = "write predicted or noisy synthetic crossings (CSV)"
EPILOG = """example:
  sensorplan simulate --example openlab-like --crossings 5 --noise --seed 1 --out crossings.csv
"""


def add_arguments(p):
    add_case_arguments(p)
    add_speed_argument(p)
    p.add_argument("--crossings", type=integer(1, MAX_CROSSINGS), default=1, help="number of crossings (default 1)")
    p.add_argument("--noise", action="store_true", help="add noise from the case's noise model")
    p.add_argument("--seed", type=SEED, help="random seed (required with --noise)")
    p.add_argument("--out", type=output_file, required=True, help="output CSV file")


def run(args, out, files):
    import numpy as np

    from ..io.csvio import format_crossings
    from ..model.simulate import simulate_crossings

    case = load_case(args)
    if args.noise and args.seed is None:
        raise SensorplanError("--noise needs --seed S so that the data can be reproduced.")
    rng = None if args.seed is None else np.random.default_rng(args.seed)
    crossings = simulate_crossings(case, args.crossings, noise=args.noise, rng=rng)
    files.write_text(args.out, format_crossings(crossings))
    kind = "noisy synthetic" if args.noise else "predicted"
    out(f"wrote {len(crossings)} {kind} crossing(s) of '{case.name}' "
        f"({case.sweep.n_loads} load positions, sensors {', '.join(case.sensors.names)}; "
        f"rotation in rad, deflection in m) to {args.out}")
    return 0
