"""JSON messages carry a schema version; `sofia schemas export`; flange pose and blob CDR <-> JSON."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError
from rosbags.typesys import Stores, get_typestore
from sofia_schemas import ALL_MESSAGES, SCHEMA_VERSION, BlobObservation, FlangePose, PayloadError, rosmsg

from ..conftest import SOFIA


def test_schema_export_command(tmp_path: Path) -> None:
    out = subprocess.run(
        [SOFIA, "schemas", "export", str(tmp_path / "s")], capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stderr
    files = sorted(p.name for p in (tmp_path / "s").iterdir())
    assert files == sorted(f"{m.__name__}.schema.json" for m in ALL_MESSAGES)
    for model in ALL_MESSAGES:
        schema = json.loads((tmp_path / "s" / f"{model.__name__}.schema.json").read_text())
        assert schema["title"] == model.__name__
        version = schema["properties"]["schema_version"]
        assert version.get("const", version.get("default")) == SCHEMA_VERSION, model.__name__


def test_every_message_carries_schema_version() -> None:
    assert len(ALL_MESSAGES) >= 12
    for model in ALL_MESSAGES:
        assert "schema_version" in model.model_fields, model.__name__
        assert model.model_fields["schema_version"].default == SCHEMA_VERSION


def test_wrong_schema_version_rejected() -> None:
    data = {"schema_version": 2, "stamp_ns": 1, "position": [0, 0, 1]}
    with pytest.raises(ValidationError, match="schema_version"):
        BlobObservation.model_validate(data)
    assert (
        json.loads(BlobObservation(stamp_ns=1, position=(0, 0, 1)).model_dump_json())["schema_version"] == 1
    )


quats = st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: np.linalg.norm(q) > 0.1)
vec3 = st.tuples(*[st.floats(-5, 5, allow_subnormal=False)] * 3)
stamps = st.integers(0, 2**31 * 10**9 - 1)


@settings(max_examples=50, deadline=None)
@given(q=quats, t=vec3, stamp_ns=stamps)
def test_flange_pose_cdr_and_json(q: tuple[float, ...], t: tuple[float, float, float], stamp_ns: int) -> None:
    q_unit = tuple(float(v) for v in np.array(q) / np.linalg.norm(q))
    pose = FlangePose(stamp_ns=stamp_ns, translation=t, rotation_xyzw=q_unit)  # type: ignore[arg-type]

    cdr = rosmsg.encode_flange_pose(pose)
    assert rosmsg.decode_flange_pose(cdr) == pose
    assert rosmsg.decode_flange_pose(pose.to_json_bytes()) == pose
    # read independently by rosbags
    msg: Any = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(cdr, "geometry_msgs/msg/TransformStamped")
    assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == stamp_ns
    assert (msg.header.frame_id, msg.child_frame_id) == ("panda_link0", "panda_link8")
    tr, rot = msg.transform.translation, msg.transform.rotation
    assert (tr.x, tr.y, tr.z) == t and (rot.x, rot.y, rot.z, rot.w) == q_unit


@settings(max_examples=50, deadline=None)
@given(p=vec3, stamp_ns=stamps)
def test_blob_cdr_and_json(p: tuple[float, float, float], stamp_ns: int) -> None:
    obs = BlobObservation(stamp_ns=stamp_ns, position=p, frame_id="cam")
    cdr = rosmsg.encode_blob(obs)
    assert rosmsg.decode_blob(cdr) == obs
    assert rosmsg.decode_blob(obs.to_json_bytes()) == obs
    msg: Any = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(cdr, "geometry_msgs/msg/PointStamped")
    assert (msg.point.x, msg.point.y, msg.point.z, msg.header.frame_id) == (*p, "cam")


def test_bad_payloads() -> None:
    with pytest.raises(PayloadError, match="flange pose JSON is invalid"):
        rosmsg.decode_flange_pose(b'{"stamp_ns": 1}')
    with pytest.raises(PayloadError, match=r"flange pose payload \(5 bytes\) is neither JSON nor CDR"):
        rosmsg.decode_flange_pose(b"\x00\x01\x00\x00\x07")
    with pytest.raises(PayloadError, match=r"blob payload \(3 bytes\) is neither JSON nor CDR"):
        rosmsg.decode_blob(b"abc")
    with pytest.raises(PayloadError, match="norm"):
        rosmsg.decode_flange_pose(b'{"stamp_ns": 1, "translation": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 2]}')


def test_msgdef_for_mcap_schemas() -> None:
    text = rosmsg.msgdef(rosmsg.POINTCLOUD2)
    assert text.startswith("std_msgs/Header header")
    assert "MSG: sensor_msgs/PointField" in text


def test_arm_phase_lines_say_ok_skip_or_fail() -> None:
    from sofia_schemas.messages import ArmPhase

    assert ArmPhase(name="pose 3/20", status="done", reason="blob at").line() == "ok   pose 3/20: blob at"
    skipped = ArmPhase(name="visit 4", status="failed", reason="no blob: blob touches the image edge")
    assert skipped.line() == "skip visit 4: no blob: blob touches the image edge"  # the next view is tried
    assert ArmPhase(name="grasp", status="failed", reason="blocked").line() == "FAIL grasp: blocked"
