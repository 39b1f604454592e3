"""The documentation runs, prints what it shows, and names only what exists.

Every code block in README.md and docs/*.md is executed:

* ```python blocks run standalone, each in a fresh namespace, with the
  working directory set to a temporary folder.
* ```console blocks: every line starting with "$ sensorplan " is split with
  shlex and run through ``sensorplan.cli.main`` (exit code 0 expected).  A
  command may continue on the next line after a trailing backslash.  Lines
  of one block share their temporary folder, so a later command can read
  what an earlier one wrote.
* plain ``` blocks (README's set-up lines): the part after "&& " is run when
  it starts with "sensorplan "; the pip part and the pytest line are not.

Shown output is compared with what the code prints:

* in a console block, the lines after a command (up to the next "$ " line)
  are that command's stdout;
* a ```text block that directly follows a python block (nothing but blank
  lines in between) is that block's stdout;
* ``print(...)  # shown`` in a python block: the comment is the line printed.

Lines are compared after stripping their ends, with runs of white space
equal.  Numbers match when they differ by at most 0.1 % or one unit in the
last digit the doc shows (last digits of solver results differ between
machines).  A line "..." stands for any number of lines, and "..." inside a
line for any text (timings, for example).  Blocks that run verification, a
report or a diagnosis take more than 10 s and carry
the ``slow`` marker.

The rest of the file checks that the docs name only commands, options and
Python names that exist, and that docs/api.md matches ``sensorplan.__all__``.
"""

import argparse
import ast
import contextlib
import functools
import importlib
import inspect
import io
import re
import shlex
import sys
import tokenize
from pathlib import Path

import pytest

import sensorplan
import sensorplan.plotting
from sensorplan.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
DOC_FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
EXPECTED_DOCS = ("index.md", "user-guide.md", "theory.md", "api.md", "examples.md", "limitations.md")

_FENCE = re.compile(r"^(\s*)(`{3,})\s*([^`\s]*)\s*$")
_EXECUTABLE = ("python", "console", "")
# What makes a block slow (> 10 s): verification, a report, a diagnosis run from Python, a design study.
_SLOW = re.compile(r"sensorplan (?:verify|report|diagnose)\b|--verify\b|\"(?:verify|report|diagnose)\"|design_study\(")

# A number as the docs show it: not part of a name (PE1, rotational_0) or of a longer number.
_NUMBER = r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?"
_NUMBER_TOKEN = re.compile(rf"(?<![\w.]){_NUMBER}(?![\w])")
RTOL = 1e-3


# --------------------------------------------------------------------------- reading the docs

def _blocks(path):
    """Fenced code blocks of a markdown file: (language, code, first code line number, fence lines)."""
    out = []
    lines = path.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, lang = m.group(1), m.group(2), m.group(3).lower()
        opening = i
        body = []
        i += 1
        while i < len(lines):
            close = re.match(r"^\s*(`{3,})\s*$", lines[i])
            if close and len(close.group(1)) >= len(fence):
                break
            line = lines[i]
            body.append(line[len(indent):] if line.startswith(indent) else line.lstrip())
            i += 1
        out.append((lang, "\n".join(body) + "\n", opening + 2, (opening, i)))
        i += 1
    return out


def _shown_after(path, blocks, index):
    """The body of a ```text block directly after block ``index`` (only blank lines between), or None."""
    if index + 1 >= len(blocks):
        return None
    lang, code, _, (opening, _) = blocks[index + 1]
    end = blocks[index][3][1]
    between = path.read_text(encoding="utf-8").splitlines()[end + 1:opening]
    if lang == "text" and all(not line.strip() for line in between):
        return code
    return None


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
            commands.append((part, []))
    return commands


def _console_commands(code):
    """(command, shown output lines) for every "$ sensorplan ..." line of a console block."""
    commands = []
    for line in _join_continuations(code.splitlines()):
        stripped = line.strip()
        if not stripped.startswith("$ "):
            if commands:
                commands[-1][1].append(line)
            elif stripped:
                raise AssertionError(f"output before the first command of a console block: {line!r}")
            continue
        command = stripped[2:].strip()
        if not command.startswith("sensorplan "):
            raise AssertionError(f"console lines must start with '$ sensorplan ' (use a bash block for other "
                                 f"commands); got {stripped!r}")
        commands.append((command, []))
    return commands


