"""docs/cli.md's synopsis ("## Commands") matches the parser: every command is there, each line
names exactly the long options its command takes, and every option has a --help text."""

import argparse
import re
from pathlib import Path

import pytest

from tiltpile.cli import COMMANDS, build_parser

DOC = (Path(__file__).resolve().parents[2] / "docs" / "cli.md").read_text()


def _synopsis() -> dict[str, str]:
    """Each command's synopsis lines (continuations included, comments dropped), by command."""
    block = DOC.split("## Commands", 1)[1].split("```", 2)[1]
    lines: dict[str, str] = {}
    command = None
    for line in block.splitlines():
        m = re.match(r"tiltpile ([\w-]+)", line)
        if m:
            command = m.group(1)
            lines.setdefault(command, "")
        if command:
            lines[command] += " " + line.split("#", 1)[0]
    return lines


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_the_synopsis_lists_every_command():
    assert sorted(_synopsis()) == sorted(COMMANDS)


@pytest.mark.parametrize("command", COMMANDS)
def test_the_synopsis_names_exactly_the_commands_options(command):
    parser = _subparsers()[command]
    options = {o for a in parser._actions for o in a.option_strings if o.startswith("--") and o != "--help"}
    listed = set(re.findall(r"--[a-z][\w-]*", _synopsis()[command]))
    assert options - listed == set(), f"tiltpile {command}: options missing from docs/cli.md"
    assert listed - options == set(), f"tiltpile {command}: docs/cli.md lists options it does not take"


@pytest.mark.parametrize("command", COMMANDS)
def test_every_option_says_what_it_does(command):
    parser = _subparsers()[command]
    silent = [a.option_strings or a.dest for a in parser._actions
              if not isinstance(a, argparse._HelpAction) and not a.help]
    assert silent == [], f"tiltpile {command}: options without a --help text"
