"""A corpus of hostile inputs run against every command of the CLI, each in its own process.

What it checks
--------------
Every case runs ``python -m sensorplan <command> ... --quiet`` as a separate
process in a fresh temporary folder (working directory ``work/`` inside it,
``TMPDIR`` pointing to an empty folder beside it), with a 120 s timeout and
a 4 GiB address-space limit (``resource.setrlimit(RLIMIT_AS)`` in
``preexec_fn``).  A case passes when

* the process ends within the timeout, neither killed nor out of memory;
* no ``Traceback`` appears on stdout or stderr;
* exit code 0: every file written lies under the output targets of the
  command line (``--out``, ``--json``, ``--figure``, ``--write-case``), the
  CSV files hold finite numbers, the JSON files parse without NaN/Infinity;
  or exit code 1: exactly one stderr line ``sensorplan ...: error: ...``
  naming the fields the case lists (the thing at fault, not a bystander),
  and not a single new file anywhere in the temporary folder;
* the expected outcome when the case states one (``ok`` or ``error``);
* nothing is left in ``TMPDIR`` (staged outputs are cleaned up).

Classes of cases (``CLASSES``): numerically extreme values that pass the
range checks, sizes without a guard, CLI options skipping checks, data
without information, non-atomic outputs, names used as file names, messages
blaming the wrong thing, swallowed failures; hostile case files (TOML) go
to every command that takes ``--config``, hostile crossings CSVs to
invert/diagnose/report, hostile logger records to crossings.

Run it (2 processes at a time by default; ``-k WORD`` runs the cases whose
name contains WORD)::

    python studies/robustness/hostile_corpus.py [-j 2] [-k WORD] [--list]

Last full run: ``RESULT`` below (updated by hand after a full run; the read-only folder cases run only
when not root).
"""

import argparse
import json
import math
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

RESULT = ("344/344 cases pass (atomic 4, blame 5, data 43, extreme 22, logger 19, name 50, option 17, size 15, "
          "swallow 1, toml 168), run as root with -j 2")

TIMEOUT_S = 120.0
MEMORY_BYTES = 4 * 2**30
CLASSES = ("extreme", "size", "option", "data", "atomic", "name", "blame", "swallow", "toml", "logger")
COMMANDS = ("simulate", "crossings", "informativeness", "detectability", "invert", "recommend", "verify",
            "diagnose", "report")
OUTPUT_OPTIONS = ("--out", "--json", "--figure", "--write-case")
# the sensorplan of this checkout, whatever is installed (the cases run in temporary folders)
ROOT = Path(__file__).resolve().parents[2]
ENV = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
           PYTHONDONTWRITEBYTECODE="1")


@dataclass
class Case:
    name: str
    cls: str
    argv: list
    files: dict = field(default_factory=dict)  # file name -> text (str) or bytes, written into work/
    expect: str = "any"  # "ok", "error" or "any"
    fields: tuple = ()  # substrings the error line must contain


# --------------------------------------------------------------------------
# fixtures: base case files, crossings and a logger record
# --------------------------------------------------------------------------

def _example(name="openlab-like"):
    return resources.files("sensorplan.examples").joinpath(f"{name}.toml").read_text("utf-8")


def _run_quiet(argv, cwd):
    subprocess.run([sys.executable, "-m", "sensorplan", *argv, "--quiet"], cwd=cwd, env=ENV, check=True,
                   capture_output=True)


def make_fixtures(folder):
    """data.csv (noisy), clean.csv (noise-free, by simulate itself), log.csv + logcase.toml (a logger record)."""
    import numpy as np

    folder = Path(folder)
    _run_quiet(["simulate", "--example", "openlab-like", "--crossings", "2", "--noise", "--seed", "1",
                "--out", "data.csv"], folder)
    _run_quiet(["simulate", "--example", "openlab-like", "--crossings", "2", "--out", "clean.csv"], folder)
    # a logger record: the noise-free crossing of simulate played back at 2 m/s (entry at 20 s), plus noise
    text = (folder / "clean.csv").read_text("utf-8").splitlines()
    rows = [r.split(",") for r in text[1:] if r.startswith("1,")]
    z = np.array([float(r[1]) for r in rows])
    values = np.array([[float(v) for v in r[2:4]] for r in rows]).T
    t = np.arange(0.0, 60.0, 0.1)
    rng = np.random.default_rng(3)
    log = ["time_s,PE1,PE2"]
    for k, tk in enumerate(t):
        zk = 2.0 * (tk - 20.0)
        a, b = (np.interp(zk, z, v, left=0.0, right=0.0) + 5e-6 * rng.standard_normal() for v in values)
        log.append(f"{tk:.2f},{1e6 * a:.6e},{1e6 * b:.6e}")
    (folder / "log.csv").write_text("\n".join(log) + "\n", encoding="utf-8")
    (folder / "logcase.toml").write_text(_example() + '\n[logger]\ntilt_unit = "urad"\n', encoding="utf-8")
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def _csv_rows(fixtures, name="data.csv"):
    lines = fixtures[name].decode("utf-8").splitlines()
    return lines[0].split(","), [r.split(",") for r in lines[1:]]


