"""The ``sofia`` command. Each installed SofIA package adds its subcommands through the
``sofia.commands`` entry-point group: an entry point is a function ``register(subparsers)`` that
adds one or more subparsers and sets ``func(args) -> int`` on them with ``set_defaults``.

Exit codes, the same for every command: 0 success; 1 the job failed (no reply, an error reply, no
object when one was required, a failed check); 2 a usage or input error (a bad option, a missing
or unreadable input file, a value out of range). ``func`` returns 0 or 1; input errors are raised
as ``ValueError`` or ``OSError`` and turned into exit 2 with their message here.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from importlib.metadata import PackageNotFoundError, entry_points, version
from pathlib import Path

from sofia_schemas.messages import ALL_MESSAGES

from .output import add_command, add_group, emit

log = logging.getLogger("sofia")


EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


class HelpFormatter(argparse.HelpFormatter):
    """Appends an option's default to its help when the help does not already name it."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        shown = action.default not in (None, False, argparse.SUPPRESS, [])
        if not action.option_strings or not shown or "default" in text or "%(default)" in text:
            return text
        return f"{text} (default %(default)s)"


def sofia_version() -> str:
    try:
        return version("sofia-runtime")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "unknown"


def register_schemas(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    s = add_group(sub, "schemas", "message schemas", description="The JSON Schemas of the bus messages.")
    e = add_command(s, "export", _export, "write the JSON Schema of every bus message into DIR",
                    "the folder and the files written, one object")  # fmt: skip
    e.add_argument("dir", type=Path,
                   help="folder to write <Message>.schema.json files into (made if missing)")  # fmt: skip


def _export(args: argparse.Namespace) -> int:
    args.dir.mkdir(parents=True, exist_ok=True)
    written = []
    for model in ALL_MESSAGES:
        path = args.dir / f"{model.__name__}.schema.json"
        path.write_text(json.dumps(model.model_json_schema(), indent=2) + "\n")
        written.append(path)
    emit(args, {"dir": args.dir, "files": written}, "\n".join(map(str, written)))
    return 0


# `sofia --help` lists the commands in these groups, in this order; a command of a package not named
# here is listed under "more".
COMMAND_GROUPS = (
    ("get started", ("demo", "up")),
    ("your own data, no services needed", ("calibrate", "detect", "replay", "synth")),
    ("the bus", ("echo", "query", "health", "router", "schemas")),
    ("services and devices", ("detector", "calibrator", "camera", "arm", "gripper")),
    ("ROS 2 and Foxglove", ("ros2", "viz")),
)
EXIT_CODES = """exit codes (every command):
  0    success
  1    the job ran and failed (an error reply or no reply, a failed check, an unhealthy service)
  2    usage or input error (an unknown option, a bad value, a missing or unreadable file)
  3    `sofia health`: a service is degraded (serving, not healthy; 0 with --degraded-ok)
  130  interrupted (Ctrl-C before the command got going)"""


class RootHelpFormatter(argparse.RawDescriptionHelpFormatter, HelpFormatter):
    """The root command's help: its grouped command list and exit-code table as written."""


def _grouped_commands(sub: argparse._SubParsersAction) -> str:  # type: ignore[type-arg]
    """The commands of ``sub`` with their one-line help, in ``COMMAND_GROUPS`` order."""
    helps = {a.dest: a.help or "" for a in sub._choices_actions}
    named = {c for _, cs in COMMAND_GROUPS for c in cs}
    groups = [*COMMAND_GROUPS, ("more", tuple(sorted(c for c in helps if c not in named)))]
    lines = ["commands:"]
    for title, names in groups:
        present = [n for n in names if n in helps]
        if present:
            lines.append(f"  {title}:")
            lines += [f"    {n:<12}{helps[n]}" for n in present]
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sofia", description="SofIA: calibrate, detect, grasp.", epilog=EXIT_CODES,
    )  # fmt: skip
    parser.add_argument("--version", action="version", version=f"sofia {sofia_version()}")
    parser.add_argument("--log-level", default="INFO", choices=("DEBUG", "INFO", "WARNING", "ERROR"),
                        type=str.upper, help="log messages shown on stderr (default INFO)")  # fmt: skip
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for ep in sorted(entry_points(group="sofia.commands"), key=lambda e: e.name):
        try:
            ep.load()(sub)
        except ImportError as e:  # a package whose optional dependencies are missing
            log.debug("command %s unavailable: %s", ep.name, e)
    for p in iter_parsers(parser):
        p.formatter_class = HelpFormatter
        p.set_defaults(error_prefix=p.prog)  # the deepest command's wins: `sofia replay play`
    parser.formatter_class = RootHelpFormatter
    parser.usage = "%(prog)s [-h] [--version] [--log-level {DEBUG,INFO,WARNING,ERROR}] COMMAND ..."
    parser.description = f"SofIA: calibrate, detect, grasp.\n\n{_grouped_commands(sub)}"
    sub.help = argparse.SUPPRESS  # listed in the groups above instead
    return parser


def iter_parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """``parser`` and every subcommand parser under it, depth first."""
    out = [parser]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in dict.fromkeys(action.choices.values()):  # aliases map to the same parser
                out.extend(iter_parsers(child))
    return out


def _error_text(e: Exception) -> str:
    """``[Errno 2] No such file or directory: 'x'`` -> ``x: no such file or directory``."""
    if isinstance(e, OSError) and e.filename is not None and e.strerror:
        return f"{e.filename}: {e.strerror[0].lower()}{e.strerror[1:]}"
    return str(e)


def main(argv: list[str] | None = None) -> int:
    from .memory import bound_heap

    bound_heap()  # before any thread starts: few malloc arenas, so freed memory can go back
    try:
        args = build_parser().parse_args(argv)  # imports every command's package: Ctrl-C may come here
    except KeyboardInterrupt:
        return 130
    from .service import setup_logging

    setup_logging(args.log_level, getattr(args, "log_file", None))
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # `sofia ... | head`: the reader has seen enough
        sys.stdout = open(os.devnull, "w")  # silences the flush at exit
        return EXIT_OK
    except (ValueError, OSError) as e:  # bad input: a file, a value (see the exit codes above)
        print(f"{args.error_prefix}: error: {_error_text(e)}", file=sys.stderr)  # as argparse's own
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
