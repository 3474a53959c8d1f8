"""The benchmark script runs (small counts) and prints its table."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_bench_runs_small() -> None:
    r = subprocess.run(
        [sys.executable, str(REPO / "bench" / "bench_calibrator.py"), "--problems", "20", "--trials", "50",
         "--baseline-runs", "3"],
        capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "| 20/20 reach the optimum" in r.stdout.replace(
        "convergence from no guess (random rotation, 6-30 poses, D435 noise) ", ""
    )
    assert "Cramer-Rao" in r.stdout and "x faster" in r.stdout


def test_targets_bench_runs_small() -> None:
    r = subprocess.run(
        [sys.executable, str(REPO / "bench" / "bench_calibrator_targets.py"), "--trials", "4"],
        capture_output=True, text=True, timeout=400,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "| lab: 11 real blob samples" in r.stdout and "LOO 2.38 mm" in r.stdout
    assert "not present (--reghec DIR)" in r.stdout and "best OpenCV method per set" in r.stdout
