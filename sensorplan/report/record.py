"""The provenance record of a report: version, date, command line, options and the SHA-256 of its inputs."""

import hashlib
from datetime import datetime, timezone
from pathlib import Path

from .page import table_html

__all__ = ["provenance", "provenance_section"]


def provenance(options, inputs, command_line, *, example=None):
    """What a report was made from: version, date, command line, options, SHA-256 of the input files."""
    from .. import __version__

    hashes = {name: {"path": str(path), "sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest()}
              for name, path in inputs.items()}
    if example:
        from importlib import resources

        text = resources.files("sensorplan.examples").joinpath(f"{example}.toml").read_bytes()
        hashes["config"] = {"path": f"example {example}", "sha256": hashlib.sha256(text).hexdigest()}
    return {"sensorplan_version": __version__, "date": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "command_line": " ".join(command_line), "options": options, "inputs": hashes}


def provenance_section(record):
    """The provenance section of a record from :func:`provenance`."""
    rows = [("sensorplan version", record["sensorplan_version"]), ("date (UTC)", record["date"]),
            ("command line", record["command_line"])]
    rows += [(f"{name}: {entry['path']}", f"sha256 {entry['sha256']}") for name, entry in record["inputs"].items()]
    opts = table_html(["option", "value"], [(k, "" if v is None else str(v)) for k, v in record["options"].items()])
    return ("Provenance", table_html(["item", "value"], rows) + "<h3>All options</h3>" + opts
            + '<p class="note">design.json beside this report holds the inputs of the design; '
              "<code>sensorplan</code> with its <code>recommend_argv</code> reproduces the layout.</p>")
