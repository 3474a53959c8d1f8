"""The ``sofia`` command. Each installed SofIA package adds its subcommands through the
``sofia.commands`` entry-point group: an entry point is a function ``register(subparsers)`` that
adds one or more subparsers and sets ``func(args) -> int`` on them with ``set_defaults``.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from importlib.metadata import entry_points
from pathlib import Path

from .messages import ALL_MESSAGES

log = logging.getLogger("sofia")


def register_schemas(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("schemas", help="message schemas")
    s = p.add_subparsers(dest="schemas_cmd", required=True)
    e = s.add_parser("export", help="write the JSON Schema of every bus message into DIR")
    e.add_argument("dir", type=Path)
    e.set_defaults(func=_export)


def _export(args: argparse.Namespace) -> int:
    args.dir.mkdir(parents=True, exist_ok=True)
    for model in ALL_MESSAGES:
        path = args.dir / f"{model.__name__}.schema.json"
        path.write_text(json.dumps(model.model_json_schema(), indent=2) + "\n")
        print(path)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sofia", description="SofIA: calibrate, detect, grasp.")
    parser.add_argument("--log-level", default="INFO", help="DEBUG, INFO, WARNING, ERROR")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for ep in sorted(entry_points(group="sofia.commands"), key=lambda e: e.name):
        try:
            ep.load()(sub)
        except ImportError as e:  # a package whose optional dependencies are missing
            log.debug("command %s unavailable: %s", ep.name, e)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from .service import setup_logging

    setup_logging(args.log_level, getattr(args, "log_file", None))
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return 130
    except (ValueError, FileNotFoundError, OSError) as e:
        print(f"sofia {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
