"""ruff and mypy on the gripper package and its tests."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
PATHS = ["services/gripper/src", "tests/gripper", "bench/bench_gripper.py"]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=240)


def test_ruff() -> None:
    paths = [p for p in PATHS if (REPO / p).exists()]
    lint = run(str(BIN / "ruff"), "check", *paths)
    assert lint.returncode == 0, lint.stdout
    fmt = run(str(BIN / "ruff"), "format", "--check", *paths)
    assert fmt.returncode == 0, fmt.stdout


def test_mypy() -> None:
    result = run(str(BIN / "mypy"), "services/gripper/src")
    assert result.returncode == 0, result.stdout


def test_no_heavy_imports() -> None:
    """The gripper image stays small: no open3d, scipy, replay or detector in the gripper's code."""
    banned = {"open3d", "scipy", "sofia_replay", "sofia_detector", "sofia_calibrator"}
    for path in (REPO / "services/gripper/src/sofia_gripper").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            assert not {n.split(".")[0] for n in names} & banned, f"{path.name} imports {names}"
    runtime = sorted(banned)
    code = f"import sys, sofia_gripper.service, sofia_gripper.cli; print(sorted(set(sys.modules) & {set(runtime)!r}))"
    result = run(sys.executable, "-c", code)
    assert result.stdout.strip() == "[]", result.stdout + result.stderr
