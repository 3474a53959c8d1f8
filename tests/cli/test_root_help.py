"""`sofia --help` lists every command once, grouped and in a fixed order (getting started first),
and prints the exit-code table it promises, as `sofia --help` shows it to a person."""

from __future__ import annotations

import argparse
import re
import subprocess
from pathlib import Path

from sofia_runtime import cli
from sofia_system.launcher import sofia_executable


def test_sofia_help_groups_every_command_once_and_shows_the_exit_codes() -> None:
    r = subprocess.run([*sofia_executable(), "--help"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    text = r.stdout
    assert text.startswith("usage: sofia ") and "COMMAND ..." in text.splitlines()[0]
    sub = next(a for a in cli.build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    listed = re.findall(r"^    (\S+)\s", text, re.M)
    assert sorted(listed) == sorted(sub.choices) and len(listed) == len(set(listed)), listed
    titles = [title for title, names in cli.COMMAND_GROUPS if set(names) & set(sub.choices)]
    positions = [text.index(f"  {title}:\n") for title in titles]
    assert positions == sorted(positions) and listed[:2] == ["demo", "up"]
    table = text[text.index("exit codes") :]
    for code, meaning in (
        ("0", "success"),
        ("1", "failed"),
        ("2", "usage or input error"),
        ("130", "interrupted"),
    ):
        assert re.search(rf"^  {code}\s+.*{meaning}", table, re.M), (code, table)


def test_a_command_of_another_package_is_listed_under_more() -> None:
    parser = argparse.ArgumentParser(prog="sofia")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.add_parser("detect", help="detect the objects")
    sub.add_parser("weld", help="a package's own command")
    text = cli._grouped_commands(sub)
    assert text.index("your own data") < text.index("detect") < text.index("  more:") < text.index("weld")


def test_an_input_error_names_the_whole_command_as_a_usage_error_does(tmp_path: Path) -> None:
    missing = tmp_path / "nope.mcap"
    for argv in (["replay", "info", str(missing)], ["replay", "info", "--no-such-option"]):
        r = subprocess.run([*sofia_executable(), *argv], capture_output=True, text=True, timeout=120)
        assert r.returncode == 2, r.stderr
        assert r.stderr.strip().splitlines()[-1].startswith("sofia replay info: error: "), r.stderr