def _csv(header, rows):
    return ",".join(header) + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows)


def _map_data(fixtures, func, header=None, name="data.csv"):
    head, rows = _csv_rows(fixtures, name)
    return _csv(header or head, [func(r) for r in rows if func(r) is not None])


def _log_rows(fixtures):
    lines = fixtures["log.csv"].decode("utf-8").splitlines()
    return lines[0].split(","), [r.split(",") for r in lines[1:]]


# --------------------------------------------------------------------------
# the cases
# --------------------------------------------------------------------------

EX = ["--example", "openlab-like"]
SS = ["--example", "simply-supported"]


def _sub(old, new):
    def mutate(text):
        if old not in text:
            raise KeyError(old)
        return text.replace(old, new)
    return mutate


# hostile case files: (label, mutation, fields the error must name); every one is fed to every command
HOSTILE_TOML = [
    ("span-1e300", _sub("spans = [15.0, 15.0]", "spans = [1e300, 15.0]"), ("spans",)),
    ("span-subnormal", _sub("spans = [15.0, 15.0]", "spans = [5e-324, 15.0]"), ("spans",)),
    ("span-negative", _sub("spans = [15.0, 15.0]", "spans = [-15.0, 15.0]"), ("spans",)),
    ("span-in-mm", _sub("spans = [15.0, 15.0]", "spans = [15000.0, 15000.0]"), ("spans",)),
    ("ei-in-kNm2", _sub("ei = [7.5e9, 1.0e10]", "ei = [7.5e6, 1.0e7]"), ("EI", "kN m^2")),
    ("ei-nan", _sub("ei = [7.5e9, 1.0e10]", "ei = [nan, 1.0e10]"), ("ei",)),
    ("ei-sign-flip", _sub("ei = [7.5e9, 1.0e10]", "ei = [-7.5e9, 1.0e10]"), ("ei",)),
    ("loads-in-kN", _sub("axle_loads = [24.0e3, 24.0e3]", "axle_loads = [24.0, 24.0]"), ("kN",)),
    ("loads-inf", _sub("axle_loads = [24.0e3, 24.0e3]", "axle_loads = [inf, 24.0e3]"), ("axle_loads",)),
    ("positions-in-cm", _sub("positions = [11.0, 19.0]", "positions = [1100.0, 1900.0]"), ("positions",)),
    ("noise-1e-300", _sub("noise_std = 5.0e-6", "noise_std = 1e-300"), ("noise_std",)),
    ("noise-in-urad", _sub("noise_std = 5.0e-6", "noise_std = 5.0"), ("noise_std",)),
    ("name-traversal", _sub('names = ["PE1", "PE2"]', 'names = ["../../evil", "PE2"]'), ("names",)),
    ("name-reserved", _sub('names = ["PE1", "PE2"]', 'names = ["position_m", "PE2"]'), ("position_m",)),
    ("elements-1e9", _sub("elements = 30", "elements = 1000000000"), ("elements",)),
    ("step-1e-300", _sub("step = 0.25", "step = 1e-300"), ("step",)),
    ("not-toml", lambda t: "spans = [15.0,\n", ("TOML",)),
    ("unknown-key", _sub("elements = 30", "elements = 30\nelemnts = 31"), ("elemnts",)),
]

_REQUIRED = {  # what each command needs besides the case
    "simulate": ["--out", "out/x.csv"],
    "crossings": ["--timeseries", "log.csv", "--out", "out/x.csv"],
    "informativeness": ["--out", "out"],
    "detectability": ["--out", "out"],
    "invert": ["--data", "data.csv", "--out", "out"],
    "recommend": ["--count", "2", "--spacing", "2", "--out", "out"],
    "verify": ["--layout", "5,25", "--scenarios", "2", "--out", "out"],
    "diagnose": ["--data", "data.csv", "--out", "out"],
    "report": ["--count", "2", "--spacing", "2", "--scenarios", "2", "--out", "out"],
}


def toml_cases():
    out = []
    text = _example()
    for label, mutate, fields in HOSTILE_TOML:
        body = mutate(text)
        for command in COMMANDS:
            out.append(Case(f"toml/{label}/{command}", "toml", [command, "--config", "case.toml", *_REQUIRED[command]],
                            {"case.toml": body}, "error", fields))
    # the case files that are read (BOM, CRLF) must work everywhere they are cheap to run
    bom = "\ufeff" + text
    out.append(Case("toml/bom/simulate", "toml", ["simulate", "--config", "case.toml", "--out", "out/x.csv"],
                    {"case.toml": bom.encode("utf-8")}, "ok"))
    out.append(Case("toml/crlf/informativeness", "toml", ["informativeness", "--config", "case.toml", "--out", "out"],
                    {"case.toml": text.replace("\n", "\r\n").encode("utf-8")}, "ok"))
    out.append(Case("toml/utf16/simulate", "toml", ["simulate", "--config", "case.toml", "--out", "out/x.csv"],
                    {"case.toml": text.encode("utf-16")}, "error", ("case.toml",)))
    out.append(Case("toml/empty/recommend", "toml", ["recommend", "--config", "case.toml", "--out", "out"],
                    {"case.toml": ""}, "error", ("case.toml",)))
    out.append(Case("toml/directory/simulate", "toml", ["simulate", "--config", ".", "--out", "out/x.csv"],
                    {}, "error", ("--config",)))
    out.append(Case("toml/missing/invert", "toml", ["invert", "--config", "nosuch.toml", "--data", "data.csv",
                                                    "--out", "out"], {}, "error", ("nosuch.toml",)))
    return out