def _print_comments(code):
    """The output comments of ``print(...)  # shown`` lines, in order."""
    shown = []
    for tok in tokenize.generate_tokens(io.StringIO(code).readline):
        if tok.type == tokenize.COMMENT and tok.line.lstrip().startswith("print("):
            shown.append(tok.string[1:].strip())
    return shown


def _collect():
    params = []
    for path in DOC_FILES:
        if not path.exists():
            continue
        rel = path.relative_to(ROOT).as_posix()
        blocks = _blocks(path)
        for index, (lang, code, line, _) in enumerate(blocks):
            if lang not in _EXECUTABLE:
                continue
            if lang == "" and not _plain_commands(code):
                continue
            shown = _shown_after(path, blocks, index) if lang == "python" else None
            marks = [pytest.mark.slow] if _SLOW.search(code) else []
            params.append(pytest.param(rel, lang, code, shown, marks=marks, id=f"{rel}-block{index}-line{line}"))
    return params


# --------------------------------------------------------------------------- comparing output

def _unit(text):
    """One unit in the last digit of a number as written."""
    mantissa, _, exponent = text.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (int(exponent or 0) - decimals)


@functools.lru_cache(maxsize=None)
def _line_pattern(shown):
    """(regex, numbers as shown) of one shown line: '...' is any text, numbers are captured."""
    parts, numbers = [], []

    def text(segment):
        words = segment.split()
        lead = r"\s*" if segment[:1].isspace() else ""
        tail = r"\s*" if segment[-1:].isspace() else ""
        return lead + r"\s+".join(re.escape(w) for w in words) + tail if words else (r"\s*" if segment else "")

    for k, segment in enumerate(shown.strip().split("...")):
        if k:
            parts.append(".*?")
        pos = 0
        for m in _NUMBER_TOKEN.finditer(segment):
            parts.append(text(segment[pos:m.start()]))
            parts.append(f"({_NUMBER})")
            numbers.append(m.group())
            pos = m.end()
        parts.append(text(segment[pos:]))
    return re.compile("".join(parts)), tuple(numbers)


def _line_matches(shown, actual):
    pattern, numbers = _line_pattern(shown)
    m = pattern.fullmatch(actual.strip())
    if m is None:
        return False
    for text, got in zip(numbers, m.groups()):
        value, printed = float(text), float(got)
        if abs(printed - value) > max(RTOL * abs(value), _unit(text)) * (1 + 1e-9):
            return False
    return True


def _is_elision(line):
    return line.strip() == "..."


def _output_matches(shown, actual):
    """Whether the printed lines match the shown ones ('...' lines match any number of lines)."""
    shown = [line for line in shown if line.strip()]
    actual = [line for line in actual if line.strip()]

    @functools.lru_cache(maxsize=None)
    def match(i, j):
        if i == len(shown):
            return j == len(actual)
        if _is_elision(shown[i]):
            return any(match(i + 1, k) for k in range(j, len(actual) + 1))
        return j < len(actual) and _line_matches(shown[i], actual[j]) and match(i + 1, j + 1)

    return match(0, 0)


def _first_difference(shown, actual):
    """A short description of where shown and printed output part (for the failure message)."""
    shown = [line for line in shown if line.strip() and not _is_elision(line)]
    actual = [line for line in actual if line.strip()]
    for line in shown:
        if not any(_line_matches(line, a) for a in actual):
            return f"no printed line matches the shown line\n    {line.strip()}"
    return "the shown lines are all printed, but not in this order or with other lines in between"


def assert_output(shown, printed, where):
    shown = [line for line in shown]
    actual = printed.splitlines()
    if not _output_matches(shown, actual):
        raise AssertionError(f"{where}: {_first_difference(shown, actual)}\n--- printed:\n{printed}"
                             f"--- the doc shows:\n" + "\n".join(shown))


