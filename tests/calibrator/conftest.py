"""Shared fixtures of the calibrator tests: the lab's real samples."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
LAB = REPO / ".." / "shared" / "data" / "lab"


@pytest.fixture
def lab_dir() -> Path:
    if not (LAB / "poses.txt").is_file() or not (LAB / "tfs.txt").is_file():
        pytest.skip(f"the lab's real samples are not at {LAB.resolve()} (poses.txt, tfs.txt)")
    return LAB