def option_cases():
    """The cases of the command-line options: extreme values, sizes, options that might skip checks."""
    return _extreme_cases() + _size_cases() + _misused_option_cases()


def _extreme_cases():
    """Numerically extreme values inside the declared ranges."""
    c = []
    add = c.append
    add(Case("extreme/recommend-noise-1", "extreme", ["recommend", *EX, "--count", "2", "--noise-std", "1",
                                                      "--out", "out"], expect="error", fields=("--noise-std",)))
    add(Case("extreme/recommend-budget-1e15", "extreme", ["recommend", *SS, "--count", "2", "--spacing", "2",
                                                          "--budget", "1e15", "--cost", "rotation=1e-300",
                                                          "--out", "out"]))
    add(Case("extreme/recommend-min-spacing-2000", "extreme", ["recommend", *EX, "--count", "1",
                                                               "--min-spacing", "2000", "--out", "out"],
             expect="error", fields=("--min-spacing",)))
    add(Case("extreme/recommend-min-spacing-just-fits", "extreme", ["recommend", *SS, "--count", "2",
                                                                    "--min-spacing", "20", "--spacing", "2",
                                                                    "--out", "out"]))
    add(Case("extreme/recommend-crossings-10000", "extreme", ["recommend", *SS, "--count", "2", "--spacing", "2",
                                                              "--crossings", "10000", "--out", "out"]))
    add(Case("extreme/recommend-seed-max", "extreme", ["recommend", *SS, "--count", "2", "--spacing", "2",
                                                       "--seed", str(2**63 - 1), "--out", "out"], expect="ok"))
    add(Case("extreme/recommend-spacing-subnormal", "extreme", ["recommend", *EX, "--spacing", "5e-324",
                                                                "--out", "out"], expect="error",
             fields=("--spacing",)))
    add(Case("extreme/detect-severity-tiny", "extreme", ["detectability", *EX, "--severity", "1e-300",
                                                         "--out", "out"]))
    add(Case("extreme/detect-severity-almost-1", "extreme", ["detectability", *EX, "--severity", "0.999999999",
                                                             "--out", "out"]))
    add(Case("extreme/detect-length-tiny", "extreme", ["detectability", *EX, "--length", "1e-300", "--out", "out"],
             fields=("--length",)))
    add(Case("extreme/detect-false-alarm-tiny", "extreme", ["detectability", *EX, "--false-alarm", "1e-300",
                                                            "--out", "out"]))
    add(Case("extreme/detect-crossings-10000", "extreme", ["detectability", *EX, "--crossings", "10000",
                                                           "--out", "out"]))
    add(Case("extreme/informativeness-noise-tiny", "extreme", ["informativeness", *EX, "--noise-std", "1e-300",
                                                               "--out", "out"], fields=("--noise-std",)))
    add(Case("extreme/informativeness-positions-subnormal", "extreme",
             ["informativeness", *EX, "--positions", "5e-324,30", "--out", "out"]))
    add(Case("extreme/invert-false-alarm-tiny", "extreme", ["invert", *EX, "--data", "data.csv", "--false-alarm",
                                                            "1e-300", "--out", "out"]))
    add(Case("extreme/verify-severity-tiny", "extreme", ["verify", *EX, "--layout", "5,25", "--severity",
                                                         "1e-300", "--scenarios", "2", "--out", "out"]))
    add(Case("extreme/verify-length-1e-300", "extreme", ["verify", *EX, "--layout", "5,25", "--length",
                                                         "1e-300", "--scenarios", "2", "--out", "out"],
             fields=("--length",)))
    add(Case("extreme/crossings-speed-tiny", "extreme", ["crossings", "--config", "logcase.toml", "--timeseries",
                                                         "log.csv", "--speed", "1e-300", "--out", "out/x.csv"],
             fields=("--speed",)))
    add(Case("extreme/crossings-max-rms-huge", "extreme", ["crossings", "--config", "logcase.toml",
                                                           "--timeseries", "log.csv", "--max-rms", "1e6",
                                                           "--out", "out/x.csv"]))
    add(Case("extreme/crossings-quiet-gap-day", "extreme", ["crossings", "--config", "logcase.toml",
                                                            "--timeseries", "log.csv", "--quiet-gap", "86400",
                                                            "--out", "out/x.csv"]))
    add(Case("extreme/crossings-min-above-max-speed", "extreme", ["crossings", "--config", "logcase.toml",
                                                                  "--timeseries", "log.csv", "--min-speed", "50",
                                                                  "--max-speed", "1", "--out", "out/x.csv"],
             expect="error", fields=("--min-speed", "--max-speed")))
    add(Case("extreme/simulate-crossings-10000", "extreme", ["simulate", *SS, "--crossings", "10000",
                                                             "--out", "out/x.csv"]))
    return c


