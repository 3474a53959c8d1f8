"""The documented commands exist as written: every `sofia ...` line of the fenced bash blocks (and every
`$ sofia ...` line of the transcripts) of the README, CONTRIBUTING.md and every page of the
documentation site (``docs/``, in the order of mkdocs.yml's nav) parses with the real `sofia` argument tree (command path,
options, choices, value types); every `make` target is in the Makefile, every compose profile and
service in compose.yaml, every script or test path in the tree. Nothing is run: a command the docs
name that does not exist, or an option it does not take, fails here in seconds.

The docs' own notation is read as a reader would: `[--opt V]` is optional (checked with it),
`a | b` after a command word and `on|off` are alternatives (each checked), `\\` continues a line,
`&&` chains commands, `#` starts a comment, `VAR=1 sofia ...` sets the environment.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import itertools
import re
import shlex
from pathlib import Path

import pytest
import yaml
from sofia_runtime import cli

ROOT = Path(__file__).parents[2]
README = ROOT / "README.md"
PIPE_PROGRAMS = {"head", "tail", "jq", "grep", "less", "wc", "tee", "sort", "cat"}  # `cmd | head` is a pipe


def fenced_lines(text: str) -> list[tuple[int, str]]:
    """(line number, command line) of the bash blocks, and the `$ ` lines of the other blocks;
    continued lines (ending in `\\`) joined."""
    out: list[tuple[int, str]] = []
    lang: str | None = None
    pending, start = "", 0
    for number, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith("```"):  # a fence, also indented inside a list item
            lang = line.lstrip()[3:].strip() if lang is None else None
            continue
        if lang is None:
            continue
        s = line.strip()
        if lang != "bash":
            if not s.startswith("$ "):
                continue
            s = s[2:]
        if pending:
            s, number = pending + " " + s, start
        if s.endswith("\\"):
            pending, start = s[:-1].rstrip(), number
            continue
        pending = ""
        if s:
            out.append((number, s))
    return out


def commands(line: str) -> list[list[str]]:
    """The commands a documented line stands for, each as argv (first word the program)."""
    line = re.sub(r"\[([^\[\]]*)\]", r"\1", line)  # optional parts: checked as given
    tokens = shlex.split(line, comments=True)
    out: list[list[str]] = []
    for _, chained in itertools.groupby(tokens, lambda t: t in ("&&", ";", "||")):
        segment = list(chained)
        if segment[0] in ("&&", ";", "||"):
            continue
        parts = [list(g) for k, g in itertools.groupby(segment, lambda t: t == "|") if not k]
        base, variants = parts[0], [parts[0]]
        for alt in parts[1:]:
            if alt[0] not in PIPE_PROGRAMS:  # `sofia arm home | stop`: another last word
                variants.append(base[:-1] + alt)
        for v in variants:
            while v and re.fullmatch(r"[A-Z_][A-Z0-9_]*=\S*", v[0]):  # VAR=value before the program
                v = v[1:]
            choices = [t.split("|") if "|" in t else [t] for t in v]  # `on|off`: each
            out.extend(list(c) for c in itertools.product(*choices))
    return [c for c in out if c]


@functools.cache
def parser() -> argparse.ArgumentParser:
    return cli.build_parser()


def parse_error(argv: list[str]) -> str | None:
    """None when ``sofia ARGV`` parses, else argparse's message."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            parser().parse_args(argv)
        except SystemExit as e:
            return err.getvalue().strip().splitlines()[-1] if e.code else None
    return None


def old_spellings(argv: list[str]) -> set[tuple[str, str]]:
    """(command, option) of the options of ``sofia ARGV`` that are hidden old names (renamed, still
    accepted)."""
    p, path = parser(), []
    for token in argv:
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if subs and token in subs[0].choices:
            p = subs[0].choices[token]
            path.append(token)
    hidden = {s for a in p._actions if a.help == argparse.SUPPRESS for s in a.option_strings}
    return {(" ".join(path), t.split("=")[0]) for t in argv if t.split("=")[0] in hidden}


KNOWN_OLD_SPELLINGS: set[tuple[str, str]] = set()  # old spellings the docs may still use: none


