"""Option types and checks of the sensor options: kinds, per-kind values, positions with kinds, counts per span.

They return the text or plain values; the commands turn them into design
inputs (``kinds_and_noise``).  Errors name the option.
"""

import argparse

from ._common import MAX_POSITIONS, number


def parse_sensors(text):
    """Positions in m, each optionally followed by ``:kind`` (e.g. 4,10:deflection,16): [(x, kind or None)]."""
    from ..model.sensors import SENSOR_KINDS

    what = "comma-separated positions in m, each optionally with :kind, e.g. 4,10:deflection,16"
    out = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        x, _, kind = part.partition(":")
        value = number(x, f"{what} (in {text!r})")
        kind = kind.strip() or None
        if kind is not None and kind not in SENSOR_KINDS:
            raise argparse.ArgumentTypeError(f"unknown sensor kind {kind!r} in {text!r}; use "
                                             f"{' or '.join(SENSOR_KINDS)}")
        out.append((value, kind))
    if not out:
        raise argparse.ArgumentTypeError("give at least one position in m")
    if len(out) > MAX_POSITIONS:
        raise argparse.ArgumentTypeError(f"at most {MAX_POSITIONS} positions; got {len(out)}")
    if len(set(out)) != len(out):
        raise argparse.ArgumentTypeError(f"a sensor is given twice in {text!r}")
    return out


def _as_argparse_type(check, name):
    """An argparse type that runs ``check(text)`` (which raises ConfigError naming the flag) and keeps the text."""

    def parse(text):
        from .._errors import ConfigError

        try:
            check(text)
        except ConfigError as exc:
            raise argparse.ArgumentTypeError(str(exc).split(": ", 1)[-1]) from None
        return text

    parse.__name__ = name
    return parse


def _check_scheduler(text):
    from .._errors import ConfigError

    if not text.strip() or any(c.isspace() for c in text):
        raise ConfigError(f"--scheduler: expected a Dask scheduler address such as tcp://127.0.0.1:8786 or 'local'; "
                          f"got {text!r}")


def _flag_error(flag, message):
    from .._errors import ConfigError

    return ConfigError(f"{flag}: {message}")


def check_kind(kind, flag):
    from ..model.sensors import SENSOR_KINDS

    if kind not in SENSOR_KINDS:
        raise _flag_error(flag, f"unknown sensor kind {kind!r}; use {' or '.join(SENSOR_KINDS)}")
    return kind


def parse_kinds(text, flag="--kind"):
    """Comma-separated sensor kinds, distinct and known (a ConfigError naming ``flag`` otherwise)."""
    kinds = tuple(check_kind(k.strip(), flag) for k in text.split(",") if k.strip())
    if not kinds or len(set(kinds)) != len(kinds):
        raise _flag_error(flag, f"give distinct sensor kinds, e.g. rotation,deflection; got {text!r}")
    return kinds


def parse_per_kind(text, flag, *, allow_plain=True, low_open=True):
    """``value`` or ``kind=value,...`` (positive, or non-negative with ``low_open=False``); None stays None."""
    if text is None:
        return None
    bound = "positive" if low_open else "non-negative"
    if "=" not in text and allow_plain:
        return _kind_number(text, flag, bound, low_open)
    out = {}
    for part in text.split(","):
        kind, sep, value = part.partition("=")
        if not sep:
            raise _flag_error(flag, f"expected kind=value pairs, e.g. rotation=1,deflection=3; got {part!r}")
        out[check_kind(kind.strip(), flag)] = _kind_number(value, flag, bound, low_open)
    return out


def _kind_number(text, flag, bound, low_open):
    value = number(text, f"a {bound} number", error=lambda message: _flag_error(flag, message))
    if value < 0 or (low_open and value == 0):
        raise _flag_error(flag, f"must be {bound}; got {text!r}")
    return value


def parse_counts(text, flag):
    """Comma-separated whole counts per span, e.g. 1,0,1 (None stays None)."""
    if text is None:
        return None
    try:
        counts = [int(v) for v in text.split(",")]
        if not counts:
            raise ValueError(text)
    except ValueError:
        raise _flag_error(flag, f"expected one whole count per span, e.g. 1,1; got {text!r}") from None
    if any(c < 0 for c in counts):
        raise _flag_error(flag, f"counts must be non-negative; got {text!r}")
    return counts


def kinds_and_noise(args, case, extra=()):
    """Kinds of new sensors (``--kind``, default the case's) and their noise std per kind (``--noise-std``).

    ``--noise-std`` may also name the ``extra`` kinds (e.g. of existing sensors); their values are
    returned too when given.
    """
    kinds = parse_kinds(args.kind) if args.kind else (case.default_kind,)
    noise = parse_per_kind(args.noise_std, "--noise-std")
    if isinstance(noise, float):
        if len(kinds) > 1:
            raise _flag_error("--noise-std", f"give one value per kind, e.g. {kinds[0]}=5e-6,{kinds[1]}=1e-4")
        noise = {kinds[0]: noise}
    unknown = sorted(set(noise or {}) - set(kinds) - set(extra))
    if unknown:
        raise _flag_error("--noise-std", f"kind {unknown[0]} is not among the kinds of --kind ({','.join(kinds)})")
    out = {k: _kind_noise(case, k, (noise or {}).get(k), len(kinds) > 1) for k in kinds}
    return kinds, out | {k: case.noise_std_for(k, v) for k, v in (noise or {}).items() if k not in out}


def _kind_noise(case, kind, value, several):
    if value is not None or not several:
        return case.noise_std_for(kind, value)
    from .._errors import ConfigError

    try:
        return case.noise_std_for(kind)
    except ConfigError:
        unit = "rad" if kind == "rotation" else "m"
        raise _flag_error("--noise-std", f"no noise std for the new {kind} sensors (the case has none to take it "
                                         f"from); give it as {kind}=VALUE in {unit}") from None


KINDS = _as_argparse_type(lambda text: parse_kinds(text), "kinds")
PER_KIND = _as_argparse_type(lambda text: parse_per_kind(text, "value"), "per_kind")
COUNTS = _as_argparse_type(lambda text: parse_counts(text, "counts"), "counts")
SCHEDULER = _as_argparse_type(_check_scheduler, "scheduler")