def _size_cases():
    """Sizes without a guard: many positions, candidates, sensors, axles or load steps."""
    c = []
    add = c.append
    add(Case("size/informativeness-1000-positions", "size",
             ["informativeness", *EX, "--positions", ",".join(f"{0.03 * i:.2f}" for i in range(1000)),
              "--out", "out"]))
    add(Case("size/recommend-2000-candidates", "size", ["recommend", *EX, "--count", "2", "--spacing", "0.015",
                                                        "--out", "out"], fields=("--spacing",)))
    add(Case("size/recommend-count-1000", "size", ["recommend", *EX, "--count", "1000", "--out", "out"],
             expect="error", fields=("--count",)))
    add(Case("size/recommend-every-candidate", "size", ["recommend", *SS, "--count", "11", "--spacing", "2",
                                                        "--out", "out"]))
    add(Case("size/recommend-count-61-min-spacing-10", "size", ["recommend", *EX, "--count", "61",
                                                                "--min-spacing", "10", "--out", "out"],
             expect="error", fields=("--count 61", "--min-spacing", "at most 4")))
    add(Case("size/recommend-count-3-min-spacing-10", "size", ["recommend", *EX, "--count", "3",
                                                               "--min-spacing", "10", "--spacing", "1",
                                                               "--out", "out"], expect="ok"))
    add(Case("size/report-count-5-min-spacing-10", "size", ["report", *EX, "--count", "5", "--min-spacing", "10",
                                                             "--out", "out"], expect="error",
             fields=("--count 5", "--min-spacing")))
    add(Case("size/recommend-per-span-min-does-not-fit", "size",
             ["recommend", *EX, "--count", "3", "--per-span-min", "3,0", "--min-spacing", "8", "--out", "out"],
             expect="error", fields=("--per-span-min", "--min-spacing")))
    add(Case("size/recommend-budget-with-spacing", "size",
             ["recommend", *EX, "--count", "3", "--budget", "2", "--min-spacing", "5", "--out", "out"],
             expect="error", fields=("--budget",)))
    add(Case("size/recommend-span-max-zero", "size", ["recommend", *EX, "--count", "2", "--per-span-max", "0,0",
                                                      "--out", "out"], expect="error", fields=("--per-span-max",)))
    add(Case("size/verify-scenarios-max", "size", ["verify", *EX, "--layout", "5,25", "--scenarios", "200",
                                                   "--workers", "16", "--out", "out"]))
    add(Case("size/invert-elements-huge", "size", ["invert", *EX, "--data", "data.csv", "--elements", "100000",
                                                   "--out", "out"], expect="error", fields=("--elements",)))
    add(Case("size/toml-million-axles", "size", ["simulate", "--config", "case.toml", "--out", "out/x.csv"],
             {"case.toml": _sub("axle_offsets = [0.0, 2.0]", f"axle_offsets = [{', '.join(['0.0'] * 200000)}]")(
                 _sub("axle_loads = [24.0e3, 24.0e3]", f"axle_loads = [{', '.join(['1.0'] * 200000)}]")(_example()))},
             expect="error", fields=("axle",)))
    add(Case("size/toml-many-sensors", "size", ["informativeness", "--config", "case.toml", "--out", "out"],
             {"case.toml": _sub('kinds = ["rotation", "rotation"]', "")(_sub("positions = [11.0, 19.0]", "positions = ["
                                + ", ".join(f"{30 * i / 5000:.4f}" for i in range(5000)) + "]")(
                 _sub('names = ["PE1", "PE2"]', "names = [" + ", ".join(f'"S{i}"' for i in range(5000)) + "]")(
                     _example())))}))
    add(Case("size/toml-load-steps", "size", ["invert", "--config", "case.toml", "--data", "data.csv",
                                             "--out", "out"],
             {"case.toml": _sub("step = 0.25", "step = 1e-5")(_example())}, fields=("step",)))
    return c


