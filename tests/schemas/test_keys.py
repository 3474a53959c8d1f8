"""Key expressions and the MCAP topic map."""

from __future__ import annotations

import re

import pytest
from sofia_schemas import keys
from sofia_schemas.keys import Keys


def test_documented_keys() -> None:
    k = Keys("panda")
    assert k.points == "sofia/panda/points"
    assert k.camera_points == "sofia/panda/camera/points"
    assert k.flange_pose == "sofia/panda/flange/pose"
    assert k.detections == "sofia/panda/detector/detections"
    assert k.detect == "sofia/panda/detector/detect"
    assert k.blob == "sofia/panda/calibrator/blob"
    assert k.calibration_result == "sofia/panda/calibrator/result"
    assert k.calibrator_op("solve") == "sofia/panda/calibrator/solve"
    assert k.gripper_state == "sofia/panda/gripper/state"
    assert k.gripper_command == "sofia/panda/gripper/command"
    assert k.status("replay") == "sofia/panda/replay/status"
    assert k.all == "sofia/panda/**"


def test_default_robot() -> None:
    assert Keys().robot == keys.DEFAULT_ROBOT == "panda"


def test_robot_from_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(keys.ROBOT_ENV, "fr3_left")
    assert keys.default_robot() == "fr3_left"
    monkeypatch.delenv(keys.ROBOT_ENV)
    assert keys.default_robot() == "panda"


def test_every_key_is_namespaced_by_robot() -> None:
    k = Keys("r2")
    names = [n for n, v in vars(Keys).items() if isinstance(v, property) and n != "prefix"]
    assert len(names) >= 10
    for name in names:
        assert getattr(k, name).startswith("sofia/r2/"), name


@pytest.mark.parametrize("bad", ["", "a/b", "p*", "pan da", "$x", "panda\n"])
def test_invalid_robot_id(bad: str) -> None:
    with pytest.raises(ValueError, match=re.escape(f"robot id {bad!r} is not a valid key chunk")):
        Keys(bad)


def test_topic_map() -> None:
    k = Keys("p1")
    assert k.topic_map() == {
        keys.TOPIC_POINTS: "sofia/p1/points",
        keys.TOPIC_CAMERA_POINTS: "sofia/p1/camera/points",
        keys.TOPIC_CAMERA_INFO: "sofia/p1/camera/camera_info",
        keys.TOPIC_FLANGE_POSE: "sofia/p1/flange/pose",
        keys.TOPIC_BLOB: "sofia/p1/calibrator/blob",
    }
    assert keys.TOPIC_POINTS == "/pc_glob"
