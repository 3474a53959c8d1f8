"""ruff (lint + format) and mypy on every package, the tests and the benchmarks; small modules."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
PACKAGES = [
    "schemas/src",
    "runtime/src",
    "system/src",
    "replay/src",
    "services/detector/src",
    "services/calibrator/src",
    "services/gripper/src",
    "services/camera/src",
    "services/arm/src",
    "services/viz/src",
]
MAX_MODULE_LINES = 300


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=600)


def test_ruff_lint() -> None:
    r = run(str(BIN / "ruff"), "check", ".")
    assert r.returncode == 0, r.stdout + r.stderr


def test_ruff_format() -> None:
    r = run(str(BIN / "ruff"), "format", "--check", ".")
    assert r.returncode == 0, r.stdout + r.stderr


def test_mypy() -> None:
    r = run(str(BIN / "mypy"))  # files and settings from pyproject.toml: every package
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.parametrize("package", PACKAGES)
def test_modules_are_small(package: str) -> None:
    long = {
        p.name: n
        for p in (REPO / package).rglob("*.py")
        if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES
    }
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


@pytest.mark.parametrize("package", PACKAGES)
def test_packages_ship_py_typed(package: str) -> None:
    assert list((REPO / package).glob("*/py.typed")), f"{package} has no py.typed"
