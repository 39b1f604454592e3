"""The documentation runs: every code block in README.md and docs/*.md is executed.

* ```python blocks run standalone, each in a fresh namespace, with the
  working directory set to a temporary folder.
* ```console blocks: every line starting with "$ sensorplan " is split with
  shlex and run through ``sensorplan.cli.main`` (exit code 0 expected);
  other lines are shown output and ignored.  A command may continue on the
  next line after a trailing backslash.  Lines of one block share their
  temporary folder, so a later command can read what an earlier one wrote.
* plain ``` blocks (README's set-up lines): the part after "&& " is run when
  it starts with "sensorplan "; the pip part and the pytest line are not.

``sensorplan report`` lines are skipped (with a reason) while the command is
not available in the installed CLI.
"""

import contextlib
import functools
import io
import re
import shlex
import sys
from pathlib import Path

import pytest

from sensorplan.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
DOC_FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
EXPECTED_DOCS = ("index.md", "user-guide.md", "theory.md", "api.md", "examples.md", "limitations.md")

_FENCE = re.compile(r"^(\s*)(`{3,})\s*([^`\s]*)\s*$")
_EXECUTABLE = ("python", "console", "")


def _blocks(path):
    """Fenced code blocks of a markdown file: (language, code, first line number)."""
    out = []
    lines = path.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, lang = m.group(1), m.group(2), m.group(3).lower()
        start = i + 1
        body = []
        i += 1
        while i < len(lines):
            close = re.match(r"^\s*(`{3,})\s*$", lines[i])
            if close and len(close.group(1)) >= len(fence):
                break
            line = lines[i]
            body.append(line[len(indent):] if line.startswith(indent) else line.lstrip())
            i += 1
        out.append((lang, "\n".join(body) + "\n", start + 1))
        i += 1
    return out


def _join_continuations(lines):
    """Join shell lines that end with a backslash with the next line."""
    out, pending = [], ""
    for line in lines:
        if pending:
            line = pending + " " + line.strip()
            pending = ""
        if line.rstrip().endswith("\\"):
            pending = line.rstrip()[:-1].rstrip()
            continue
        out.append(line)
    if pending:
        out.append(pending)
    return out


def _plain_commands(code):
    """sensorplan commands of a plain set-up block (the part after "&& ")."""
    commands = []
    for line in _join_continuations(code.splitlines()):
        part = line.split("&& ", 1)[1] if "&& " in line else line
        part = part.strip()
        if part.startswith("sensorplan "):
            commands.append(part)
    return commands


def _console_commands(code):
    """The "$ sensorplan ..." lines of a console block; other "$ " lines are a mistake."""
    commands = []
    for line in _join_continuations(code.splitlines()):
        stripped = line.strip()
        if not stripped.startswith("$ "):
            continue  # shown output
        command = stripped[2:].strip()
        if not command.startswith("sensorplan "):
            raise AssertionError(f"console lines must start with '$ sensorplan ' (use a bash block for other "
                                 f"commands); got {stripped!r}")
        commands.append(command)
    return commands


def _collect():
    params = []
    for path in DOC_FILES:
        if not path.exists():
            continue
        rel = path.relative_to(ROOT).as_posix()
        for index, (lang, code, line) in enumerate(_blocks(path)):
            if lang not in _EXECUTABLE:
                continue
            if lang == "" and not _plain_commands(code):
                continue
            params.append(pytest.param(rel, index, lang, code, id=f"{rel}-block{index}-line{line}"))
    return params


@functools.lru_cache(maxsize=None)
def _report_available():
    """False when the installed CLI does not know the report command (argparse exits with 2)."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(["report", "--help"]) != 2


def _run_commands(commands):
    skipped = []
    for command in commands:
        args = shlex.split(command)
        assert args[0] == "sensorplan"
        if args[1:2] == ["report"] and not _report_available():
            skipped.append(command)
            continue
        code = main(args[1:])
        assert code == 0, f"`{command}` exited with {code}"
    if skipped:
        pytest.skip("`sensorplan report` is not available yet; skipped: " + "; ".join(skipped))


@pytest.fixture
def _close_figures():
    yield
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close("all")


@pytest.mark.usefixtures("_close_figures")
@pytest.mark.parametrize(("doc", "index", "lang", "code"), _collect())
def test_code_block_runs(doc, index, lang, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    if lang == "python":
        namespace = {"__name__": "__docs__"}
        exec(compile(code, f"{doc} (block {index})", "exec"), namespace)
    elif lang == "console":
        commands = _console_commands(code)
        assert commands, f"{doc} block {index}: a console block without '$ sensorplan' lines"
        _run_commands(commands)
    else:
        _run_commands(_plain_commands(code))


def test_documentation_files_exist():
    missing = [name for name in EXPECTED_DOCS if not (ROOT / "docs" / name).is_file()]
    assert not missing, f"missing documentation files: {missing}"


def test_api_reference_names_every_public_name():
    import sensorplan
    import sensorplan.plotting

    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    missing = [name for name in (*sensorplan.__all__, *sensorplan.plotting.__all__) if f"`{name}" not in text]
    assert not missing, f"docs/api.md does not document: {missing}"


def test_user_guide_names_every_cli_option():
    text = (ROOT / "docs" / "user-guide.md").read_text(encoding="utf-8")
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    missing = []
    for command, subparser in sub.choices.items():
        if f"sensorplan {command}" not in text:
            missing.append(command)
        for action in subparser._actions:
            for option in action.option_strings:
                if option.startswith("--") and option != "--help" and option not in text:
                    missing.append(f"{command} {option}")
    assert not missing, f"docs/user-guide.md does not mention: {missing}"


def test_markdown_has_no_untested_commands():
    """Shell examples are console blocks (tested), not text blocks that drift."""
    for path in DOC_FILES:
        if not path.exists() or path.name == "README.md":
            continue
        for lang, code, line in _blocks(path):
            if lang in ("console", "python", ""):
                continue
            for text_line in code.splitlines():
                assert not text_line.strip().startswith("$ sensorplan"), (
                    f"{path.name}:{line}: '$ sensorplan' line in a {lang or 'plain'} block is not run by the tests")
