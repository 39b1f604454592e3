"""The command line as a new user meets it: bare `sensorplan`, misspelt and abbreviated options, the
defaults --help states against those the parser uses and those the user guide's option tables state.
"""

import re
from pathlib import Path

import pytest

from sensorplan.cli import build_parser, main
from sensorplan.cli._common import show_default

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "user-guide.md"


def test_bare_sensorplan_prints_the_help(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: sensorplan") and "recommend" in out and "report" in out


@pytest.mark.parametrize("argv, message", [
    (["recommend", "--example", "openlab-like", "--cross", "10"],
     "sensorplan recommend: error: unknown option --cross; did you mean --crossings?"),
    (["verify", "--cross", "10"], "sensorplan verify: error: unknown option --cross; did you mean --verify-crossings?"),
    (["verify", "--layuot", "1"], "sensorplan verify: error: unknown option --layuot; did you mean --layout?"),
    (["recommend", "--count=2", "--nosie-std=1e-6"], "unknown option --nosie-std; did you mean --noise-std?"),
    (["invert", "--zzz"], "sensorplan invert: error: unknown option --zzz (see `sensorplan invert --help`)"),
    (["reccomend"], "sensorplan: error: unknown command 'reccomend'; did you mean recommend?"),
])
def test_unknown_or_abbreviated_option_is_one_line_with_a_suggestion(argv, message, capsys, tmp_path):
    assert main([*argv, "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "out").exists()


def test_no_abbreviation_anywhere():
    parser = build_parser()
    assert not parser.allow_abbrev
    assert all(not sub.allow_abbrev for sub in parser.commands.values())
    with pytest.raises(SystemExit):  # argparse itself refuses the prefix too
        parser.commands["simulate"].parse_args(["--example", "openlab-like", "--cross", "3", "--out", "x.csv"])


def _stated(text):
    """The default a help text states, "(default X)" or "(default X, ...)", else None."""
    match = re.search(r"\(default:? ([^;,)]+)", " ".join(text.split()))
    return None if match is None else match.group(1).strip()


@pytest.mark.parametrize("command", sorted(build_parser().commands))
def test_help_states_the_default_the_parser_uses(command):
    for action in build_parser().commands[command].option_actions:
        if not action.option_strings or action.help is None or action.option_strings == ["-h", "--help"]:
            continue
        text = action.help % {"default": action.default}
        if action.default is None or isinstance(action.default, bool):  # not given: the help says what happens
            continue
        stated = _stated(text)
        if stated is None:  # "(smooth, default)"
            assert "default" in text and show_default(action.default) in text, (command, action.option_strings)
        else:
            assert stated == show_default(action.default), (command, action.option_strings, text)


def _guide_tables():
    """(command, flag cell, default cell) of every option row of the user guide's command sections."""
    command = None
    for line in GUIDE.read_text(encoding="utf-8").splitlines():
        heading = re.match(r"### `sensorplan (\w+)`", line)
        if heading:
            command = heading.group(1)
        elif line.startswith("## "):
            command = None
        elif command and line.startswith("| `-"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            yield command, cells[0], cells[1]


def _number(text):
    try:
        return float(text)
    except ValueError:
        return None


def test_user_guide_tables_state_the_parser_defaults():
    parser = build_parser()
    rows = list(_guide_tables())
    assert {c for c, _, _ in rows} >= {"report", "recommend", "verify", "invert", "detectability"}
    for command, flags, default in rows:
        sub = parser.commands[command]
        flag = re.match(r"`(--[\w-]+)", flags).group(1)
        action = next(a for a in sub.option_actions if flag in a.option_strings)
        choices = re.search(r"\{([^}]+)\}", flags)
        if choices and action.choices is not None:
            assert set(choices.group(1).split(",")) == set(action.choices), (command, flag)
        first = default.replace("`", "").split(" (")[0].strip()
        where = (command, flag, default, action.default)
        # what the parser uses; for an option given as None, the default its help states ("(default 0.25)")
        expected = action.default if action.default is not None else _stated(action.help or "")
        if action.required:
            assert first == "required", where
        elif expected is False:
            assert first == "off", where
        elif expected is None or _number(show_default(expected)) is None and action.default is None:
            assert _number(first) is None, where  # words: "none", "the case's sensors", ...
        elif _number(first.split()[0]) is not None:  # "1 per sensor"
            assert _number(first.split()[0]) == pytest.approx(float(show_default(expected))), where
        else:
            assert first == show_default(expected), where
