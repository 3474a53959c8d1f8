"""The generated reference pages match the code: every command and visible option of the `sofia`
parsers is on the CLI page, every key of `Keys` (with the payload it carries) and every message's
JSON Schema on the bus-keys page; an option or a key added in the code shows up without editing
Markdown."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
from pathlib import Path
from types import ModuleType

from sofia_runtime import cli
from sofia_schemas import Keys
from sofia_schemas.messages import ALL_MESSAGES, Detection

ROOT = Path(__file__).parents[2]


def generator() -> ModuleType:
    spec = importlib.util.spec_from_file_location("docs_reference", ROOT / "docs" / "_gen" / "reference.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_command_and_option_of_the_parsers_is_on_the_cli_page() -> None:
    gen = generator()
    parser = cli.build_parser()
    page = gen.cli_markdown(parser)
    paths = gen._parser_path(parser)
    assert len(paths) > 40, len(paths)
    missing = []
    for path, p, _ in paths:
        section = page.split(f"`{path}`\n", 1)
        if len(section) < 2:
            missing.append(path)
            continue
        body = section[1].split("\n#", 1)[0]
        missing += [f"{path} {s}" for a in gen.visible_options(p) for s in a.option_strings or [a.dest]
                    if f"`{s}`" not in body and f"`{a.metavar}`" not in body]  # fmt: skip
    assert not missing, missing


def test_an_option_added_to_a_parser_shows_up() -> None:
    gen = generator()
    parser = cli.build_parser()
    detect = next(p for path, p, _ in gen._parser_path(parser) if path == "sofia detect")
    before = gen.cli_markdown(parser)
    detect.add_argument(
        "--max-depth-m", type=float, default=1.5, help="drop points farther than this, metres"
    )
    after = gen.cli_markdown(parser)
    assert "--max-depth-m" not in before
    row = next(line for line in after.splitlines() if "`--max-depth-m`" in line)
    assert "`1.5`" in row and "metres" in row


def test_every_key_of_keys_is_on_the_bus_keys_page_with_its_payload() -> None:
    gen = generator()
    page = gen.keys_page()
    names = gen.key_attributes(Keys)
    assert {"points", "detections", "detect", "calibrator_op", "status", "arm_progress"} <= set(names)
    undocumented = [n for n in names if n not in gen.KEY_PAYLOADS]
    assert not undocumented, f"describe these keys' payloads in KEY_PAYLOADS: {undocumented}"
    keys = Keys("panda")
    for name in names:
        for expr in gen.key_expressions(keys, name):
            assert f"`{expr.replace('/panda/', '/{robot}/')}` | `Keys.{name}`" in page, expr
    assert "`sofia/{robot}/calibrator/solve`" in page and "`sofia/{robot}/arm/status`" in page
    for model in ALL_MESSAGES:
        assert f"### {model.__name__}\n" in page
    schema = json.dumps(Detection.model_json_schema(), indent=2)
    assert schema in page


def test_a_key_added_to_keys_shows_up() -> None:
    gen = generator()

    @dataclasses.dataclass(frozen=True)
    class MoreKeys(Keys):
        @property
        def camera_health(self) -> str:
            """Health of the camera's USB link."""
            return f"{self.prefix}/camera/health"

    page = gen.keys_markdown(MoreKeys, ALL_MESSAGES)
    row = next(line for line in page.splitlines() if "`sofia/{robot}/camera/health`" in line)
    assert "Health of the camera's USB link." in row and "not documented" in row
    assert "| `sofia/{robot}/points` | `Keys.points` |" in page  # the inherited keys too


def test_the_generated_pages_are_the_ones_the_site_builds() -> None:
    gen = generator()
    assert gen.CLI_PAGE == "reference/cli.md" and gen.KEYS_PAGE == "reference/bus-keys.md"
    assert isinstance(gen.cli_page(), str) and gen.cli_page() == gen.cli_markdown(cli.build_parser())
