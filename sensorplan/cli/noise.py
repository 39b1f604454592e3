"""``sensorplan noise``: a logger record -> each channel's noise (white, correlated, wander) and its Allan deviation."""

from pathlib import Path

from ._common import add_case_arguments, input_file, output_file, real

NAME = "noise"
HELP = "estimate each sensor's noise (white, correlated, wander) from the quiet parts of a logger record"
EPILOG = """example:
  sensorplan noise --config bridge.toml --timeseries logger.csv --json noise.json --out out/noise
  sensorplan noise --config bridge.toml --timeseries logger.csv --write-case bridge-noise.toml --speed 1.5

The logger file is read as by `sensorplan crossings` (time_s or time_ms, or
ISO 8601 timestamps; units from the case's [logger] section: tilt_unit rad,
deg, mdeg, mm/m or urad; deflection_unit m or mm; time_unit s or ms).  The
quiet parts (no vehicle, no burst) of at least --min-quiet seconds are used.
Per channel: white std (per sample), correlated (Ornstein-Uhlenbeck) std
and correlation time, random walk (per sqrt(s)), each with its standard
error, and the Allan deviation of the data against the fitted model.
--write-case writes the case with the white std in [sensors] noise_std and
the rest in [noise] (see docs/noise.md).
"""

SPEED = real(0.0, 200.0, what="a speed in m/s", low_open=True)


def add_arguments(p):
    add_case_arguments(p)
    p.add_argument("--timeseries", type=input_file, required=True,
                   help="logger export CSV: time_s (or time_ms, or ISO timestamps),<sensor names>")
    p.add_argument("--json", type=output_file, help="JSON file of the estimates (default: none)")
    p.add_argument("--out", type=Path, help="output folder for the Allan-deviation figure (default: none)")
    p.add_argument("--write-case", type=output_file,
                   help="write the case with the estimated noise to this TOML file")
    p.add_argument("--speed", type=SPEED,
                   help="crossing speed in m/s written with the noise model (default: the case's [noise] speed)")
    p.add_argument("--rate", type=real(0.0, 1e6, what="a rate in Hz", low_open=True),
                   help="fit every k-th sample, at most this rate in Hz (default: every sample)")
    p.add_argument("--min-quiet", type=real(1.0, 86400.0, what="a time in s"), default=60.0,
                   help="shortest quiet segment used, in s (default 60)")


def _speed(case, speed):
    """The crossing speed written with the noise model: --speed, else the case's [noise] speed."""
    from .._errors import ConfigError

    speed = speed if speed is not None else getattr(case.noise, "speed", None)
    if speed is None:
        raise ConfigError("--write-case needs the crossing speed of the time-correlated noise model; give --speed "
                          "(m/s) or [noise] speed in the case.")
    return speed


def _noise_case(case, result, speed):
    """The case with the estimated noise of the record's channels (other sensors keep theirs)."""
    from dataclasses import replace

    import numpy as np

    from ..model.noise import NoiseModel

    n = case.sensors.n_sensors
    std = np.array(case.noise.std, dtype=float)
    parts = {key: np.zeros(n) for key in ("correlated_std", "correlation_time_s", "random_walk")}
    for c in result.channels:
        i = case.sensors.names.index(c.name)
        std[i] = c.white_std.value
        for key in parts:
            parts[key][i] = getattr(c, key).value
    return replace(case, noise=NoiseModel(std, 0.0, speed=speed, **parts))


def run(args, out, files):
    from .. import plotting
    from ..acquisition.noise import estimate_noise
    from ..io.config import load_logger_format
    from ..io.logger import read_timeseries
    from ._common import load_case, stage_figure, stage_json

    case = load_case(args)
    speed = _speed(case, args.speed) if args.write_case is not None else None
    logger = load_logger_format(args.config)
    series = read_timeseries(args.timeseries, case.sensors, logger)
    kinds = [case.sensors.kinds[case.sensors.names.index(name)] for name in series.names]
    result = estimate_noise(series, kinds, max_rate=args.rate, min_segment_s=args.min_quiet)
    out(result.summary())
    written = []
    if args.json is not None:
        written.append(f"estimates: {stage_json(files, args.json, result.to_dict())}")
    if args.out is not None:
        figure = stage_figure(files, plotting.plot_allan_deviation(result)[0], args.out / "allan_deviation.png")
        written.append(f"figure: {figure}")
    if args.write_case is not None:
        from ..io.case_writer import case_to_toml

        header = f"{case.name} with the noise estimated by `sensorplan noise` from {args.timeseries}"
        path = files.write_text(args.write_case, case_to_toml(_noise_case(case, result, speed), header=header,
                                                                  logger=logger))
        written.append(f"case: {path}")
    if written:
        out("written: " + "; ".join(written))
    return 0
