"""The documentation site builds with `mkdocs build --strict` (a broken link, a missing page of the
nav, a bad anchor or an API reference that does not resolve fails it), as `make docs` builds it,
and the pages the README and the site promise are there."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).parents[2]
README_MAX_LINES = 150


def nav_pages() -> list[str]:
    """The Markdown files of mkdocs.yml's nav, in nav order."""
    config = yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=yaml.BaseLoader)
    pages: list[str] = []

    def walk(items: object) -> None:
        if isinstance(items, str):
            pages.append(items)
        elif isinstance(items, list):
            for item in items:
                walk(item)
        elif isinstance(items, dict):
            for value in items.values():
                walk(value)

    walk(config["nav"])
    return pages


def test_the_site_builds_strict(tmp_path: Path) -> None:
    site = tmp_path / "site"
    env = os.environ | {"NO_MKDOCS_2_WARNING": "1"}
    r = subprocess.run([str(Path(sys.executable).with_name("mkdocs")), "build", "--strict", "--site-dir", str(site)],
                       cwd=ROOT, capture_output=True, text=True, timeout=280, env=env)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    for page in nav_pages():
        built = site / (page[: -len(".md")] + "/index.html" if page != "index.md" else "index.html")
        assert built.is_file(), f"{page} was not built"
    cli = (site / "reference" / "cli" / "index.html").read_text()
    assert "sofia calibrate" in cli and "--transform" in cli
    keys = (site / "reference" / "bus-keys" / "index.html").read_text()
    assert "sofia/{robot}/detector/detections" in keys and "schema_version" in keys


def test_the_nav_lists_every_page_and_the_sections_the_reader_needs() -> None:
    pages = nav_pages()
    written = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    generated = {"reference/cli.md", "reference/bus-keys.md"}
    assert written | generated == set(pages), set(pages) ^ (written | generated)
    for needed in ("getting-started.md", "how-to/calibrate-from-files.md", "how-to/detect-your-cloud.md",
                   "how-to/ros2.md", "how-to/camera.md", "how-to/franka.md", "how-to/gripper.md",
                   "how-to/docker.md", "concepts/architecture.md", "concepts/frames.md",
                   "concepts/calibration.md", "concepts/detection.md", "benchmarks.md"):  # fmt: skip
        assert needed in pages, needed


def test_the_readme_is_two_screens_with_the_two_commands_and_links_into_the_site() -> None:
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= README_MAX_LINES
    assert "make demo    # set up" in text and "make test    # set up" in text
    links = re.findall(r"\]\((docs/[^)#]+)", text)
    assert len(links) >= 10, links
    missing = [link for link in links if not (ROOT / link).is_file()]
    assert not missing, missing