def _misused_option_cases():
    """Options that might skip checks: outputs on files or folders, unreachable schedulers, clean data."""
    c = []
    add = c.append
    add(Case("option/out-is-a-file", "option", ["informativeness", *EX, "--out", "data.csv"], expect="error",
             fields=("data.csv",)))
    add(Case("option/out-under-a-file", "option", ["recommend", *SS, "--count", "2", "--out", "data.csv/sub"],
             expect="error", fields=("data.csv",)))
    add(Case("option/json-is-a-directory", "option", ["detectability", *EX, "--out", "out", "--json", "."],
             expect="error", fields=("--json",)))
    add(Case("option/data-is-a-directory", "option", ["invert", *EX, "--data", ".", "--out", "out"],
             expect="error", fields=("--data",)))
    add(Case("option/timeseries-missing", "option", ["crossings", *EX, "--timeseries", "nosuch.csv",
                                                     "--out", "out/x.csv"], expect="error", fields=("nosuch.csv",)))
    add(Case("option/axle-times-garbage", "option", ["crossings", "--config", "logcase.toml", "--timeseries",
                                                     "log.csv", "--axle-times", "axles.csv", "--out", "out/x.csv"],
             {"axles.csv": "time_s\nnan\n"}, expect="error", fields=("axles.csv",)))
    add(Case("option/scheduler-unreachable", "option", ["verify", *EX, "--layout", "5,25", "--scenarios", "2",
                                                        "--scheduler", "tcp://127.0.0.1:9", "--scheduler-timeout",
                                                        "2", "--out", "out"], expect="error",
             fields=("--scheduler",)))
    add(Case("option/simulate-out-is-a-directory", "option", ["simulate", *EX, "--out", "."], expect="error",
             fields=("--out",)))
    add(Case("option/simulate-noise-without-seed", "option", ["simulate", *EX, "--noise", "--out", "out/x.csv"],
             expect="error", fields=("--seed",)))
    add(Case("option/diagnose-write-case-directory", "option", ["diagnose", *EX, "--data", "data.csv",
                                                                "--write-case", ".", "--out", "out"],
             expect="error", fields=("--write-case",)))
    add(Case("option/report-data-clean", "option", ["report", *EX, "--count", "2", "--spacing", "2",
                                                    "--scenarios", "2", "--data", "clean.csv", "--out", "out"],
             expect="error", fields=("noise-free",)))
    add(Case("option/fixed-on-a-support-excluded", "option", ["recommend", *EX, "--fixed", "15", "--exclude",
                                                              "14:16", "--out", "out"], expect="error",
             fields=("--fixed", "--exclude")))
    add(Case("option/region-outside", "option", ["recommend", *EX, "--criterion", "A", "--region", "100:200",
                                                 "--count", "2", "--spacing", "2", "--out", "out"],
             expect="error", fields=("--region",)))
    add(Case("option/verify-layout-duplicate-kinds", "option", ["verify", *EX, "--layout", "5,5:deflection",
                                                                "--scenarios", "2", "--out", "out"]))
    add(Case("option/detect-step-over-length", "option", ["recommend", *EX, "--criterion", "detect", "--step",
                                                          "29", "--count", "2", "--spacing", "2", "--out", "out"]))
    add(Case("option/argv-unknown", "option", ["recommend", *EX, "--cuont", "2"], expect="error",
             fields=("--cuont",)))
    add(Case("option/no-command", "option", [], expect="error"))
    return c


def data_cases(fix):
    c = []
    add = c.append
    head, rows = _csv_rows(fix)
    for command in ("invert", "diagnose", "report"):
        extra = ["--count", "2", "--spacing", "2", "--scenarios", "2"] if command == "report" else []

        def case(label, body, expect="error", fields=(), cls="data", cmd=command, ex=extra):
            return Case(f"data/{label}/{cmd}", cls, [cmd, *EX, *ex, "--data", "h.csv", "--out", "out"],
                        {"h.csv": body}, expect, fields)

        add(case("all-zero", _map_data(fix, lambda r: [r[0], r[1], 0.0, 0.0]), fields=("PE1",)))
        add(case("one-dead-channel", _map_data(fix, lambda r: [r[0], r[1], r[2], 1e-6]), fields=("PE2",)))
        add(case("positions-in-mm", _map_data(fix, lambda r: [r[0], float(r[1]) * 1000, r[2], r[3]]),
                 fields=("position_m",)))
        add(case("readings-in-urad", _map_data(fix, lambda r: [r[0], r[1], float(r[2]) * 1e6, float(r[3]) * 1e6]),
                 fields=("PE1",)))
        add(case("nan-cell", _map_data(fix, lambda r: [r[0], r[1], "nan" if r[1] == "10.0" else r[2], r[3]]),
                 fields=("nan",)))
        add(case("inf-cell", _map_data(fix, lambda r: [r[0], r[1], "inf" if r[1] == "10.0" else r[2], r[3]]),
                 fields=("inf",)))
        add(case("header-only", ",".join(head) + "\n", fields=("h.csv",)))
        add(case("bom-and-crlf", ("\ufeff" + _map_data(fix, lambda r: r)).replace("\n", "\r\n").encode("utf-8"),
                 expect="any"))
        add(case("semicolons", _map_data(fix, lambda r: r).replace(",", ";"), fields=("semicolon",)))
        add(case("missing-sensor-column", _map_data(fix, lambda r: r[:3], header=head[:3]), expect="any",
                 fields=("PE2",)))
        add(case("sign-flipped", _map_data(fix, lambda r: [r[0], r[1], r[2], -float(r[3])]), expect="any",
                 fields=("PE2",)))
        add(case("clean-from-simulate", fix["clean.csv"], expect="any", fields=("noise-free",)))
    add(Case("data/load-factor-1e300/invert", "data", ["invert", *EX, "--data", "h.csv", "--out", "out"],
             {"h.csv": _map_data(fix, lambda r: r + ["1e300"], header=head + ["load_factor"])}, "error",
             ("load_factor",)))
    add(Case("data/load-factor-subnormal/diagnose", "data", ["diagnose", *EX, "--data", "h.csv", "--out", "out"],
             {"h.csv": _map_data(fix, lambda r: r + ["5e-324"], header=head + ["load_factor"])}, "error",
             ("load_factor",)))
    add(Case("data/single-row/invert", "data", ["invert", *EX, "--data", "h.csv", "--out", "out"],
             {"h.csv": _csv(head, rows[:1])}, "error", ("h.csv",)))
    add(Case("data/one-position-repeated/invert", "data", ["invert", *EX, "--data", "h.csv", "--out", "out"],
             {"h.csv": _csv(head, [[r[0], "10.0", r[2], r[3]] for r in rows])}, "error", ("position_m",)))
    add(Case("data/crossing-labels-weird/invert", "data", ["invert", *EX, "--data", "h.csv", "--out", "out"],
             {"h.csv": _map_data(fix, lambda r: ["../x\u202e" if r[0] == "1" else r[0], *r[1:]])}, "any",
             ("crossing",)))
    add(Case("data/huge-values/invert", "data", ["invert", *EX, "--data", "h.csv", "--out", "out"],
             {"h.csv": _map_data(fix, lambda r: [r[0], r[1], "1e300", "-1e300"])}, "error", ("PE1",)))
    add(Case("data/binary/diagnose", "data", ["diagnose", *EX, "--data", "h.csv", "--out", "out"],
             {"h.csv": bytes(range(256)) * 4}, "error", ("h.csv",)))
    add(Case("swallow/data-noise-free-invert-warns", "swallow", ["invert", *EX, "--data", "clean.csv",
                                                                 "--out", "out"], {}, "any"))
    return c


