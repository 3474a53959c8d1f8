"""Write synthetic scenes and calibration sessions to MCAP, with their ground truth.

Board scenes: per frame a base-frame cloud on ``/pc_glob`` (like the lab's recording), a
camera-frame cloud on ``/camera/depth/color/points`` and the flange pose, all with the frame's
stamp. Calibration sessions: per pose the camera-frame cloud, a measured blob position on
``/sofia/blob``, and flange poses (still around each frame, moving in between).
Truth is JSON in the metadata record ``sofia.truth`` (see :func:`sofia_replay.read_truth`).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Literal

import numpy as np
from sofia_schemas import Board, pointcloud
from sofia_schemas.frames import BASE_FRAME, CAMERA_FRAME
from sofia_schemas.keys import TOPIC_BLOB, TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE, TOPIC_POINTS
from sofia_schemas.messages import BlobObservation, FlangePose
from sofia_schemas.transforms import interpolate_poses

from ..mcap_io import McapWriter
from .calibration import CalibrationSession, make_calibration_session
from .camera import Camera
from .scene import DEFAULT_T_FLANGE_CAM, SceneKind, make_scene, render_scene

log = logging.getLogger(__name__)

START_NS = 1_700_000_000_000_000_000  # board scenes
CALIBRATION_START_NS = START_NS - 3_600_000_000_000  # calibration sessions: an hour earlier

TOPIC_TF, TOPIC_TF_STATIC = "/tf", "/tf_static"
SCENE_KINDS = ("one", "empty", "nonred", "two", "mixed")
MIXED_CYCLE: tuple[SceneKind, ...] = ("one", "one", "two", "nonred", "one", "empty")
Frames = Literal["base", "camera", "both"]


def _flange(T: np.ndarray, stamp_ns: int, frame_id: str) -> FlangePose:
    return FlangePose.from_matrix(T, stamp_ns=stamp_ns, frame_id=frame_id)


def write_tf(w: McapWriter, pose: FlangePose, T_flange_cam: np.ndarray | None = None) -> None:
    """``/tf`` (base -> flange) at the pose's stamp, and ``/tf_static`` (flange -> camera optical
    frame) when ``T_flange_cam`` is given, so that Foxglove places camera clouds in the base frame."""
    from sofia_schemas.ros2 import convert as cv
    from sofia_schemas.ros2.typesupport import encode
    from sofia_schemas.transforms import matrix_to_quat_xyzw

    tf = cv.tf_message([cv.flange_transform(pose)])
    w.write_raw(TOPIC_TF, cv.TF_MESSAGE, encode(tf, cv.TF_MESSAGE), pose.stamp_ns)
    if T_flange_cam is not None:
        static = cv.transform_stamped(pose.stamp_ns, pose.child_frame_id, CAMERA_FRAME, T_flange_cam[:3, 3],
                                      matrix_to_quat_xyzw(T_flange_cam[:3, :3]))  # fmt: skip
        cdr = encode(cv.tf_message([static]), cv.TF_MESSAGE)
        w.write_raw(TOPIC_TF_STATIC, cv.TF_MESSAGE, cdr, pose.stamp_ns)


def write_scene_set(
    path: Path,
    kind: str = "mixed",
    n: int = 10,
    seed: int = 0,
    rate_hz: float = 10.0,
    board: Board | None = None,
    frames: Frames = "both",
    camera: Camera | None = None,
) -> dict[str, object]:
    """Render ``n`` board scenes of ``kind`` (``one``, ``empty``, ``nonred``, ``two`` or ``mixed``)
    and write them to ``path``. Returns the ground truth written into the file."""
    if kind not in SCENE_KINDS:
        raise ValueError(f"scene kind {kind!r} is not one of {SCENE_KINDS}")
    if n < 1 or rate_hz <= 0:
        raise ValueError(f"need n >= 1 and rate_hz > 0, got n={n}, rate_hz={rate_hz}")
    board = board or Board.default()
    rng = np.random.default_rng(seed)
    period_ns = int(1e9 / rate_hz)
    truth_frames = []
    with McapWriter(path) as w:
        for i in range(n):
            k: SceneKind = MIXED_CYCLE[i % len(MIXED_CYCLE)] if kind == "mixed" else kind  # type: ignore[assignment]
            stamp_ns = START_NS + i * period_ns
            f = render_scene(make_scene(board, k, rng), rng, camera)
            pose = _flange(f.T_base_flange, stamp_ns, board.frame_id)
            w.write_flange_pose(TOPIC_FLANGE_POSE, pose)
            write_tf(w, pose, DEFAULT_T_FLANGE_CAM if i == 0 else None)
            if frames in ("base", "both"):
                cdr = pointcloud.encode_points(
                    f.points_base, stamp_ns=stamp_ns, frame_id=board.frame_id, rgb=f.render.rgb
                )
                w.write_cloud(TOPIC_POINTS, cdr, stamp_ns)
            if frames in ("camera", "both"):
                cdr = pointcloud.encode_points(
                    f.render.points_cam, stamp_ns=stamp_ns, frame_id=CAMERA_FRAME, rgb=f.render.rgb
                )
                w.write_cloud(TOPIC_CAMERA_POINTS, cdr, stamp_ns)
            truth_frames.append(
                {
                    "stamp_ns": stamp_ns,
                    "kind": k,
                    "T_base_board": f.scene.T_base_board.tolist(),
                    "T_base_flange": f.T_base_flange.tolist(),
                    "objects": [o.to_json() for o in f.scene.objects],
                }
            )
            log.info("scene %d/%d (%s): %d objects", i + 1, n, k, len(f.scene.objects))
        truth: dict[str, object] = {
            "type": "scenes",
            "kind": kind,
            "seed": seed,
            "board": board.model_dump(mode="json"),
            "T_flange_cam": DEFAULT_T_FLANGE_CAM.tolist(),
            "frames": truth_frames,
        }
        w.add_truth(truth)
    return truth


def blob_measurement(p_cam_true: np.ndarray, rng: np.random.Generator, camera: Camera) -> np.ndarray:
    """A measured blob position: truth plus D435-like noise (depth sigma(z), 0.3 mm laterally)."""
    sigma = np.array([3e-4, 3e-4, float(camera.depth_sigma(p_cam_true[2]))])
    return p_cam_true + rng.normal(0.0, 1.0, 3) * sigma


def _motion(T_a: np.ndarray, T_b: np.ndarray, n: int) -> np.ndarray:
    """(n, 4, 4) poses strictly between ``T_a`` and ``T_b`` (linear translation, slerp rotation)."""
    return np.asarray(interpolate_poses(T_a, T_b, np.linspace(0, 1, n + 2)[1:-1]))


def write_calibration_session(
    path: Path,
    n_poses: int = 12,
    seed: int = 0,
    T_flange_cam: np.ndarray | None = None,
    clouds: bool = True,
    frame_id: str = BASE_FRAME,
) -> CalibrationSession:
    """Render a calibration session and write it to ``path``; returns the session (with truth)."""
    rng = np.random.default_rng(seed)
    camera = Camera()
    session = make_calibration_session(
        n_poses, rng, T_flange_cam, camera=camera, start_ns=CALIBRATION_START_NS
    )
    period = session.frames[1].stamp_ns - session.frames[0].stamp_ns if n_poses > 1 else 2_000_000_000
    still_ns = 200_000_000  # the arm rests 0.2 s before and after each capture
    with McapWriter(path) as w:
        for i, f in enumerate(session.frames):
            for dt in (-still_ns, 0, still_ns):
                w.write_flange_pose(TOPIC_FLANGE_POSE, _flange(f.T_base_flange, f.stamp_ns + dt, frame_id))
            if clouds:
                cdr = pointcloud.encode_points(
                    f.points_cam, stamp_ns=f.stamp_ns, frame_id=CAMERA_FRAME, rgb=f.rgb
                )
                w.write_cloud(TOPIC_CAMERA_POINTS, cdr, f.stamp_ns)
            p = blob_measurement(f.p_cam_true, rng, camera)
            w.write_blob(
                TOPIC_BLOB,
                BlobObservation(
                    stamp_ns=f.stamp_ns, frame_id=CAMERA_FRAME, position=tuple(map(float, p)), n_pixels=0
                ),
            )  # type: ignore[arg-type]
            if i + 1 < len(session.frames):
                nxt = session.frames[i + 1]
                moving = _motion(f.T_base_flange, nxt.T_base_flange, 8)
                t0, t1 = f.stamp_ns + still_ns, nxt.stamp_ns - still_ns
                for j, T in enumerate(moving):
                    t = t0 + (j + 1) * (t1 - t0) // (len(moving) + 1)
                    w.write_flange_pose(TOPIC_FLANGE_POSE, _flange(T, t, frame_id))
        w.add_truth(
            {
                "type": "calibration",
                "seed": seed,
                "T_flange_cam": session.T_flange_cam.tolist(),
                "p_base_blob": session.p_base_blob.tolist(),
                "blob_radius": session.blob_radius,
                "period_ns": period,
                "frames": [
                    {
                        "stamp_ns": f.stamp_ns,
                        "p_cam_true": f.p_cam_true.tolist(),
                        "T_base_flange": f.T_base_flange.tolist(),
                    }
                    for f in session.frames
                ],
            }
        )
    return session
