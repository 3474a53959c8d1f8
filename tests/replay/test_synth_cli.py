"""`sofia synth` writes recordings the replay tools read, with ground truth in the metadata."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sofia_replay import mcap_io
from sofia_schemas import Board
from sofia_schemas.keys import TOPIC_BLOB, TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE, TOPIC_POINTS

pytest.importorskip("open3d")


def test_synth_scenes(tmp_path: Path, sofia_proc: Callable[..., Any]) -> None:
    board_file = tmp_path / "board.yaml"
    board_file.write_text(Board(yaw=0.2, center=(0.55, 0.05)).to_yaml())
    out = tmp_path / "sub" / "scenes.mcap"
    proc = sofia_proc(
        "synth", "scenes", str(out), "-n", "2", "--kind", "one", "--rate", "5", "--board", str(board_file)
    )
    assert proc.popen.wait(120) == 0, proc.log()
    s = mcap_io.summary(out)
    assert {t: v.count for t, v in s.topics.items()} == {
        TOPIC_POINTS: 2,
        TOPIC_CAMERA_POINTS: 2,
        TOPIC_FLANGE_POSE: 2,
        "/tf": 2,  # base -> flange, for Foxglove's TF tree
        "/tf_static": 1,  # flange -> camera optical frame
    }
    assert s.duration_s == pytest.approx(0.2)
    truth = mcap_io.read_truth(out)
    assert truth is not None and len(truth["frames"]) == 2
    assert truth["board"]["yaw"] == 0.2 and truth["board"]["center"] == [0.55, 0.05]
    _, _, cloud = next(mcap_io.iter_clouds(out, [TOPIC_POINTS]))
    assert cloud.shape == (480, 640) and cloud.frame_id == "panda_link0"
    assert np.isfinite(cloud.xyz()).all(axis=-1).mean() > 0.5


def test_synth_calibration_without_clouds(tmp_path: Path, sofia_proc: Callable[..., Any]) -> None:
    out = tmp_path / "cal.mcap"
    proc = sofia_proc("synth", "calibration", str(out), "--poses", "3", "--seed", "4", "--no-clouds")
    assert proc.popen.wait(120) == 0, proc.log()
    topics = mcap_io.summary(out).topics
    assert TOPIC_CAMERA_POINTS not in topics and topics[TOPIC_BLOB].count == 3
    assert len(list(mcap_io.iter_blobs(out))) == 3
    assert mcap_io.read_truth(out) is not None


def test_synth_bad_kind(sofia_proc: Callable[..., Any], tmp_path: Path) -> None:
    proc = sofia_proc("synth", "scenes", str(tmp_path / "x.mcap"), "--kind", "pyramid")
    assert proc.popen.wait(60) == 2
    assert "invalid choice: 'pyramid'" in proc.log()
