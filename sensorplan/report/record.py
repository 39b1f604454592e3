"""The provenance record of a report: version, date, command line, options and the SHA-256 of its inputs."""

import hashlib
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from .page import table_html

__all__ = ["provenance", "provenance_section", "Provenance", "InputFile"]


@dataclass(frozen=True)
class InputFile:
    """One input of a report: where it was read from and the SHA-256 of its bytes."""

    path: str
    sha256: str

    def to_dict(self):
        return {"path": self.path, "sha256": self.sha256}


@dataclass(frozen=True)
class Provenance:
    """What a report was made from (:func:`provenance`)."""

    sensorplan_version: str
    date: str  # UTC, ISO 8601 to the second
    command_line: str
    options: dict  # option name -> value, as the command parsed them
    inputs: dict  # input name ("config", "data") -> InputFile

    def to_dict(self):
        return {"sensorplan_version": self.sensorplan_version, "date": self.date,
                "command_line": self.command_line, "options": self.options,
                "inputs": {name: entry.to_dict() for name, entry in self.inputs.items()}}


def provenance(options, inputs, command_line, *, example=None):
    """What a report was made from: version, date, command line, options, SHA-256 of the input files."""
    from .. import __version__

    hashes = {name: InputFile(str(path), hashlib.sha256(Path(path).read_bytes()).hexdigest())
              for name, path in inputs.items()}
    if example:
        from importlib import resources

        text = resources.files("sensorplan.examples").joinpath(f"{example}.toml").read_bytes()
        hashes["config"] = InputFile(f"example {example}", hashlib.sha256(text).hexdigest())
    return Provenance(__version__, datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                      " ".join(command_line), options, hashes)


def provenance_section(record):
    """The provenance section of a :class:`Provenance` record."""
    rows = [("sensorplan version", record.sensorplan_version), ("date (UTC)", record.date),
            ("command line", record.command_line)]
    rows += [(f"{name}: {entry.path}", f"sha256 {entry.sha256}") for name, entry in record.inputs.items()]
    opts = table_html(["option", "value"], [(k, "" if v is None else str(v)) for k, v in record.options.items()])
    return ("Provenance", table_html(["item", "value"], rows) + "<h3>All options</h3>" + opts
            + '<p class="note">design.json beside this report holds the inputs of the design; '
              "<code>sensorplan</code> with its <code>recommend_argv</code> reproduces the layout.</p>")
