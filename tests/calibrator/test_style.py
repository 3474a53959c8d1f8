"""ruff (lint + format) and mypy are clean on the calibrator's code."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
PATHS = ["services/calibrator", "tests/calibrator", "bench/bench_calibrator.py",
         "schemas/src/sofia_schemas/messages/calibration.py"]  # fmt: skip


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(list(args), cwd=REPO, capture_output=True, text=True, timeout=240)


def test_ruff() -> None:
    r = run(str(BIN / "ruff"), "check", *PATHS)
    assert r.returncode == 0, r.stdout + r.stderr
    r = run(str(BIN / "ruff"), "format", "--check", *PATHS)
    assert r.returncode == 0, r.stdout + r.stderr


def test_mypy() -> None:
    r = run(str(BIN / "mypy"), "services/calibrator/src")
    assert r.returncode == 0, r.stdout + r.stderr