def doc_pages() -> list[Path]:
    """The README, CONTRIBUTING.md and the site's written pages in nav order (the generated
    reference pages hold usage lines, not commands to run)."""
    config = yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=yaml.BaseLoader)
    pages: list[str] = []

    def walk(items: object) -> None:
        if isinstance(items, str):
            pages.append(items)
        for item in items if isinstance(items, list) else items.values() if isinstance(items, dict) else []:
            walk(item)

    walk(config["nav"])
    written = [ROOT / "docs" / p for p in pages if (ROOT / "docs" / p).is_file()]
    return [README, ROOT / "CONTRIBUTING.md", *written]


def page_commands(page: Path) -> list[tuple[str, list[str]]]:
    """(``page:line``, argv) of every command of ``page``."""
    where = page.relative_to(ROOT).as_posix()
    return [(f"{where}:{n}", argv) for n, line in fenced_lines(page.read_text()) for argv in commands(line)]


def doc_commands() -> list[tuple[str, list[str]]]:
    return [c for page in doc_pages() for c in page_commands(page)]


def test_every_sofia_command_in_the_docs_parses() -> None:
    sofia = [(n, argv) for n, argv in doc_commands() if argv[0] == "sofia"]
    assert len(sofia) > 50, f"only {len(sofia)} sofia commands found in the docs: is the parsing broken?"
    wrong = [f"{n}: sofia {shlex.join(argv[1:])}: {e}" for n, argv in sofia
             if (e := parse_error(argv[1:])) is not None]  # fmt: skip
    assert not wrong, "\n".join(wrong)


def test_the_docs_use_no_old_spelling_of_a_renamed_option() -> None:
    found = {f"{n}: sofia {command} {option}" for n, argv in doc_commands() if argv[0] == "sofia"
             for command, option in old_spellings(argv[1:]) - KNOWN_OLD_SPELLINGS}  # fmt: skip
    assert not found, "use the new option names (see `sofia ... --help`):\n" + "\n".join(sorted(found))


def test_make_targets_compose_profiles_scripts_and_test_paths_in_the_docs_exist() -> None:
    makefile = (ROOT / "Makefile").read_text()
    targets = set(re.findall(r"^([\w.-]+):", makefile, re.M))
    services = yaml.safe_load((ROOT / "compose.yaml").read_text())["services"]
    profiles = {p for s in services.values() for p in s.get("profiles", [])}
    wrong: list[str] = []
    for n, argv in doc_commands():
        if argv[0] == "make":
            wrong += [f"{n}: make {t}: no such target" for t in argv[1:] if t not in targets]
        elif argv[:2] == ["docker", "compose"]:
            named = [b for a, b in itertools.pairwise(argv) if a == "--profile"]
            wrong += [f"{n}: compose has no profile {p}" for p in named if p not in profiles]
            if "logs" in argv:
                wrong += [f"{n}: compose has no service {s}" for s in argv[argv.index("logs") + 1 :]
                          if not s.startswith("-") and s not in services]  # fmt: skip
        elif argv[0].endswith("python") or argv[0] == "bash":
            for path in (a.split("::")[0] for a in argv[1:]):
                if re.fullmatch(r"(bench|tests|scripts|\.ci)/[\w./-]+", path) and not (ROOT / path).exists():
                    wrong.append(f"{n}: {path} does not exist")
    assert not wrong, "\n".join(wrong)


@pytest.mark.parametrize(
    "line,expected",
    [
        ("sofia arm home | stop   # c", [["sofia", "arm", "home"], ["sofia", "arm", "stop"]]),
        ("sofia gripper torque on|off", [["sofia", "gripper", "torque", "on"], ["sofia", "gripper", "torque", "off"]]),
        ("SOFIA_ROS2=1 sofia up [--ros2] && make demo", [["sofia", "up", "--ros2"], ["make", "demo"]]),
        ("sofia echo k --json | head -3", [["sofia", "echo", "k", "--json"]]),
    ],
)  # fmt: skip
def test_the_readme_notation_is_read_as_meant(line: str, expected: list[list[str]]) -> None:
    assert commands(line) == expected


def test_a_command_or_option_that_does_not_exist_fails() -> None:
    text = "```bash\nsofia replay play x.mcap --no-such-option\nsofia detect a.pcd \\\n  --json\n```\n"
    lines = fenced_lines(text)
    assert lines == [(2, "sofia replay play x.mcap --no-such-option"), (3, "sofia detect a.pcd --json")]
    assert "unrecognized arguments: --no-such-option" in (parse_error(commands(lines[0][1])[0][1:]) or "")
    assert parse_error(commands(lines[1][1])[0][1:]) is None
    assert "invalid choice" in (parse_error(["no-such-command"]) or "")
