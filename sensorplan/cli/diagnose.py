"""``sensorplan diagnose``: where model and measurements disagree, and why."""

from pathlib import Path

from ._common import (
    add_case_arguments,
    add_out_arguments,
    load_case,
    progress,
    stage_figure,
    stage_json,
)

NAME = "diagnose"
HELP = "diagnose the sim-to-real gap between the model and crossings (CSV)"
EPILOG = """example:
  sensorplan simulate --example openlab-like --crossings 6 --noise --seed 1 --out data.csv
  sensorplan diagnose --example openlab-like --data data.csv --json diagnosis.json --out out/diagnose
"""


def add_arguments(p):
    add_case_arguments(p)
    p.add_argument("--data", type=Path, required=True, help="crossings CSV (crossing,position_m,<sensors>)")
    add_out_arguments(p, json_default="diagnosis.json")


def run(args, out, files):
    from .. import plotting
    from ..diagnosis.diagnose import diagnose
    from ..inference.screening import check_not_noise_free
    from ..io.csvio import read_crossings

    case = load_case(args)
    data = read_crossings(args.data, case.sensors)
    check_not_noise_free(case, data, source=str(args.data))
    result = diagnose(case, data, progress=progress(args, "diagnose", "effects") if len(data) * 8 >= 20 else None,
                      check_scale=str(args.data))
    supports = case.bridge.support_positions
    figures = [
        stage_figure(files, plotting.plot_residual_map(result), args.out / "residual_map.png"),
        stage_figure(files, plotting.plot_shrinkage(result), args.out / "shrinkage.png"),
        stage_figure(files, plotting.plot_ei_before_after(result, supports=supports), args.out / "ei_before_after.png"),
    ]
    json_path = stage_json(files, args.json or args.out / "diagnosis.json", result.to_dict())
    out(result.summary())
    out(f"diagnosis written to {json_path}; figures: " + ", ".join(str(p) for p in figures))
    return 0
