"""ROS 2 data in: a camera driver's cloud (``/camera/camera/depth/color/points``, camera optical
frame) and a robot state publisher's ``/tf`` chain, published by the zenoh-ros2-sdk peer, reach the
detector through ``sofia ros2 serve``; the detections come out in the base frame, right."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation
from sofia_replay.synth import make_scene, render_scene
from sofia_schemas import Board, pointcloud

STAMP_NS = 1_700_000_500_000_000_000


def _edge(parent: str, child: str, T: np.ndarray) -> list[object]:
    q = Rotation.from_matrix(T[:3, :3]).as_quat()
    return [parent, child, STAMP_NS, T[:3, 3].tolist(), q.tolist()]


def test_camera_driver_and_tf_reach_the_detector(  # type: ignore[no-untyped-def]
    bus, peer, sofia_proc, robot_id: str, tmp_path: Path, flange_cam_file: Path
) -> None:
    rng = np.random.default_rng(5)
    scene = make_scene(Board.default(), "one", rng, shape="cylinder", fld=(2, 2))
    frame = render_scene(scene, rng)
    cloud_file = tmp_path / "camera.cdr"
    cloud_file.write_bytes(bytes(pointcloud.encode_points(
        frame.render.points_cam, stamp_ns=STAMP_NS, frame_id="camera_color_optical_frame")))  # fmt: skip
    # the flange pose as a robot state publisher sends it: a chain of joints, plus a child beyond
    T_base_l4 = np.eye(4)
    T_base_l4[:3, :3] = Rotation.from_euler("zyx", [0.4, -0.3, 0.2]).as_matrix()
    T_base_l4[:3, 3] = [0.1, -0.05, 0.45]
    T_l4_flange = np.linalg.inv(T_base_l4) @ frame.T_base_flange
    tf_file = tmp_path / "tf.json"
    tf_file.write_text(json.dumps([
        _edge("panda_link0", "panda_link4", T_base_l4), _edge("panda_link4", "panda_link8", T_l4_flange),
        _edge("panda_link8", "panda_hand", np.eye(4)),
    ]))  # fmt: skip
    transform = flange_cam_file

    detector = sofia_proc("detector", "serve", "--transform", str(transform), env=bus.env)
    bridge = sofia_proc("ros2", "serve", env=bus.env)
    detector.wait_for_log("detector ready")
    bridge.wait_for_log("ros2 ready")
    p = peer("--camera-cloud", str(cloud_file), "--tf", str(tf_file))
    p.next("ready", timeout=60)
    published = p.next("published", timeout=60)
    assert published == {"cloud_stamp_ns": STAMP_NS, "frame_id": "camera_color_optical_frame"}
    det = p.next("detections", timeout=30)
    assert det["stamp_ns"] == STAMP_NS and det["frame_id"] == "panda_link0"
    assert [d["class_id"] for d in det["items"]] == ["2,2/red"]
    error = np.linalg.norm(np.array(det["items"][0]["center"]) - scene.objects[0].center)
    assert error < 0.005, f"centre {error * 1000:.1f} mm from the truth"
    assert "Traceback" not in bridge.log() + detector.log()
