"""Shared fixtures of the calibrator tests: the lab's real samples, shipped in ``data/lab``."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
LAB = REPO / "data" / "lab"


@pytest.fixture
def lab_dir() -> Path:
    assert (LAB / "poses.txt").is_file() and (LAB / "tfs.txt").is_file(), f"missing lab samples in {LAB}"
    return LAB
