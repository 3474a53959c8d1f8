"""ruff and mypy on the detector package, its tests and its benchmark; small modules."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
PATHS = [
    "services/detector/src", "tests/detector", "bench/bench_detector.py",
    "schemas/src/sofia_schemas/messages/detection.py", "schemas/src/sofia_schemas/messages/pick.py",
]  # fmt: skip


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=240)


def test_ruff() -> None:
    lint = run(str(BIN / "ruff"), "check", *PATHS)
    assert lint.returncode == 0, lint.stdout
    fmt = run(str(BIN / "ruff"), "format", "--check", *PATHS)
    assert fmt.returncode == 0, fmt.stdout


def test_mypy() -> None:
    result = run(str(BIN / "mypy"), "services/detector/src")
    assert result.returncode == 0, result.stdout


def test_modules_are_small() -> None:
    for path in (REPO / "services/detector/src/sofia_detector").glob("*.py"):
        assert len(path.read_text().splitlines()) < 300, path.name
