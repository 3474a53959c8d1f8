"""How every ``sofia`` command prints its results: text for people by default; with ``--json``,
JSON for machines: one object per result on one line (a command that prints a stream of results
prints one object per line). Errors and progress go to stderr in both cases.

A package declares its commands with :func:`add_group` and :func:`add_command` (which adds the
option, or :func:`add_json_option` does) and prints with :func:`emit`.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from pydantic import BaseModel

JSON_HELP = "print JSON for machines"  # every --json help starts with this
SubParsers = argparse._SubParsersAction  # type: ignore[type-arg]


def add_json_option(parser: argparse.ArgumentParser, what: str = "one object", text: str = "text") -> None:
    """``--json``: ``what`` says the shape, e.g. "one object per cloud and line"; ``text`` names
    what is printed without it."""
    parser.add_argument(
        "--json", action="store_true", help=f"{JSON_HELP}: {what} (default: {text} for people)"
    )


def add_group(sub: SubParsers, name: str, help: str, metavar: str = "ACTION", **kwargs: Any) -> SubParsers:
    """Group ``sofia NAME ACTION``: where its actions are added (the one chosen: ``args.<name>_cmd``)."""
    parser = sub.add_parser(name, help=help, **kwargs)
    return parser.add_subparsers(dest=f"{name}_cmd", required=True, metavar=metavar)


def add_command(sub: SubParsers, name: str, func: Callable[[argparse.Namespace], int], help: str,
                json: str | None = None, **kwargs: Any) -> argparse.ArgumentParser:  # fmt: skip
    """Sub-command ``name`` that runs ``func(args)`` (its exit code); ``json``: the shape its
    ``--json`` prints (None: no ``--json``); ``kwargs`` go to ``add_parser`` (``description``)."""
    parser: argparse.ArgumentParser = sub.add_parser(name, help=help, **kwargs)
    if json is not None:
        add_json_option(parser, json)
    parser.set_defaults(func=func)
    return parser


def float_arg(what: str, ok: Callable[[float], bool]) -> Callable[[str], float]:
    """An argparse ``type``: a number that ``ok`` accepts, else the error "TEXT is not ``what``"."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not ok(value):
            raise argparse.ArgumentTypeError(f"{text} is not {what}")
        return value

    return parse


def jsonable(value: Any) -> Any:
    """``value`` with pydantic messages, paths and numpy values turned into plain JSON types."""
    if isinstance(value, BaseModel):
        return value.model_dump(mode="json")
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if hasattr(value, "tolist"):  # numpy arrays and scalars
        return value.tolist()
    return value


def emit(args: argparse.Namespace, result: Any, text: str | Callable[[], str]) -> None:
    """Print ``result`` as one JSON line when ``args.json`` is set, else ``text`` (or what it returns)."""
    if getattr(args, "json", False):
        print(json.dumps(jsonable(result)), flush=True)
    else:
        print(text() if callable(text) else text, flush=True)


def fields_text(values: Mapping[str, Any], indent: str = "") -> str:
    """``key: value`` lines for people; nested mappings indented below their key."""
    lines: list[str] = []
    for key, value in values.items():
        if isinstance(value, Mapping) and value:
            lines.append(f"{indent}{key}:")
            lines.append(fields_text(value, indent + "  "))
        elif value is not None and value != [] and value != {}:
            lines.append(f"{indent}{key}: {_short(jsonable(value))}")
    return "\n".join(lines)


def _short(value: Any) -> str:
    """Numbers to 6 significant digits, lists in brackets, for reading."""
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return "[" + ", ".join(_short(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_short(v)}" for k, v in value.items()) + "}"
    return str(value)
