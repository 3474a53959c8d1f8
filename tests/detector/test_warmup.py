"""The detector service's warm-up: a real scene through the whole per-cloud path before the first cloud."""

from __future__ import annotations

import logging
import subprocess
import sys

import numpy as np
import pytest
from sofia_detector.detect import detect
from sofia_detector.pick import PickParams
from sofia_detector.warmup import WARM_BOX_M, warm_scene, warm_up
from sofia_schemas import Board
from sofia_schemas.messages import Detection


def test_warm_scene_is_a_box_the_detector_finds() -> None:
    """Not a token call: the scene has a board the detector fits and a blue box on the first red
    field, found where it stands, so the warm-up runs the paths a real object takes."""
    board = Board.default()
    points, rgb = warm_scene(board)
    det = detect(points, board, rgb=rgb)
    assert det.status == "ok" and len(det.objects) == 1, det
    obj = det.objects[0]
    row, col = board.allowed[0]
    assert obj.field == (row, col) and obj.allowed and obj.colour == "blue"
    truth = board.field_center_base(row, col)
    assert np.hypot(*(np.array(obj.center[:2]) - truth[:2])) < 0.003
    assert abs(obj.extents[2] - WARM_BOX_M[2]) < 0.002


def test_warm_up_imports_what_a_callback_would_import_holding_the_gil() -> None:
    """A flange pose's CDR types (rosbags) were imported by the first flange-pose callback, holding
    the GIL during the first detection; after the warm-up they are loaded."""
    code = (
        "import sys\n"
        "from sofia_schemas import Board\n"
        "from sofia_detector.pick import PickParams\n"
        "from sofia_detector.detect import detect\n"
        "from sofia_detector.warmup import warm_up\n"
        "from sofia_schemas import pointcloud\n"
        "lazy = ('rosbags.typesys',)\n"
        "print([m in sys.modules for m in lazy])\n"
        "b = Board.default()\n"
        "def detect_payload(payload, camera, key):\n"
        "    c = pointcloud.decode(payload)\n"
        "    return detect(c.xyz(), b, rgb=c.rgb(), source=key)\n"
        "took = warm_up(b, detect_payload, PickParams())\n"
        "print([m in sys.modules for m in lazy], took > 0)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    before, after = out.stdout.splitlines()
    assert before == "[False]", "imported before the warm-up: this test no longer shows anything"
    assert after == "[True] True"


def test_a_failing_warm_up_is_logged_not_raised(caplog: pytest.LogCaptureFixture) -> None:
    """The service starts even when the warm-up cannot run (here: its detection raises)."""

    def broken(payload: bytes, camera: bool, key: str) -> Detection:
        raise ValueError("no such thing")

    with caplog.at_level(logging.WARNING, logger="sofia_detector.warmup"):
        took = warm_up(Board.default(), broken, PickParams())
    assert took >= 0
    assert "warm-up failed (ValueError: no such thing)" in caplog.text
