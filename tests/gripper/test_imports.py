"""The gripper image stays small: its code pulls in no open3d, scipy, replay, detector or calibrator."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=240)


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
