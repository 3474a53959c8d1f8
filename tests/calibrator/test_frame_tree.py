"""One name per frame: ``sofia calibrate``'s ROS 1 / ROS 2 lines, the bridge's /tf_static and the
robot's flange pose form one TF tree that reaches every cloud's ``frame_id`` from ``panda_link0``."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import numpy as np
from sofia_camera.cloud import FRAME_ID as CAMERA_CLOUD_FRAME
from sofia_detector.service import ServiceConfig as DetectorConfig
from sofia_replay.synth.record import CAMERA_FRAME as RECORDED_CAMERA_FRAME
from sofia_runtime.ros2.bridge import BridgeConfig
from sofia_schemas import Board, CalibrationResult, FlangePose
from sofia_schemas.frames import BASE_FRAME, CAMERA_FRAME, FLANGE_FRAME, R_LINK_OPTICAL
from sofia_schemas.messages import BlobObservation
from sofia_schemas.ros2 import convert as cv
from sofia_schemas.transforms import make_transform, matrix_to_quat_xyzw
from sofia_viz.service import ServiceConfig as VizConfig

from ..conftest import SOFIA

Edge = tuple[str, str, np.ndarray]  # parent, child, (4, 4) T_parent_child


def _T(t: list[float], q_xyzw: list[float]) -> np.ndarray:
    return make_transform(np.array(t), np.array(q_xyzw))


def ros1_edge(line: str) -> Edge:
    """``<node ... args="x y z qx qy qz qw parent child period" />`` as an edge."""
    args = re.search(r'args="([^"]+)"', line)
    assert args, line
    words = args.group(1).split()
    v = [float(w) for w in words[:7]]
    return words[7], words[8], _T(v[:3], v[3:7])


def ros2_edge(line: str) -> Edge:
    """``ros2 run tf2_ros static_transform_publisher --x .. --frame-id P --child-frame-id C``."""
    opts = dict(re.findall(r"--([a-z-]+) (\S+)", line))
    v = [float(opts[k]) for k in ("x", "y", "z", "qx", "qy", "qz", "qw")]
    return opts["frame-id"], opts["child-frame-id"], _T(v[:3], v[3:])


def tf_edge(msg: object) -> Edge:
    """A ``geometry_msgs/msg/TransformStamped`` as an edge."""
    tr = msg.transform  # type: ignore[attr-defined]
    t, q = tr.translation, tr.rotation
    return msg.header.frame_id, msg.child_frame_id, _T([t.x, t.y, t.z], [q.x, q.y, q.z, q.w])  # type: ignore[attr-defined]


def walk(edges: list[Edge], root: str, target: str) -> np.ndarray:
    """T_root_target along the tree's edges (each child has one parent); fails naming the frame
    that has no parent."""
    parent_of = {child: (parent, T) for parent, child, T in edges}
    assert len(parent_of) == len(edges), f"a frame has two parents: {[(p, c) for p, c, _ in edges]}"
    T, frame = np.eye(4), target
    while frame != root:
        assert frame in parent_of, f"{frame!r} has no TF parent on the way to {root!r}"
        parent, T_parent_frame = parent_of[frame]
        T, frame = T_parent_frame @ T, parent
    return T


def test_calibration_lines_and_tf_static_reach_every_cloud_frame(lab_dir: Path) -> None:
    r = subprocess.run([SOFIA, "calibrate", "--poses", str(lab_dir / "poses.txt"), "--tfs", str(lab_dir / "tfs.txt"),
                        "--json"], capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 0, r.stderr
    result = CalibrationResult.model_validate(json.loads(r.stdout))
    T_flange_cam = np.array(result.matrix)
    assert (result.parent_frame, result.child_frame) == (FLANGE_FRAME, CAMERA_FRAME)
    # the same edge from the ROS 1 line, the ROS 2 line and the bridge's /tf_static
    static_tf = cv.calibration_transform(result, BridgeConfig(robot="panda").camera_frame)
    for parent, child, T in (ros1_edge(result.ros1_static_transform), ros2_edge(result.ros2_static_transform),
                             tf_edge(static_tf)):  # fmt: skip
        assert (parent, child) == (FLANGE_FRAME, CAMERA_FRAME)
        np.testing.assert_allclose(T, T_flange_cam, atol=2e-6)
    # the robot's flange pose (the arm's and the bridge's /tf edge)
    q_base_flange = tuple(float(v) for v in matrix_to_quat_xyzw(np.diag([1.0, -1.0, -1.0])))
    T_base_flange = _T([0.4, 0.1, 0.5], list(q_base_flange))
    pose = FlangePose(stamp_ns=1, translation=(0.4, 0.1, 0.5), rotation_xyzw=q_base_flange)  # type: ignore[arg-type]
    edges = [tf_edge(cv.flange_transform(pose)), ros2_edge(result.ros2_static_transform)]
    # every frame a cloud is published or taken in
    cloud_frames = {
        "camera service": CAMERA_CLOUD_FRAME,
        "synthetic recordings": RECORDED_CAMERA_FRAME,
        "detector (camera clouds)": DetectorConfig(
            board=Board.default(), robot="panda", zenoh=None
        ).camera_frames[0],  # type: ignore[arg-type]
        "viz": VizConfig(robot="panda", zenoh=None, board=Board.default()).camera_frame,  # type: ignore[arg-type]
        "ROS 2 bridge": BridgeConfig(robot="panda").camera_frame,
        "blob observations": BlobObservation(stamp_ns=1, position=(0.0, 0.0, 0.5)).frame_id,
        "board (base-frame clouds)": Board.default().frame_id,
    }
    for who, frame in cloud_frames.items():
        T = walk(edges, BASE_FRAME, frame)
        want = T_base_flange @ T_flange_cam if frame == CAMERA_FRAME else np.eye(4)
        np.testing.assert_allclose(T, want, atol=2e-6, err_msg=who)


def test_optical_rotation_is_realsense_ros_camera_link_to_optical() -> None:
    """realsense-ros: camera_link -> camera_color_optical_frame is rpy (-pi/2, 0, -pi/2)."""
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xyz", [-np.pi / 2, 0.0, -np.pi / 2]).as_matrix()
    np.testing.assert_allclose(R_LINK_OPTICAL, R, atol=1e-12)
    np.testing.assert_allclose(
        R_LINK_OPTICAL @ [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]
    )  # optical z = body x (forward)
    np.testing.assert_allclose(matrix_to_quat_xyzw(R_LINK_OPTICAL), [-0.5, 0.5, -0.5, 0.5], atol=1e-12)
