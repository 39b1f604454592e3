"""``sensorplan invert``: Bayesian identification of EI(x) from crossings (CSV)."""

import sys

from ._common import (
    FALSE_ALARM,
    MAX_INVERSION_ELEMENTS,
    SEED,
    add_case_arguments,
    add_out_arguments,
    file_names,
    input_file,
    integer,
    load_case,
    read_data,
    stage_figure,
    stage_json,
)
from ._progress import Progress

NAME = "invert"
HELP = "Bayesian identification of EI(x) from crossings (CSV)"
EPILOG = """example:
  sensorplan simulate --example openlab-like --crossings 10 --noise --seed 1 --out data.csv
  sensorplan invert --example openlab-like --data data.csv --elements 30 --json posterior.json --out out/invert
"""


def add_arguments(p):
    add_case_arguments(p)
    p.add_argument("--data", type=input_file, required=True, help="crossings CSV (crossing,position_m,<sensors>)")
    p.add_argument("--elements", type=integer(1, MAX_INVERSION_ELEMENTS),
                   help="number of elements of the inversion mesh")
    p.add_argument("--false-alarm", type=FALSE_ALARM, default=0.05,
                   help="false-alarm rate of the damage detector on undamaged bridges (default 0.05)")
    p.add_argument("--nuisance", choices=["smooth", "levels"], default="smooth",
                   help="what an undamaged bridge may do: a smooth EI trend per span (default) or one EI "
                        "factor per span (plus the elastic springs either way)")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the detector's threshold simulation (default 0)")
    p.add_argument("--no-detect", action="store_true",
                   help="identify EI without the damage detector (the verdict then rests on the band alone)")
    add_out_arguments(p, json_default="posterior.json")


def run(args, out, files):
    import warnings

    from .. import plotting
    from .._errors import SensorplanError, SensorplanWarning
    from ..inference.inversion import invert
    from ..inference.screening import check_case_data_scale
    from ..model.structure import Mesh

    case = load_case(args)
    data = read_data(args.data, case, "invert")
    if args.elements is not None:
        if args.elements < case.bridge.n_spans:
            raise SensorplanError(f"--elements {args.elements} is fewer than the {case.bridge.n_spans} spans; give "
                                  f"at least one element per span.")
        case = case.with_mesh(Mesh.uniform(case.bridge, args.elements))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SensorplanWarning)
        check_case_data_scale(case, data, source=str(args.data))  # a unit slip is refused before the stage line
        Progress("invert", quiet=args.quiet).stage(
            f"identifying EI on {case.n_elements} elements from {len(data)} crossing(s) of {data.n_sensors} "
            "sensor(s)" + ("" if args.no_detect else ", then calibrating the damage detector"))
        result = invert(case, data, check_scale=str(args.data), false_alarm=args.false_alarm,
                        nuisance=args.nuisance, rng=args.seed, detect=not args.no_detect)
    for message in dict.fromkeys(str(w.message) for w in caught):  # the data checks ran twice: each warning once
        print(f"sensorplan invert: warning: {message}", file=sys.stderr)
    figures = [stage_figure(files, plotting.plot_ei_posterior(result, supports=case.bridge.support_positions),
                            args.out / "ei_posterior.png")]
    for name, file_name in zip(result.sensor_names, file_names(result.sensor_names)):
        figures.append(stage_figure(files, plotting.plot_fit(result, name), args.out / f"fit_{file_name}.png"))
    json_path = stage_json(files, args.json or args.out / "posterior.json", result.to_dict())
    out(result.summary())
    out(f"posterior written to {json_path}; figures: " + ", ".join(str(p) for p in figures))
    return 0
