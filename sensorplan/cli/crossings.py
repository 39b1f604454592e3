"""``sensorplan crossings``: a data logger's record -> crossings CSV (readings against load position)."""

from ._common import (
    add_case_arguments,
    input_file,
    output_file,
    real,
    stage_figure,
    stage_json,
)

SPEED = real(0.0, 200.0, what="a speed in m/s", low_open=True)

NAME = "crossings"
OUT_IS_FILE = True  # --out is the CSV file, not a folder
HELP = "find the crossings in a logger record and write them as a crossings CSV"
EPILOG = """example:
  sensorplan crossings --config bridge.toml --timeseries logger.csv --out out/crossings.csv

The logger file has a column time_s and one column per sensor name (units as
in the case's [logger] section, default rad / m); temperature columns named
in [logger] temperature_columns are averaged per crossing.

An event is accepted only when the case's vehicle explains it significantly
better than wander + noise (a generalised likelihood ratio test whose
threshold lets chance through --false-events-per-day times per day of record,
default once).  The noise model in time is the case's [noise] section
(correlated_std, correlation_time_s, random_walk); without it the noise is
estimated from the record and the output says so (run 'sensorplan noise
--write-case' on a quiet record for a better one).  A record with no vehicle
ends with one line naming its strongest candidate and the threshold (exit 1).
"""


def add_arguments(p):
    add_case_arguments(p)
    p.add_argument("--timeseries", type=input_file, required=True, help="logger export CSV: time_s,<sensor names>")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--speed", type=SPEED, help="known constant speed in m/s (only entry times are fitted)")
    group.add_argument("--axle-times", type=input_file,
                       help="axle-detector CSV: time_s (front axle at x = 0)[,speed_m_s], one row per vehicle")
    p.add_argument("--min-speed", type=SPEED, default=0.3, help="slowest plausible speed in m/s (default 0.3)")
    p.add_argument("--max-speed", type=SPEED, default=40.0, help="fastest plausible speed in m/s (default 40)")
    p.add_argument("--quiet-gap", type=real(0.0, 86400.0, what="a time in s", low_open=True), default=3.0,
                   help="minimum quiet time between two vehicles in s (default 3)")
    p.add_argument("--max-rms", type=real(1.0, 1e6, what="a ratio to the noise std"), default=2.0,
                   help="largest accepted whitened fit rms, 1 = the noise model (default 2)")
    p.add_argument("--false-events-per-day", type=real(0.0, 1e6, what="a rate per day", low_open=True),
                   default=1.0, help="false events the test lets through per day of record (default 1)")
    p.add_argument("--out", type=output_file, required=True, help="crossings CSV to write (crossing,position_m,...)")
    p.add_argument("--json", type=output_file, help="events JSON (default: OUT with suffix .json)")
    p.add_argument("--figure", type=output_file,
                   help="figure of the record and the fits (default: OUT with suffix .png)")


def run(args, out, files):
    from .. import plotting
    from .._errors import ConfigError, DataError
    from ..acquisition import extract_crossings
    from ..io.config import load_logger_format
    from ..io.csvio import format_crossings
    from ..io.logger import read_axle_times, read_timeseries
    from ._common import load_case

    if args.min_speed >= args.max_speed:
        raise ConfigError(f"--min-speed {args.min_speed:g} m/s is not below --max-speed {args.max_speed:g} m/s; "
                          "give --min-speed below --max-speed.")
    if args.speed is not None and not args.min_speed <= args.speed <= args.max_speed:
        raise ConfigError(f"--speed {args.speed:g} m/s is outside the plausible speeds --min-speed "
                          f"{args.min_speed:g} to --max-speed {args.max_speed:g} m/s; give the speed in m/s or widen "
                          "the range.")
    case = load_case(args)
    series = read_timeseries(args.timeseries, case.sensors, load_logger_format(args.config))
    axle_times = axle_speeds = None
    if args.axle_times is not None:
        axle_times, axle_speeds = read_axle_times(args.axle_times)
    result = extract_crossings(case, series, speed=args.speed, axle_times=axle_times, axle_speeds=axle_speeds,
                               speed_range=(args.min_speed, args.max_speed), quiet_gap=args.quiet_gap,
                               max_rms=args.max_rms, false_events_per_day=args.false_events_per_day)
    if result.crossings is None:
        raise DataError(f"{args.timeseries}: {result.verdict()}; check the units in [logger] and the speed range "
                        "(--min-speed, --max-speed) if vehicles did cross.")
    csv_path = files.write_text(args.out, format_crossings(result.crossings))
    json_path = stage_json(files, args.json or args.out.with_suffix(".json"), result.to_dict())
    figure = stage_figure(files, plotting.plot_crossing_events(result, series)[0],
                          args.figure or args.out.with_suffix(".png"))
    out(result.summary())
    out(f"{len(result.accepted)} crossing(s) written to {csv_path}; events: {json_path}; figure: {figure}")
    return 0
