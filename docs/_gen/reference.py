"""The generated reference pages of the documentation site: every `sofia` command and option from
the argparse parsers, and every bus key from :class:`sofia_schemas.Keys` with the JSON Schema of its
messages from the pydantic models. Nothing here is copied by hand: an option or a key added in the
code shows up on the next `mkdocs build` (`make docs`).

Used as an MkDocs hook (``hooks:`` in mkdocs.yml): :func:`on_files` adds the pages
``reference/cli.md`` and ``reference/bus-keys.md`` to the build, generated in memory.
``tests/docs/test_reference.py`` compares what it generates with the parsers and ``Keys``.
"""

from __future__ import annotations

import argparse
import inspect
import json
from typing import Any

CLI_PAGE = "reference/cli.md"
KEYS_PAGE = "reference/bus-keys.md"
ROBOT = "{robot}"

# The payload of each key: (kind, what travels, the JSON message models of it). A key of `Keys`
# missing here is still listed (from its docstring), marked as undocumented.
KEY_PAYLOADS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "points": ("put", "CDR `sensor_msgs/msg/PointCloud2`, robot base frame", ()),
    "camera_points": ("put", "CDR `sensor_msgs/msg/PointCloud2`, camera optical frame", ()),
    "camera_info": ("put", "CDR `sensor_msgs/msg/CameraInfo` of the colour stream", ()),
    "flange_pose": ("put", "CDR `geometry_msgs/msg/TransformStamped` (base → flange) or JSON", ("FlangePose",)),
    "detections": ("put", "JSON, one per cloud, stamped with the cloud's stamp", ("Detection",)),
    "detect": ("queryable", "query: CDR `PointCloud2`, JSON selection or empty → JSON", ("Detection",)),
    "blob": ("put", "CDR `geometry_msgs/msg/PointStamped` or JSON (camera frame)", ("BlobObservation",)),
    "calibration_result": ("put + queryable", "JSON", ("CalibrationResult",)),
    "calibrator": ("prefix", "the calibrator's queryables below it", ()),
    "calibrator_op": ("queryable", "JSON in, JSON out", ("CalibrationSample", "CalibrationSamples",
                      "CalibrationSolveOptions", "CalibrationRemove", "CalibrationFiles", "CalibrationResult")),
    "gripper_state": ("put", "JSON", ("GripperState",)),
    "gripper_command": ("queryable", "query: JSON → JSON", ("GripperCommand", "GripperResult")),
    "arm_command": ("queryable", "query: JSON → JSON", ("ArmCommand", "ArmResult")),
    "arm_state": ("put", "JSON", ("ArmState",)),
    "arm_joint_states": ("put", "CDR `sensor_msgs/msg/JointState` (`panda_joint1..7`)", ()),
    "arm_progress": ("put", "JSON, one per step of a running `calibrate` or `pick_place`", ("ArmPhase",)),
    "pick_target": ("put", "JSON: grasp and pre-grasp flange poses, opening", ("PickTarget",)),
    "status": ("put + queryable", "JSON, every second and on query", ("ServiceStatus",)),
}  # fmt: skip
NOT_KEYS = {"prefix", "all", "robot"}  # attributes of Keys that are no single key
SERVICES = ("detector", "calibrator", "gripper", "arm", "camera", "replay", "viz")


def _parser_path(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser, str]]:
    """(command path, parser, help line) of ``parser`` and every subcommand under it, depth first."""
    out: list[tuple[str, argparse.ArgumentParser, str]] = []

    def walk(p: argparse.ArgumentParser, path: str, help_line: str) -> None:
        out.append((path, p, help_line))
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                helps = {a.dest: a.help or "" for a in action._choices_actions}
                for name, child in action.choices.items():
                    if child.prog.split()[-1] == name:  # aliases map to the same parser: once
                        walk(child, f"{path} {name}", helps.get(name, ""))

    walk(parser, parser.prog, parser.description or "")
    return out


def visible_options(p: argparse.ArgumentParser) -> list[argparse.Action]:
    """The options and positionals of ``p`` that ``--help`` shows (not hidden old spellings)."""
    return [a for a in p._actions if a.help != argparse.SUPPRESS
            and not isinstance(a, (argparse._SubParsersAction, argparse._HelpAction))]  # fmt: skip


def _cell(text: Any) -> str:
    """``text`` for one table cell: one line, pipes escaped, reST literals as Markdown code."""
    return str(text).replace("``", "`").replace("|", "\\|").replace("\n", " ")


def _usage(p: argparse.ArgumentParser) -> str:
    formatter = argparse.HelpFormatter(p.prog, width=100)
    formatter.add_usage(p.usage, p._actions, p._mutually_exclusive_groups, prefix="")
    return formatter.format_help().strip()


