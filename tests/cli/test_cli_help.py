"""The `sofia` argparse tree (every installed package's commands): every option says what it is,
with its unit and default; one option name means one thing; renamed options keep their old
spelling as a hidden alias."""

from __future__ import annotations

import argparse
import functools
from collections.abc import Iterator

import pytest
from sofia_runtime import cli

# a float or int option must name its unit (or say it is a count, a ratio, an id ...)
UNIT_WORDS = (
    " s", "seconds", "ms", "hz", " m", "mm", "metres", "deg", "rad", "multiplier", "number", "count",
    "id", "seed", "index", "n ", "fraction", "bit/s", "newtons", "ma", "samples", "clouds", "poses",
    "scenes", "messages", "(0, 1]", "ticks", "version", "pixels",
)  # fmt: skip


@functools.cache
def build_parser() -> argparse.ArgumentParser:
    """The whole tree, built once (loading every package's commands takes a while)."""
    return cli.build_parser()


def walk(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:  # fmt: skip
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield from walk(child, (*path, name))


def options(parser: argparse.ArgumentParser) -> Iterator[argparse.Action]:
    for a in parser._actions:
        if isinstance(a, argparse._HelpAction | argparse._VersionAction | argparse._SubParsersAction):
            continue
        if a.help == argparse.SUPPRESS:  # a hidden deprecated alias
            continue
        yield a


def name(path: tuple[str, ...], a: argparse.Action) -> str:
    return f"sofia {' '.join(path)} {'/'.join(a.option_strings) or a.dest}"


def gaps(check: object) -> list[str]:
    """Every option of every command (all installed packages) that fails ``check``."""
    found: list[str] = []
    for path, parser in walk(build_parser()):
        for a in options(parser):
            problem = check(a)  # type: ignore[operator]
            if problem:
                found.append(f"{name(path, a)}: {problem}")
    return found


def test_the_tree_has_the_commands_of_every_package() -> None:
    commands = {p[0] for p, _ in walk(build_parser()) if p}
    expected = {"echo", "query", "health", "router", "up", "demo", "schemas", "replay", "synth", "detect"}
    assert expected | {"detector", "calibrate", "calibrator"} <= commands


def test_every_option_has_help() -> None:
    found = gaps(lambda a: "no help text" if not (a.help or "").strip() else None)
    assert not found, "\n".join(found)


def test_every_default_is_shown() -> None:
    """`--help` names the default of every option that has one (said in the text or appended)."""

    def check(a: argparse.Action) -> str | None:
        if not a.option_strings or a.default in (None, False, []):
            return None
        parser = argparse.ArgumentParser(formatter_class=cli.HelpFormatter)
        parser._add_action(a)
        text = " ".join(parser.format_help().split())
        return None if "default" in text else f"default {a.default!r} not shown"

    found = gaps(check)
    assert not found, "\n".join(found)


def test_numeric_options_name_their_unit() -> None:
    def check(a: argparse.Action) -> str | None:
        if a.type not in (int, float):
            return None
        text = f" {(a.help or '').lower()} {(a.metavar or '') if isinstance(a.metavar, str) else ''} ".lower()
        return None if any(w in text for w in UNIT_WORDS) else f"no unit in {a.help!r}"

    found = gaps(check)
    assert not found, "\n".join(found)


def test_up_demo_and_command_groups_are_described() -> None:
    parsers = dict(walk(build_parser()))
    for path in [("up",), ("demo",), ("replay",), ("synth",), ("replay", "export"), ("router",)]:
        assert (parsers[path].description or "").strip(), f"sofia {' '.join(path)} has no description"
    assert "exit codes" in (build_parser().epilog or "")


@pytest.mark.parametrize(
    "argv,dest,value",
    [
        (["synth", "scenes", "o.mcap", "--hz", "5"], "hz", 5.0),
        (["synth", "scenes", "o.mcap", "--rate", "5"], "hz", 5.0),  # the old spelling, hidden
        (["synth", "scenes", "o.mcap"], "hz", 10.0),
        (["synth", "calibration", "o.mcap", "--n-poses", "3"], "n_poses", 3),
        (["synth", "calibration", "o.mcap", "--poses", "3"], "n_poses", 3),
        (["synth", "calibration", "o.mcap"], "n_poses", 12),
        (["demo", "--n-poses", "4", "--n-scenes", "3"], "n_poses", 4),
        (["demo", "--poses", "4"], "n_poses", 4),
        (["demo", "--scenes", "3"], "n_scenes", 3),
        (["replay", "convert", "a.bag", "b.mcap", "--rename", "/a=/b"], "rename", ["/a=/b"]),
        (["replay", "convert", "a.bag", "b.mcap", "--topic", "/a=/b"], "rename", ["/a=/b"]),
        (["replay", "play", "r.mcap", "--loop"], "restamp", None),  # None: follows --loop
        (["replay", "play", "r.mcap", "--loop", "--no-restamp"], "restamp", False),
        (["arm", "serve", "--sim", "--hz", "100"], "hz", 100.0),
        (["arm", "serve", "--sim", "--rate", "100"], "hz", 100.0),  # the old spelling, hidden
    ],
)
def test_renamed_options_and_their_hidden_aliases(argv: list[str], dest: str, value: object) -> None:
    assert getattr(cli.build_parser().parse_args(argv), dest) == value  # a fresh parser: parsing sets state


def test_one_name_means_one_thing() -> None:
    """`--rate` is a playback multiplier and `--poses` a file wherever they are offered; counts are
    `--n-*`, frame rates `--hz`."""
    parsers = dict(walk(build_parser()))
    helps = {
        path: {s: a.help or "" for a in options(p) for s in a.option_strings} for path, p in parsers.items()
    }
    for path, h in helps.items():
        if "--rate" in h:
            assert "multiplier" in h["--rate"], (path, h["--rate"])
        if "--poses" in h:
            assert "poses.txt" in h["--poses"], (path, h["--poses"])
    assert "--hz" in helps[("synth", "scenes")] and "--rate" not in helps[("synth", "scenes")]
    assert "--n-poses" in helps[("synth", "calibration")] and "--n-poses" in helps[("demo",)]


def test_router_does_not_offer_another_mode() -> None:
    router = dict(walk(build_parser()))[("router",)]
    assert "--zenoh-mode" not in router.format_help()