def name_cases(fix):
    c = []
    text = _example()
    head, rows = _csv_rows(fix)
    for label, pair in (("collide-after-sanitising", ("a b", "a_b")), ("case-fold", ("PE1", "pe1"))):
        body = _sub('names = ["PE1", "PE2"]', f'names = ["{pair[0]}", "{pair[1]}"]')(text)
        c.append(Case(f"name/{label}/invert", "name", ["invert", "--config", "case.toml", "--data", "h.csv",
                                                      "--out", "out"],
                      {"case.toml": body, "h.csv": _csv([head[0], head[1], *pair], rows)}, "ok"))
    names = {
        "slash": '"a/b"', "dotdot": '".."', "traversal": '"../../x"', "newline": '"a\\nb"', "comma": '"a,b"',
        "quote": '"a\\"b"', "space": '"a b"', "bom": '"\\ufeffPE1"', "crossing": '"crossing"',
        "load-factor": '"load_factor"', "time": '"time_s"', "long": '"' + "x" * 300 + '"',
        "case-duplicate": '"pe2"', "unicode": '"Neigung\u00b0"', "nul": '"a\\u0000b"', "dot": '"."',
    }
    for label, value in names.items():
        body = _sub('names = ["PE1", "PE2"]', f'names = [{value}, "PE2"]')(text)
        for command, extra in (("simulate", ["--out", "out/x.csv"]), ("informativeness", ["--out", "out"]),
                               ("detectability", ["--out", "out"])):
            c.append(Case(f"name/{label}/{command}", "name", [command, "--config", "case.toml", *extra],
                          {"case.toml": body}, "any", ("names",)))
    return c


def logger_cases(fix):
    c = []
    head, rows = _log_rows(fix)
    base = ["crossings", "--config", "logcase.toml", "--timeseries", "l.csv", "--out", "out/x.csv"]

    def case(label, body, expect="error", fields=("l.csv",), argv=base):
        return Case(f"logger/{label}", "logger", argv, {"l.csv": body}, expect, fields)

    c.append(case("valid", fix["log.csv"], expect="ok"))
    c.append(case("all-zero", _csv(head, [[r[0], 0, 0] for r in rows])))
    c.append(case("constant-offset", _csv(head, [[r[0], 1e3, 1e3] for r in rows])))
    c.append(case("time-reversed", _csv(head, rows[::-1]), fields=("time_s",)))
    c.append(case("time-duplicated", _csv(head, [[0.0, r[1], r[2]] for r in rows]), fields=("time_s",)))
    c.append(case("time-nan", _csv(head, [["nan" if i == 5 else r[0], r[1], r[2]] for i, r in enumerate(rows)]),
                  fields=("time_s",)))
    c.append(case("time-1e300", _csv(head, [[float(r[0]) * 1e300, r[1], r[2]] for r in rows])))
    c.append(case("time-subnormal-steps", _csv(head, [[i * 5e-324, r[1], r[2]] for i, r in enumerate(rows)])))
    c.append(case("values-in-rad-not-urad", _csv(head, [[r[0], float(r[1]) * 1e-6, float(r[2]) * 1e-6]
                                                        for r in rows])))
    c.append(case("values-1e300", _csv(head, [[r[0], 1e300, -1e300] for r in rows])))
    c.append(case("inf-reading", _csv(head, [[r[0], "inf" if i == 3 else r[1], r[2]] for i, r in enumerate(rows)]),
                  fields=("PE1",)))
    c.append(case("sign-flipped", _csv(head, [[r[0], r[1], -float(r[2])] for r in rows]), expect="any"))
    c.append(case("bom-header", ("\ufeff" + fix["log.csv"].decode()).encode("utf-8"), expect="ok"))
    c.append(case("semicolons", fix["log.csv"].decode().replace(",", ";"), fields=("semicolon",)))
    c.append(case("unknown-column", _csv(["time_s", "PE1", "PX"], rows), fields=("PX",)))
    c.append(case("two-rows", _csv(head, rows[:2])))
    c.append(case("million-columns", "time_s," + ",".join(f"c{i}" for i in range(100000)) + "\n0,"
                  + ",".join("0" for _ in range(100000)) + "\n"))
    c.append(case("empty", b""))
    c.append(case("speed-given-wrong", fix["log.csv"], fields=("--speed 199",), argv=[*base, "--speed", "199"]))
    return c


