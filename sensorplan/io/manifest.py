"""The manifest of an output folder: which files the last run wrote there, so that the next run can remove
those it does not rewrite (a new design never sits beside an old verification).

The manifest, ``.sensorplan-manifest.json`` in the folder, lists each file a
run wrote there with its SHA-256.  A file of the previous run is removed only
when it is still exactly what sensorplan wrote (same hash), lies inside the
folder and is not one of this run's inputs: a file sensorplan did not write,
or one the user changed since, is never deleted.

Owns: reading, writing and applying the manifest.  May import: the foundations.
"""

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

__all__ = ["MANIFEST", "Manifest", "file_hash", "prune_previous_run"]

MANIFEST = ".sensorplan-manifest.json"


def file_hash(path):
    """SHA-256 (hex) of the file at ``path``."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


@dataclass(frozen=True)
class Manifest:
    """The files (relative path -> SHA-256) one run wrote in ``folder``."""

    folder: Path
    files: dict

    @classmethod
    def read(cls, folder):
        """The folder's manifest; an empty one when there is none or it cannot be read (never an error)."""
        folder = Path(os.path.abspath(folder))
        try:
            data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
            files = {str(k): str(v) for k, v in data["files"].items()}
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            files = {}
        return cls(folder, files)

    @classmethod
    def of(cls, folder, paths):
        """The manifest of the files ``paths`` (absolute) that lie inside ``folder``."""
        folder = Path(os.path.abspath(folder))
        inside = [Path(p) for p in paths if folder in Path(p).parents]
        return cls(folder, {p.relative_to(folder).as_posix(): file_hash(p) for p in inside})

    def write(self):
        """Write the manifest through a temporary file and a rename (no half-written manifest)."""
        path = self.folder / MANIFEST
        tmp = self.folder / f"{MANIFEST}.tmp"
        tmp.write_text(json.dumps({"written_by": "sensorplan", "files": self.files}, indent=1) + "\n",
                       encoding="utf-8")
        os.replace(tmp, path)


def prune_previous_run(folder, written, *, keep=()):
    """Remove the files of the previous run in ``folder`` that this run did not rewrite; record this run's.

    ``written`` are the absolute paths this run wrote; ``keep`` paths (the
    run's inputs) are never removed.  Returns the relative paths removed.
    """
    folder = Path(os.path.abspath(folder))
    if not folder.is_dir():
        return ()
    previous = Manifest.read(folder)
    current = Manifest.of(folder, written)
    kept = {Path(os.path.abspath(p)) for p in keep}
    removed = []
    for name, digest in sorted(previous.files.items()):
        path = Path(os.path.abspath(folder / name))
        if name in current.files or folder not in path.parents or path in kept or not path.is_file():
            continue
        try:
            if file_hash(path) == digest:
                path.unlink()
                removed.append(name)
        except OSError:  # unreadable or not removable: left in place
            continue
    if current.files or previous.files:
        try:
            current.write()
        except OSError:  # the outputs are in place; only the next run's clean-up is lost
            pass
    return tuple(removed)