def test_output_comparison_can_fail():
    assert _output_matches(["criterion 150.779; gap -0.558", "..."], ["criterion 150.78; gap -0.558", "x"])
    assert _output_matches(["status optimal, relative duality gap ..."], ["status optimal, relative duality gap "
                                                                           "5.6e-11, 0.05 s"])
    assert _output_matches(["  spring PE1=5.01e-06 ... (nominal 2e+09)"], ["spring PE1=5.012e-06 x (nominal 2e+09)"])
    assert not _output_matches(["criterion 150.779"], ["criterion 151.779"])     # a different number
    assert not _output_matches(["gap -0.558"], ["gap 0.558"])                    # a sign
    assert not _output_matches(["positions [m]: 2.00, 14.00"], ["positions [m]: 2.00, 14.50"])
    assert not _output_matches(["converged: True"], ["converged: False"])       # a word
    assert not _output_matches(["a", "b"], ["a"])                                 # a missing line
    assert not _output_matches(["a"], ["a", "b"])                                 # an extra line


# --------------------------------------------------------------------------- running the blocks

def _run_commands(commands, where):
    for command, shown in commands:
        args = shlex.split(command)
        assert args[0] == "sensorplan"
        stdout = io.StringIO()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(io.StringIO()):
            code = main(args[1:])
        assert code == 0, f"{where}: `{command}` exited with {code}"
        if shown:
            assert_output(shown, stdout.getvalue(), f"{where}: `{command}`")


@pytest.fixture
def _close_figures():
    yield
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close("all")


