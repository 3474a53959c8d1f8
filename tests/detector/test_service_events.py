"""``sofia detector serve`` (a separate process): the worker wakes on each arrival, queries are served
while a camera cloud waits for its flange pose, and dropped input makes the status ``degraded`` (stale
clouds: ``test_service.test_burst_keeps_only_the_latest_cloud``)."""

from __future__ import annotations

import os
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import zenoh
from sofia_runtime import client
from sofia_schemas import pointcloud
from sofia_schemas.keys import ENCODING_CDR_POINTCLOUD2, Keys
from sofia_schemas.messages import Detection, FlangePose, ServiceStatus
from sofia_schemas.rosmsg import encode_flange_pose

from ..conftest import SOFIA
from .test_service import BLOCK, STAMP_NS, _collect, _wait_subscribed

POSE_WAIT_S = 20.0  # long enough that a worker blocked by the waiting cloud could not hide it


def _status(session, keys: Keys) -> ServiceStatus:  # type: ignore[no-untyped-def]
    return ServiceStatus.model_validate_json(
        client.query(session, keys.status("detector"))[0].ok.payload.to_bytes()
    )


def test_queries_are_served_while_a_camera_cloud_waits_for_its_pose(
    sofia_proc, robot_id: str, session, scenes, flange_cam_file: Path
) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    tf = flange_cam_file
    proc = sofia_proc("detector", "serve", "--transform", str(tf), "--pose-wait", str(POSE_WAIT_S))
    proc.wait_for_log("detector ready")
    dets, _sub = _collect(session, keys.detections)
    _wait_subscribed(session, keys)
    f = scenes["box"].frame
    poses = session.declare_publisher(keys.flange_pose)
    poses.put(encode_flange_pose(FlangePose.from_matrix(f.T_base_flange, STAMP_NS - 20_000_000)))
    cam = session.declare_publisher(keys.camera_points, congestion_control=BLOCK)
    cdr = pointcloud.encode_points(
        f.render.points_cam, stamp_ns=STAMP_NS, frame_id="camera_color_optical_frame"
    )
    cam.put(bytes(cdr), encoding=ENCODING_CDR_POINTCLOUD2)  # its pose (at or after its stamp) not yet sent
    deadline = time.monotonic() + 15
    while _status(session, keys).counters["received"] < 1 and time.monotonic() < deadline:
        time.sleep(0.1)
    # the cloud waits for its pose: a query with a cloud is answered meanwhile, status queries too
    base = pointcloud.encode_points(
        scenes["sphere"].points_base, stamp_ns=STAMP_NS + 7, frame_id="panda_link0"
    )
    t0 = time.monotonic()
    reply = client.query(session, keys.detect, bytes(base))
    waited_s = time.monotonic() - t0
    assert reply[0].ok is not None and Detection.model_validate_json(
        reply[0].ok.payload.to_bytes()
    ).stamp_ns == (STAMP_NS + 7)
    assert waited_s < POSE_WAIT_S / 2, waited_s  # not held up by the waiting camera cloud
    status = _status(session, keys)
    assert status.counters["received"] == 1 and status.counters["processed"] == 0, status.counters
    assert dets.empty()  # the camera cloud is still waiting
    # its pose arrives: the worker wakes at once and maps the cloud with it
    poses.put(encode_flange_pose(FlangePose.from_matrix(f.T_base_flange, STAMP_NS + 20_000_000)))
    det = Detection.model_validate_json(dets.get(timeout=POSE_WAIT_S / 2))
    assert det.stamp_ns == STAMP_NS and det.source == keys.camera_points
    assert np.linalg.norm(np.array(det.objects[0].center) - scenes["box"].objects[0].center) < 0.005
    assert _status(session, keys).state == "ok"
    assert proc.stop() == 0


def _feed(pub: zenoh.Publisher, payload: bytes, stop: threading.Event) -> None:
    """Put ``payload`` every 0.5 s until ``stop`` is set."""
    while not stop.wait(0.5):
        pub.put(payload, encoding=ENCODING_CDR_POINTCLOUD2)


def test_camera_clouds_without_calibration_make_the_status_degraded(
    sofia_proc, robot_id: str, session, scenes
) -> None:  # type: ignore[no-untyped-def]
    """No --transform and no calibrator: camera-frame clouds are dropped, the status says so
    (``degraded``, the reason, the count) and ``sofia health detector`` shows it."""
    keys = Keys(robot_id)
    proc = sofia_proc("detector", "serve")
    proc.wait_for_log("detector ready")
    dets, _sub = _collect(session, keys.detections)
    _wait_subscribed(session, keys)
    assert _status(session, keys).state == "ok"
    cam = session.declare_publisher(keys.camera_points, congestion_control=BLOCK)
    f = scenes["box"].frame
    cdr = pointcloud.encode_points(
        f.render.points_cam, stamp_ns=STAMP_NS, frame_id="camera_color_optical_frame"
    )
    cam.put(bytes(cdr), encoding=ENCODING_CDR_POINTCLOUD2)
    deadline = time.monotonic() + 15
    while (status := _status(session, keys)).counters["no_transform"] < 1 and time.monotonic() < deadline:
        time.sleep(0.1)
    assert status.state == "degraded" and status.counters["no_transform"] == 1, status.model_dump_json()
    assert "camera-frame clouds not mapped to the base frame: 1 dropped" in status.detail
    assert "--transform FILE or run the calibrator" in status.detail
    env = dict(os.environ, SOFIA_ROBOT=robot_id)
    # the status stays degraded for DEGRADED_WINDOW_S after a drop; a loaded machine can take longer
    # than that to start `sofia health`, so the camera keeps sending unmappable clouds meanwhile
    stop = threading.Event()
    feeder = threading.Thread(target=_feed, args=(cam, bytes(cdr), stop), daemon=True)
    feeder.start()
    try:
        health = subprocess.run(
            [SOFIA, "health", "detector"], env=env, capture_output=True, text=True, timeout=60
        )
    finally:
        stop.set()
        feeder.join()
    assert "detector: degraded" in health.stdout and "not mapped to the base frame" in health.stdout, health
    assert health.returncode == 3  # degraded: serving, not healthy (0 with --degraded-ok)
    relaxed = subprocess.run([SOFIA, "health", "detector", "--degraded-ok"], env=env, capture_output=True,
                             text=True, timeout=60)  # fmt: skip
    assert relaxed.returncode == 0, relaxed
    # base-frame clouds are still detected
    pub = session.declare_publisher(keys.points, congestion_control=BLOCK)
    pub.put(
        bytes(
            pointcloud.encode_points(
                scenes["sphere"].points_base, stamp_ns=STAMP_NS + 9, frame_id="panda_link0"
            )
        )
    )
    assert Detection.model_validate_json(dets.get(timeout=15)).stamp_ns == STAMP_NS + 9
    assert proc.popen.poll() is None