def atomic_cases():
    c = []
    # the JSON cannot be written after the figures are staged: nothing may be left
    c.append(Case("atomic/json-under-a-file-after-figures", "atomic", ["recommend", *SS, "--count", "2", "--spacing",
                                                                      "2", "--out", "out", "--json", "data.csv/d.json"],
                  {}, "error", ("data.csv",)))
    c.append(Case("atomic/write-case-under-a-file", "atomic", ["diagnose", *EX, "--data", "data.csv", "--write-case",
                                                              "data.csv/c.toml", "--out", "out"], {}, "error",
                  ("data.csv",)))
    if os.geteuid() != 0:  # root writes into read-only folders
        c.append(Case("atomic/out-read-only", "atomic", ["recommend", *SS, "--count", "2", "--spacing", "2",
                                                         "--out", "ro/sub"], {"ro/.keep": ""}, "error", ("ro",)))
        c.append(Case("atomic/json-read-only", "atomic", ["detectability", *EX, "--out", "out", "--json",
                                                          "ro/d.json"], {"ro/.keep": ""}, "error", ("ro",)))
    c.append(Case("atomic/json-over-existing-file-ok", "atomic", ["informativeness", *EX, "--out", "out"],
                  {"out/informativeness.json": "old"}, "ok"))
    c.append(Case("atomic/crossings-figure-under-a-file", "atomic",
                  ["crossings", "--config", "logcase.toml", "--timeseries", "log.csv", "--out", "out/x.csv",
                   "--figure", "data.csv/f.png"], {}, "error", ("data.csv",)))
    c.append(Case("blame/json-name-equals-out-file", "blame",
                  ["crossings", "--config", "logcase.toml", "--timeseries", "log.csv", "--out", "out/x.csv",
                   "--json", "out/x.csv"], {}, "error", ("out/x.csv", "--json")))
    c.append(Case("blame/report-per-span-min-count", "blame", ["report", *EX, "--count", "1", "--per-span-min",
                                                               "1,1", "--out", "out"], {}, "error",
                  ("--per-span-min", "--count")))
    c.append(Case("blame/recommend-cost-budget", "blame", ["recommend", *EX, "--count", "2", "--cost",
                                                           "rotation=2", "--budget", "3", "--out", "out"], {},
                  "error", ("--budget",)))
    c.append(Case("blame/fixed-too-close", "blame", ["recommend", *EX, "--fixed", "11,12", "--min-spacing", "2",
                                                     "--out", "out"], {}, "error", ("--fixed", "--min-spacing")))
    c.append(Case("blame/verify-noise-std-per-kind", "blame", ["verify", *EX, "--layout", "5,25:deflection",
                                                               "--scenarios", "2", "--out", "out"], {}, "error",
                  ("--noise-std", "deflection")))
    return c


def all_cases(fixtures):
    return toml_cases() + option_cases() + data_cases(fixtures) + name_cases(fixtures) + logger_cases(fixtures) + \
        atomic_cases()


# --------------------------------------------------------------------------
# the runner
# --------------------------------------------------------------------------

def _limit():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_BYTES, MEMORY_BYTES))


def _snapshot(root):
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in Path(root).rglob("*") if p.is_file()}


def _targets(argv):
    """Folders an output may land in: each output option's value (a file's folder for a file name)."""
    roots = []
    for i, a in enumerate(argv[:-1]):
        if a in OUTPUT_OPTIONS:
            p = Path(argv[i + 1])
            roots.append(p.parent if p.suffix else p)
    return roots


def _under(path, roots):
    return any(path == r or r in path.parents for r in roots if str(r) not in ("", "."))


def _strict_json(path):
    def reject(token):
        raise ValueError(f"{token} in {path.name}")
    json.loads(path.read_text("utf-8"), parse_constant=reject)


def _finite_csv(path):
    for line in path.read_text("utf-8").splitlines()[1:]:
        for cell in line.split(","):
            try:
                value = float(cell)
            except ValueError:
                continue
            if not math.isfinite(value):
                raise ValueError(f"non-finite value {cell!r} in {path.name}")