@pytest.mark.usefixtures("_close_figures")
@pytest.mark.parametrize(("doc", "lang", "code", "shown"), _collect())
def test_code_block_runs_and_prints_what_it_shows(doc, lang, code, shown, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    if lang == "python":
        namespace = {"__name__": "__docs__"}
        stdout = io.StringIO()
        with contextlib.redirect_stdout(stdout):
            exec(compile(code, f"{doc}", "exec"), namespace)
        comments = _print_comments(code)
        assert not (comments and shown), f"{doc}: show a block's output either in comments or in a text block"
        if shown is not None:
            assert_output(shown.splitlines(), stdout.getvalue(), f"{doc}: python block")
        elif comments:
            assert_output(comments, stdout.getvalue(), f"{doc}: python block")
    elif lang == "console":
        commands = _console_commands(code)
        assert commands, f"{doc}: a console block without '$ sensorplan' lines"
        _run_commands(commands, doc)
    else:
        _run_commands(_plain_commands(code), doc)


# --------------------------------------------------------------------------- names that exist

def test_documentation_files_exist():
    missing = [name for name in EXPECTED_DOCS if not (ROOT / "docs" / name).is_file()]
    assert not missing, f"missing documentation files: {missing}"


@functools.lru_cache(maxsize=None)
def _cli():
    """{command: set of its options} and the options of the top-level parser."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    commands = {name: {o for a in p._actions for o in a.option_strings} for name, p in sub.choices.items()}
    top = {o for a in parser._actions for o in a.option_strings}
    return commands, top


def _doc_texts():
    return {path.relative_to(ROOT).as_posix(): path.read_text(encoding="utf-8") for path in DOC_FILES}


def _inline_and_shell_code(text):
    """Inline code spans and the lines of non-python code blocks (where commands are written)."""
    pieces, prose, in_block, lang = [], [], False, ""
    for line in text.splitlines():
        m = _FENCE.match(line)
        if m and not in_block:
            in_block, lang = True, m.group(3).lower()
            continue
        if in_block and re.match(r"^\s*`{3,}\s*$", line):
            in_block = False
            continue
        if in_block:
            if lang != "python":
                pieces.append(line)
        else:
            prose.append(line)
    pieces += re.findall(r"`([^`\n]+)`", "\n".join(prose))
    return pieces


_COMMAND = re.compile(r"(?<![\w./-])sensorplan\s+([a-z][a-z-]*)\b")
_OPTION = re.compile(r"(?<![\w-])(--[a-z][a-z0-9-]*)")


def test_docs_name_only_existing_commands_and_options():
    commands, top = _cli()
    all_options = top.union(*commands.values())
    problems = []
    for doc, text in _doc_texts().items():
        text = re.sub(r"unknown option --[\w-]+", "unknown option", text)  # shown as unknown on purpose
        # every `sensorplan <command>` names a command; options on its line belong to it
        for piece in _inline_and_shell_code(text):
            for line in _join_continuations(piece.splitlines()):
                found = _COMMAND.findall(line)
                for command in found:
                    if command not in commands:
                        problems.append(f"{doc}: unknown command `sensorplan {command}` in {line.strip()!r}")
                if len(set(found)) == 1 and found[0] in commands:
                    for option in _OPTION.findall(line):
                        if option not in commands[found[0]]:
                            problems.append(f"{doc}: `sensorplan {found[0]}` has no option {option}: {line.strip()!r}")
        # main([...]) calls in python blocks: options belong to their command
        for call in re.findall(r"main\((\[[^\]]*\])", text):
            try:
                argv = ast.literal_eval(call)
            except ValueError:
                continue
            if argv and argv[0] in commands:
                problems += [f"{doc}: main({call}) uses {a}, unknown to {argv[0]}" for a in argv
                             if isinstance(a, str) and a.startswith("--") and a not in commands[argv[0]]]
        # every --option anywhere (prose included) is an option of some command
        for option in set(_OPTION.findall(text)):
            if option not in all_options:
                problems.append(f"{doc}: option {option} exists in no command")
    assert not problems, "\n".join(sorted(set(problems)))


def _section_options(text):
    """{command: options in the first column of the option tables of its section}."""
    out, command = {}, None
    for line in text.splitlines():
        heading = re.match(r"^#{2,4} `sensorplan ([a-z-]+)`", line)
        if heading:
            command = heading.group(1)
        elif line.startswith("## "):
            command = None
        elif command and line.startswith("| `--"):
            out.setdefault(command, set()).add(re.match(r"\| `(--[a-z0-9-]+)", line).group(1))
    return out


def test_user_guide_documents_every_option_in_its_command_section():
    commands, _ = _cli()
    text = (ROOT / "docs" / "user-guide.md").read_text(encoding="utf-8")
    tables = _section_options(text)
    common = {"--help", "--debug", "--quiet", "--config", "--example", "--version"}
    problems = []
    for command, options in commands.items():
        documented = tables.get(command, set())
        problems += [f"`sensorplan {command}` section does not document {o}" for o in sorted(options - common - documented)
                     if o.startswith("--")]
        problems += [f"`sensorplan {command}` section documents {o}, which the command does not have"
                     for o in sorted(documented - options)]
    assert not problems, "\n".join(problems)


def _resolve(dotted):
    """Import and getattr along ``sensorplan.a.b.c``; raises on the first missing part."""
    parts = dotted.split(".")
    obj = importlib.import_module(parts[0])
    for i, part in enumerate(parts[1:], start=1):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            obj = importlib.import_module(".".join(parts[: i + 1]))
    return obj


def test_docs_use_only_python_names_that_resolve():
    problems = []
    for doc, text in _doc_texts().items():
        names = set(re.findall(r"(?<![\w/.])sensorplan((?:\.[A-Za-z_]\w*)+)", text))
        for dotted in sorted(names):
            try:
                _resolve("sensorplan" + dotted)
            except (ImportError, AttributeError) as exc:
                problems.append(f"{doc}: sensorplan{dotted} does not resolve ({exc})")
        for name in sorted(set(re.findall(r"(?<![\w.])sp\.([A-Za-z_]\w*)", text))):
            if not hasattr(sensorplan, name):
                problems.append(f"{doc}: sp.{name} is not a name of sensorplan")
        for name in sorted(set(re.findall(r"(?<![\w.])plotting\.([A-Za-z_]\w*)", text)) - {"py"}):
            if name not in sensorplan.plotting.__all__:
                problems.append(f"{doc}: plotting.{name} is not in sensorplan.plotting.__all__")
    assert not problems, "\n".join(problems)


def test_docs_name_only_existing_files():
    # module paths (sensorplan/design/selection.py) exist; a bare `name.py` is a file of the package,
    # the studies or the tests (the old "Module `_selection.py`" style no longer resolves)
    problems = []
    files = {p.name for top in ("sensorplan", "studies", "tests") for p in (ROOT / top).rglob("*.py")}
    for doc, text in _doc_texts().items():
        for path in sorted(set(re.findall(r"(?<![\w/.-])((?:sensorplan|studies|tests)/[\w/.-]*\.(?:py|md|csv|toml))",
                                          text))):
            if not (ROOT / path).exists():
                problems.append(f"{doc}: {path} does not exist")
        for name in sorted(set(re.findall(r"`(\w+\.py)`", text))):
            if name not in files:
                problems.append(f"{doc}: `{name}` is no file of the package, the studies or the tests")
    assert not problems, "\n".join(problems)


# --------------------------------------------------------------------------- the API reference

def _api_text():
    return (ROOT / "docs" / "api.md").read_text(encoding="utf-8")


def _public_section(text):
    """docs/api.md up to the section on what is outside the public API."""
    return text.split("\n## Outside the public API", 1)[0]


def test_api_reference_names_every_public_name():
    text = _api_text()
    missing = [name for name in (*sensorplan.__all__, *sensorplan.plotting.__all__) if f"`{name}" not in text]
    assert not missing, f"docs/api.md does not document: {missing}"
    assert "\n## Outside the public API" in text and "\n## Architecture" in text


def _documented_signatures(text):
    """(name, [parameter names]) of every `name(params)` heading and list entry of docs/api.md."""
    out = []
    for m in re.finditer(r"^(?:#{3} |\* )`([A-Za-z_][\w.]*)\(([^`]*)\)`", text, flags=re.M):
        params = []
        depth, current = 0, ""
        for ch in m.group(2) + ",":
            if ch in "([{":
                depth += 1
            elif ch in ")]}":
                depth -= 1
            if ch == "," and depth == 0:
                name = current.split("=")[0].strip()
                if name and name not in ("*", "/"):
                    params.append(name.lstrip("*"))
                current = ""
            else:
                current += ch
        out.append((m.group(1), params))
    return out


def test_api_reference_signatures_match_the_code():
    text = _public_section(_api_text())
    problems = []
    for name, params in _documented_signatures(text):
        module, _, attr = name.rpartition(".")
        if module:
            obj = _resolve(f"sensorplan.{module}.{attr}" if not module.startswith("sensorplan") else name)
        elif name in sensorplan.__all__:
            obj = getattr(sensorplan, name)
        elif name in sensorplan.plotting.__all__:
            obj = getattr(sensorplan.plotting, name)
        else:
            problems.append(f"`{name}` has a heading in docs/api.md but is not public")
            continue
        actual = [p for p in inspect.signature(obj).parameters if p != "self"]
        if params != actual:
            problems.append(f"`{name}`: docs/api.md shows ({', '.join(params)}), the code has ({', '.join(actual)})")
    assert not problems, "\n".join(problems)


def test_api_reference_headings_are_public_names():
    text = _public_section(_api_text())
    public = set(sensorplan.__all__) | set(sensorplan.plotting.__all__)
    headed = set()
    for heading in re.findall(r"^### (.+)$", text, flags=re.M):
        headed |= {n for n in re.findall(r"`([A-Za-z_]\w*)", heading)}
    assert headed <= public, f"headed in docs/api.md but not in sensorplan.__all__: {sorted(headed - public)}"


def test_markdown_has_no_untested_commands():
    """Shell examples are console blocks (tested), not text blocks that drift."""
    for path in DOC_FILES:
        if not path.exists() or path.name == "README.md":
            continue
        for lang, code, line, _ in _blocks(path):
            if lang in ("console", "python", ""):
                continue
            for text_line in code.splitlines():
                assert not text_line.strip().startswith("$ sensorplan"), (
                    f"{path.name}:{line}: '$ sensorplan' line in a {lang or 'plain'} block is not run by the tests")
