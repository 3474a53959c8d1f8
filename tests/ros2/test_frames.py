"""``header.frame_id`` decides how the detector treats a cloud; the type in a Zenoh encoding is checked."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import zenoh
from sofia_replay.synth import make_scene, render_scene
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas import Board, pointcloud
from sofia_schemas.keys import ENCODING_CDR_POINTCLOUD2, Keys
from sofia_schemas.messages import Detection, ErrorReply, ServiceStatus
from sofia_schemas.ros2 import convert as cv
from sofia_schemas.ros2.typesupport import encode
from sofia_schemas.transforms import matrix_to_quat_xyzw

from ..conftest import first_reply

STAMP_NS = 1_700_000_900_000_000_000


def test_frames_decide_and_encodings_are_checked(sofia_proc, robot_id: str, flange_cam_file: Path) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    rng = np.random.default_rng(8)
    scene = make_scene(Board.default(), "one", rng, shape="sphere", fld=(0, 2))
    frame = render_scene(scene, rng)
    truth = np.array(scene.objects[0].center)
    transform = flange_cam_file
    proc = sofia_proc("detector", "serve", "--transform", str(transform))
    proc.wait_for_log("detector ready")
    with zenoh.open(zenoh_config()) as session:
        dets: list[Detection] = []
        _sub = session.declare_subscriber(
            keys.detections, lambda s: dets.append(Detection.model_validate_json(s.payload.to_bytes()))
        )
        first_reply(session, keys.status("detector"), b"", timeout=20.0)  # subscribed by now
        # the flange pose as a PoseStamped (converted: the type is read from the encoding)
        T = frame.T_base_flange
        pose = cv.new_pose_stamped(STAMP_NS, "panda_link0", T[:3, 3], matrix_to_quat_xyzw(T[:3, :3]))
        session.put(
            keys.flange_pose, encode(pose, cv.POSE_STAMPED), encoding="application/cdr;" + cv.POSE_STAMPED
        )
        time.sleep(0.3)
        cam_cdr = bytes(pointcloud.encode_points(frame.render.points_cam, stamp_ns=STAMP_NS,
                                                 frame_id="camera_color_optical_frame"))  # fmt: skip
        # a camera-frame cloud sent to the detect queryable is mapped by its frame
        reply = first_reply(session, keys.detect, cam_cdr, timeout=20.0)
        assert reply.ok is not None, reply.err.payload.to_bytes() if reply.err else None
        det = Detection.model_validate_json(reply.ok.payload.to_bytes())
        assert det.status == "ok" and np.linalg.norm(np.array(det.objects[0].center) - truth) < 0.005
        assert det.transform == f"file {transform}"
        # ... and so is one on the base-frame key
        session.put(keys.points, cam_cdr, encoding=ENCODING_CDR_POINTCLOUD2)
        deadline = time.monotonic() + 15
        while not dets and time.monotonic() < deadline:
            time.sleep(0.05)
        assert dets and np.linalg.norm(np.array(dets[0].objects[0].center) - truth) < 0.005
        # a cloud in an unknown frame is refused, naming the frame
        odd = bytes(pointcloud.encode_points(frame.points_base, stamp_ns=STAMP_NS, frame_id="mystery_link"))
        reply = first_reply(session, keys.detect, odd, timeout=20.0)
        assert reply.err is not None
        err = ErrorReply.model_validate_json(reply.err.payload.to_bytes())
        assert err.error == "UnknownFrame" and "'mystery_link'" in err.message
        # a flange payload whose encoding names another type is refused, naming the type
        session.put(keys.flange_pose, b"\x00\x01\x00\x00" + bytes(40),
                    encoding="application/cdr;geometry_msgs/msg/PointStamped")  # fmt: skip
        time.sleep(0.5)
        status = ServiceStatus.model_validate_json(
            first_reply(session, keys.status("detector"), b"", timeout=20.0).ok.payload.to_bytes()
        )
        assert "geometry_msgs/msg/PointStamped" in status.detail
    assert proc.popen.poll() is None
