"""What `sofia demo` prints reads as sentences (no raw stamps, no `None`), and the launcher's info
lines go to its log file, not to the terminal."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest
from sofia_schemas.messages import DetectedObject, Detection
from sofia_system.demo import launcher_log
from sofia_system.summary import Summary
from sofia_system.wording import MISSED_MM, describe_detection, transform_text

RED = DetectedObject(field=(2, 2), allowed=True, center=(0.701, 0.042, 0.025), centroid=(0.7, 0.04, 0.02),
                     extents=(0.04, 0.04, 0.05), yaw=0.0, n_points=500, confidence=0.9)  # fmt: skip


def detection(*objects: DetectedObject) -> Detection:
    return Detection(
        stamp_ns=1, frame_id="panda_link0", status="ok" if objects else "no_object", objects=list(objects)
    )


def test_a_detection_is_said_against_the_truth() -> None:
    text, err = describe_detection(detection(RED), [{"center": [0.7011, 0.042, 0.025]}])
    assert text == "1 object on red field (2, 2), centre (0.701, 0.042, 0.025) m, 0.1 mm from the true centre"
    assert err == pytest.approx(0.1)
    other = RED.model_copy(update={"allowed": False, "field": (2, 1)})
    text, _ = describe_detection(detection(other, RED), [{"center": [0.701, 0.042, 0.025]}])
    assert text.startswith("2 objects, the first on non-red (not to pick) field (2, 1), centre")


def test_an_empty_board_a_miss_and_no_truth() -> None:
    assert describe_detection(detection(), []) == ("no object on the board (right: the board is empty)", None)
    assert describe_detection(detection(), [{"center": [0.5, 0, 0]}]) == (
        "MISSED: no object found, 1 on the board", MISSED_MM,
    )  # fmt: skip
    assert describe_detection(detection(RED), [])[0].endswith("(WRONG: the board is empty)")
    assert describe_detection(detection(RED), None) == ("no ground truth for this stamp", None)


def test_the_transform_is_named_by_its_time() -> None:
    assert (
        transform_text("calibrator result 1795397011438923260") == "the calibrator's result of 01:23:31 UTC"
    )
    assert transform_text("file T_flange_cam.yaml") == "file T_flange_cam.yaml"


def test_launcher_info_goes_to_the_file_warnings_also_to_the_terminal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = logging.getLogger("sofia.up")
    level = log.level
    log.setLevel(logging.INFO)
    try:
        with launcher_log(tmp_path / "logs" / "launcher.log"):
            log.info("started detector pid 1")
            log.warning("detector exited with 1")
    finally:
        log.setLevel(level)
    err = capsys.readouterr().err
    assert "started detector" not in err and "detector exited with 1" in err
    written = (tmp_path / "logs" / "launcher.log").read_text()
    assert "started detector pid 1" in written and "detector exited with 1" in written
    assert log.propagate and not log.handlers  # put back as it was


def test_the_summary_for_machines() -> None:
    s = Summary()
    s.add("pick targets", "8 published", True)
    assert s.as_list() == [{"step": "pick targets", "result": "8 published", "ok": True}]
