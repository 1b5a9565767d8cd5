"""Every command's --help explains every option, and the README names every command and agent action."""

from __future__ import annotations

import argparse
import importlib
import re

import pytest

from common.cli import add_logging_args
from panostereo.cli import COMMANDS
from tests.support import REPO


def _parsers(name: str) -> list[tuple[str, argparse.ArgumentParser]]:
    parser = argparse.ArgumentParser(prog=f"panostereo {name}")
    add_logging_args(parser)
    importlib.import_module(COMMANDS[name][0]).configure(parser)
    out = [(f"panostereo {name}", parser)]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            out += [(f"panostereo {name} {sub}", p) for sub, p in action.choices.items()]
    return out


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_option_has_help(name: str) -> None:
    missing = [
        f"{prog} {'/'.join(a.option_strings) or a.dest}"
        for prog, parser in _parsers(name)
        for a in parser._actions
        if not isinstance(a, argparse._HelpAction | argparse._SubParsersAction) and not a.help
    ]
    assert not missing, f"options without help: {missing}"


def test_agent_help_lists_every_action_and_the_readme_documents_each() -> None:
    _, *subs = _parsers("agent")
    actions = sorted(prog.rsplit(" ", 1)[1] for prog, _ in subs)
    summary = COMMANDS["agent"][1]
    assert all(a in summary for a in actions), (summary, actions)
    readme = (REPO / "README.md").read_text()
    for action in actions:
        assert re.search(rf"^\| `{action}\b", readme, re.MULTILINE), f"README has no row for agent {action}"
    for name in COMMANDS:
        assert f"panostereo {name}" in readme, f"README never names panostereo {name}"


SESSION_FLAGS = {"--mode", "--multicast-scouting", "--connect", "--listen", "--zenoh-config"}
"""The shared zenoh flags: the README documents them once, for every process that joins a site."""


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_the_readme_names_every_option_of_every_command(name: str) -> None:
    readme = (REPO / "README.md").read_text()
    assert all(f"`{flag}" in readme for flag in SESSION_FLAGS)
    missing = [
        f"{prog} {opt}"
        for prog, parser in _parsers(name)
        for a in parser._actions
        for opt in a.option_strings[-1:]
        if opt.startswith("--") and opt not in ("--help", "--log-level", *SESSION_FLAGS) and opt not in readme
    ]
    assert not missing, f"options the README never names: {missing}"