def run_case(case, fixtures):
    """(passed, detail) of one case."""
    tmp = Path(tempfile.mkdtemp(prefix="hostile-"))
    work, tmpdir = tmp / "work", tmp / "tmpdir"
    work.mkdir()
    tmpdir.mkdir()
    try:
        _write_inputs(work, fixtures, case)
        before = _snapshot(tmp)
        env = dict(ENV, TMPDIR=str(tmpdir))
        t0 = time.perf_counter()
        try:
            proc = subprocess.run([sys.executable, "-m", "sensorplan", *case.argv, "--quiet"], cwd=work, env=env,
                                  capture_output=True, text=True, timeout=TIMEOUT_S, preexec_fn=_limit,
                                  check=False)
        except subprocess.TimeoutExpired:
            return False, f"timeout after {TIMEOUT_S:g} s"
        seconds = time.perf_counter() - t0
        if not case.argv:  # no command at all: argparse's own usage error
            ok = proc.returncode == 1 and "Traceback" not in proc.stderr
            return ok, f"rc {proc.returncode} ({seconds:.1f} s): {proc.stderr.strip()[:200]}"
        for ro in {Path(n).parts[0] for n in case.files if n.startswith("ro/")}:
            (work / ro).chmod(0o755)
        after = _snapshot(tmp)
        new = sorted(k for k in after if k not in before or after[k] != before[k])
        return _judge(case, proc, f"rc {proc.returncode} ({seconds:.1f} s): {proc.stderr.strip()[:300]}", tmp,
                      after, new)
    finally:
        for p in tmp.rglob("*"):
            if p.is_dir():
                p.chmod(0o755)
        shutil.rmtree(tmp, ignore_errors=True)


def _write_inputs(work, fixtures, case):
    """The fixtures and the case's own files in ``work``; its ``ro/`` folders made read-only."""
    for name, content in fixtures.items():
        (work / name).write_bytes(content)
    for name, content in case.files.items():
        path = work / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))
    for ro in {Path(n).parts[0] for n in case.files if n.startswith("ro/")}:
        (work / ro).chmod(0o555)


def _judge(case, proc, detail, tmp, after, new):
    """(passed, detail) of a finished process: no traceback, exit 0 or 1, nothing left in TMPDIR, then the
    rules of an error (one line naming the fields, no file) or of a result (sane files under the outputs)."""
    if "Traceback" in proc.stderr or "Traceback" in proc.stdout:
        return False, "traceback: " + " | ".join((proc.stderr + proc.stdout).strip().splitlines()[-3:])
    if proc.returncode not in (0, 1):
        return False, "exit code: " + detail
    leftovers = [k for k in after if k.startswith("tmpdir/")]
    if leftovers:
        return False, f"left in TMPDIR: {leftovers[:3]}; " + detail
    if proc.returncode == 1:
        lines = proc.stderr.strip().splitlines()
        if case.expect == "ok":
            return False, "expected a result: " + detail
        if new:
            return False, f"files left behind on failure: {new[:5]}; " + detail
        if len(lines) != 1 or ": error: " not in lines[0]:
            return False, f"{len(lines)} stderr lines: " + detail
        missing = [f for f in case.fields if f not in lines[0]]
        if missing:
            return False, f"the error does not name {missing}: " + detail
        return True, detail
    if case.expect == "error":
        return False, "expected an error: " + detail
    roots = [Path("work") / r for r in _targets(case.argv)]
    outside = [k for k in new if not _under(Path(k), roots)]
    if outside:
        return False, f"written outside the outputs: {outside[:5]}; " + detail
    try:
        for k in new:
            if k.endswith(".json"):
                _strict_json(tmp / k)
            elif k.endswith(".csv"):
                _finite_csv(tmp / k)
    except (ValueError, UnicodeDecodeError) as exc:
        return False, f"insane output ({exc}); " + detail
    if not new:
        return False, "exit 0 but no output written; " + detail
    return True, detail


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("-k", "--keyword", default="")
    parser.add_argument("--list", action="store_true")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="hostile-fixtures-") as folder:
        fixtures = make_fixtures(folder)
        cases = [c for c in all_cases(fixtures) if args.keyword in c.name]
        if args.list:
            for c in cases:
                print(c.cls, c.name, " ".join(c.argv))
            print(f"{len(cases)} cases")
            return 0
        by_class = {}
        failures = []
        t0 = time.perf_counter()

        def one(case):
            return case, *run_case(case, fixtures)

        with ThreadPoolExecutor(args.jobs) as pool:
            for case, ok, detail in pool.map(one, cases):
                by_class.setdefault(case.cls, [0, 0])[0 if ok else 1] += 1
                print(f"{'PASS' if ok else 'FAIL'} {case.name}: {detail.splitlines()[0] if detail else ''}"[:400],
                      flush=True)
                if not ok:
                    failures.append((case.name, detail))
    passed = sum(v[0] for v in by_class.values())
    print(f"\n{passed}/{len(cases)} cases pass in {time.perf_counter() - t0:.0f} s; per class: "
          + ", ".join(f"{k} {v[0]}/{sum(v)}" for k, v in sorted(by_class.items())))
    for name, detail in failures:
        print(f"  FAIL {name}: {re.sub(chr(10), ' | ', detail)[:600]}")
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
