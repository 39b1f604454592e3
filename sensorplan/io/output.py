"""All-or-nothing output: every file of a command appears, or none does.

A command stages each output file (JSON, CSV, figures) in a temporary file
beside its destination and commits them together at the end; if anything
fails before or during the commit, the staged files are removed, files that
were overwritten are restored and folders created for the output are
removed again.

Owns: staging and committing output files.  May import: errors.
"""

import os
import shutil
import tempfile
from pathlib import Path

from .._errors import ConfigError
from .manifest import prune_previous_run

__all__ = ["OutputFiles", "atomic_write_text"]


def _existing_ancestor(path):
    path = Path(os.path.abspath(path))
    while not path.exists():
        path = path.parent
    return path


def _publish_mode(path):
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)  # mkstemp creates 0600; give the usual file mode


class OutputFiles:
    """Stage output files and commit them together (a context manager).

    ``stage(path)`` returns a temporary path to write instead of ``path``;
    leaving the ``with`` block normally moves every staged file into place,
    an exception discards them all.  With an output ``folder``, a commit
    also removes the files the previous run wrote there and this one did not
    rewrite (:func:`~sensorplan.io.manifest.prune_previous_run`; never the
    ``keep`` paths, the run's inputs); their names are in ``removed``.

    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> with OutputFiles() as files:
    ...     _ = files.write_text(folder / "a" / "x.txt", "x")
    >>> (folder / "a" / "x.txt").read_text()
    'x'
    >>> try:
    ...     with OutputFiles() as files:
    ...         _ = files.write_text(folder / "b" / "y.txt", "y")
    ...         raise RuntimeError("disk full")
    ... except RuntimeError:
    ...     pass
    >>> (folder / "b").exists()
    False
    """

    def __init__(self, *, folder=None, keep=()):
        self._staged = []  # (temporary, final)
        self.folder = folder
        self.keep = tuple(keep)
        self.removed = ()  # files of the previous run removed by the commit (relative to folder)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.commit()
        else:
            self.discard()
        return False

    def stage(self, path, *, suffix=".tmp"):
        """A temporary file to write in place of ``path`` (created empty)."""
        final = Path(os.path.abspath(path))
        if final.is_dir():
            raise IsADirectoryError(f"Output path {path} is a folder; give a file name.")
        if any(final == f for _, f in self._staged):
            raise ConfigError(f"Two outputs of this command would be written to {path}, one over the other; give each "
                              "output option (--out, --json, --figure, ...) its own file name.")
        folder = _existing_ancestor(final.parent)
        if not folder.is_dir():
            raise NotADirectoryError(f"Output folder {folder} is a file, so {path} cannot be written in it; "
                                     "give a folder (e.g. --out) that is not an existing file.")
        fd, tmp = tempfile.mkstemp(prefix=".sensorplan-", suffix=suffix, dir=folder)
        os.close(fd)
        self._staged.append((Path(tmp), final))
        return Path(tmp)

    def write_text(self, path, text):
        """Stage ``text`` for ``path``; returns ``path``."""
        tmp = self.stage(path)
        with open(tmp, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)
        return Path(path)

    def discard(self):
        for tmp, _ in self._staged:
            if tmp.exists():
                tmp.unlink()
        self._staged = []

    def commit(self):
        """Move every staged file into place; on failure undo what was moved."""
        created, moved, backups = [], [], []
        try:
            for tmp, final in self._staged:
                missing = []
                parent = final.parent
                while not parent.exists():
                    missing.append(parent)
                    parent = parent.parent
                for folder in reversed(missing):
                    folder.mkdir()
                    created.append(folder)
                if final.exists():
                    fd, backup = tempfile.mkstemp(prefix=".sensorplan-backup-", dir=final.parent)
                    os.close(fd)
                    os.replace(final, backup)
                    backups.append((Path(backup), final))
                _publish_mode(tmp)
                os.replace(tmp, final)
                moved.append(final)
        except BaseException:
            for final in moved:
                if final.exists():
                    final.unlink()
            for backup, final in backups:
                os.replace(backup, final)
            for folder in reversed(created):
                shutil.rmtree(folder, ignore_errors=True)
            self.discard()
            raise
        for backup, _ in backups:
            backup.unlink()
        self._staged = []
        if self.folder is not None:
            self.removed = prune_previous_run(self.folder, moved, keep=self.keep)


def atomic_write_text(path, text):
    """Write ``text`` to ``path`` through a temporary file and a rename."""
    with OutputFiles() as files:
        files.write_text(path, text)
    return Path(path)