def _option_row(a: argparse.Action) -> str:
    name = ", ".join(f"`{s}`" for s in a.option_strings) or f"`{a.metavar or a.dest}`"
    value = ""
    if a.choices is not None and not isinstance(a, argparse._SubParsersAction):
        value = " | ".join(f"`{c}`" for c in a.choices)
    elif a.nargs != 0:
        metavar = a.metavar if a.metavar is not None else a.dest.upper()
        value = f"`{' '.join(metavar) if isinstance(metavar, tuple) else metavar}`"
        value += f" ({a.nargs})" if a.nargs in ("+", "*", "?") or isinstance(a.nargs, int) else ""
    shown = a.default not in (None, False, argparse.SUPPRESS, [])
    default = f"`{a.default}`" if shown and a.option_strings else ""
    required = "yes" if a.required or (not a.option_strings and a.nargs not in ("?", "*")) else ""
    return f"| {name} | {_cell(value)} | {_cell(default)} | {required} | {_cell(a.help or '')} |"


def cli_markdown(parser: argparse.ArgumentParser) -> str:
    """The CLI reference page for ``parser`` (the root `sofia` parser) and all its subcommands."""
    lines = ["# Command-line reference", "",
             "Generated from the `sofia` argument parsers when the site is built: every command, "
             "its options, their values and defaults. `sofia COMMAND --help` prints the same.", ""]  # fmt: skip
    for path, p, help_line in _parser_path(parser):
        depth = min(path.count(" "), 3)
        lines += [f"{'#' * (depth + 2) if depth else '##'} `{path}`", ""]
        if p.description and "\n" in p.description:  # written as laid out (the root's command groups)
            lines += ["```text", p.description, "```", ""]
        elif help_line or p.description:
            lines += [_cell(p.description or help_line), ""]
        lines += ["```text", _usage(p), "```", ""]
        actions = visible_options(p)
        if actions:
            lines += ["| option | value | default | required | what |", "|---|---|---|---|---|"]
            lines += [_option_row(a) for a in actions]
            lines.append("")
        if p.epilog:
            lines += ["```text", p.epilog, "```", ""] if "\n" in p.epilog else [_cell(p.epilog), ""]
    return "\n".join(lines)


def key_attributes(keys_cls: type) -> list[str]:
    """The attributes of ``Keys`` that name keys, in the class's order."""
    members = {n: v for c in reversed(keys_cls.__mro__[:-1]) for n, v in vars(c).items()}
    return [n for n, v in members.items() if not n.startswith("_") and n not in NOT_KEYS | {"topic_map"}
            and (isinstance(v, property) or inspect.isfunction(v))]  # fmt: skip


def key_expressions(keys: Any, name: str) -> list[str]:
    """The key expressions attribute ``name`` of ``keys`` stands for (every op / service of a method)."""
    from sofia_runtime.ros2.bridge import CALIBRATOR_OPS

    attr = getattr(keys, name)
    if not callable(attr):
        return [attr]
    args = {"calibrator_op": CALIBRATOR_OPS, "status": SERVICES}.get(name)
    if args is None:
        sig = inspect.signature(attr)
        return [f"{keys.prefix}/<{', '.join(sig.parameters)}>"]
    return [attr(a) for a in args]


def keys_markdown(keys_cls: type, models: tuple[type, ...]) -> str:
    """The bus keys reference page: every key of ``keys_cls`` and the JSON Schema of ``models``."""
    keys = object.__new__(keys_cls)  # the robot id shown as a placeholder, which no real id can be
    object.__setattr__(keys, "robot", ROBOT)
    by_name = {m.__name__: m for m in models}
    lines = ["# Bus keys and messages", "",
             "Generated from `sofia_schemas.Keys` and the pydantic message models when the site is built. "
             "Every key is namespaced by the robot id (`$SOFIA_ROBOT`, default `panda`), shown here as "
             f"`{ROBOT}`.", "", "| key | attribute | kind | payload | messages |", "|---|---|---|---|---|"]  # fmt: skip
    for name in key_attributes(keys_cls):
        kind, payload, names = KEY_PAYLOADS.get(name, ("?", "(payload not documented)", ()))
        doc = inspect.getdoc(getattr(keys_cls, name)) or ""
        what = f"{payload}. {doc.splitlines()[0]}" if doc else payload
        messages = ", ".join(f"[`{n}`](#{n.lower()})" for n in names if n in by_name)
        for expr in key_expressions(keys, name):
            lines.append(f"| `{expr}` | `Keys.{name}` | {kind} | {_cell(what)} | {messages} |")
    lines += ["", "## Messages", "", "Every JSON message carries `schema_version`. "
              "`sofia schemas export DIR` writes these schemas as files.", ""]  # fmt: skip
    for model in models:
        doc = inspect.getdoc(model) or ""
        lines += [f"### {model.__name__}", "", doc.replace("``", "`"), "", "```json",
                  json.dumps(model.model_json_schema(), indent=2), "```", ""]  # fmt: skip
    return "\n".join(lines)


def cli_page() -> str:
    from sofia_runtime import cli

    return cli_markdown(cli.build_parser())


def keys_page() -> str:
    from sofia_schemas import Keys
    from sofia_schemas.messages import ALL_MESSAGES

    return keys_markdown(Keys, ALL_MESSAGES)


def on_files(files: Any, config: Any) -> Any:
    """MkDocs hook: the generated pages, added to the build."""
    from mkdocs.structure.files import File

    for path, make in ((CLI_PAGE, cli_page), (KEYS_PAGE, keys_page)):
        files.append(File.generated(config, path, content=make()))
    return files
