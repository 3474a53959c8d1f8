"""``sofia detector serve`` as a separate process, driven over Zenoh from the test."""

from __future__ import annotations

import queue
import time
from pathlib import Path

import numpy as np
import pytest
import zenoh
from sofia_replay.synth import DEFAULT_T_FLANGE_CAM
from sofia_replay.synth.realism import make_real_frame
from sofia_runtime import client
from sofia_schemas import Board, pointcloud
from sofia_schemas.keys import ENCODING_CDR_POINTCLOUD2, ENCODING_JSON, Keys
from sofia_schemas.messages import (
    CalibrationResult,
    Detection,
    ErrorReply,
    FlangePose,
    PickTarget,
    ServiceStatus,
)
from sofia_schemas.rosmsg import encode_flange_pose

from ..conftest import calibration_result

STAMP_NS = 1_700_000_123_000_000_000
BLOCK = zenoh.CongestionControl.BLOCK  # clouds of 4 MB: Zenoh must not drop them under load


def _collect(session: zenoh.Session, key: str) -> tuple[queue.Queue[bytes], object]:
    q: queue.Queue[bytes] = queue.Queue()
    sub = session.declare_subscriber(key, lambda s: q.put(s.payload.to_bytes()))
    return q, sub


def _wait_subscribed(session: zenoh.Session, keys: Keys) -> None:
    """Wait until the service answers its status query: its subscribers are declared by then."""
    replies = client.query(session, keys.status("detector"))
    assert replies and replies[0].ok is not None


def test_clouds_in_detections_out_with_pick_and_status(sofia_proc, robot_id: str, session, scenes) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    proc = sofia_proc("detector", "serve")
    proc.wait_for_log("detector ready")
    dets, _s1 = _collect(session, keys.detections)
    picks, _s2 = _collect(session, keys.pick_target)
    statuses, _s3 = _collect(session, keys.status("detector"))
    _wait_subscribed(session, keys)
    pub = session.declare_publisher(keys.points, congestion_control=BLOCK)
    s = scenes["two"]
    for i in range(3):
        cdr = pointcloud.encode_points(s.points_base, stamp_ns=STAMP_NS + i, frame_id="panda_link0")
        pub.put(bytes(cdr), encoding=ENCODING_CDR_POINTCLOUD2)
        det = Detection.model_validate_json(dets.get(timeout=15))
        assert det.stamp_ns == STAMP_NS + i and det.source == keys.points
        assert len(det.objects) == 2 and det.objects[0].allowed
        truth = {o.field: o.center for o in s.objects}
        for obj in det.objects:
            assert np.linalg.norm(np.array(obj.center) - truth[obj.field]) < 0.005
        pick = PickTarget.model_validate_json(picks.get(timeout=10))
        assert pick.stamp_ns == STAMP_NS + i and pick.object_center == det.objects[0].center
    status = ServiceStatus.model_validate_json(statuses.get(timeout=5))
    assert status.service == "detector" and status.counters["processed"] >= 1
    assert {"received", "dropped", "errors"} <= set(status.counters)
    assert proc.stop() == 0  # SIGTERM: a clean stop
    assert "detector stopping" in proc.log() and "Traceback" not in proc.log()


def test_no_pick_for_a_truncated_object(sofia_proc, robot_id: str, session, scenes) -> None:  # type: ignore[no-untyped-def]
    """A bottle cut by the image border on a red field is detected (truncated, confidence below
    0.5), but gets no pick target: its centre is that of its visible part. The status counts the
    withheld picks and the log says why; the next whole object is picked."""
    keys = Keys(robot_id)
    proc = sofia_proc("detector", "serve")
    proc.wait_for_log("detector ready")
    dets, _s1 = _collect(session, keys.detections)
    picks, _s2 = _collect(session, keys.pick_target)
    _wait_subscribed(session, keys)
    pub = session.declare_publisher(keys.points, congestion_control=BLOCK)
    cut = make_real_frame(Board.default(), "edge-cut", np.random.default_rng(2))
    cdr = pointcloud.encode_points(cut.points_base, stamp_ns=STAMP_NS, frame_id="panda_link0", rgb=cut.rgb)
    pub.put(bytes(cdr), encoding=ENCODING_CDR_POINTCLOUD2)
    det = Detection.model_validate_json(dets.get(timeout=15))
    assert len(det.objects) == 1 and det.objects[0].allowed and "image_edge" in det.objects[0].truncated
    assert det.objects[0].confidence < 0.5
    s = scenes["two"]
    cdr = pointcloud.encode_points(s.points_base, stamp_ns=STAMP_NS + 1, frame_id="panda_link0")
    pub.put(bytes(cdr), encoding=ENCODING_CDR_POINTCLOUD2)
    Detection.model_validate_json(dets.get(timeout=15))
    pick = PickTarget.model_validate_json(picks.get(timeout=10))
    assert pick.stamp_ns == STAMP_NS + 1  # the first pick is the whole object's: none for the cut one
    status = ServiceStatus.model_validate_json(
        client.query(session, keys.status("detector"))[0].ok.payload.to_bytes()
    )  # type: ignore[union-attr]
    assert status.counters["picks_withheld"] == 1 and status.counters["picks"] == 1
    assert proc.stop() == 0
    assert "no pick target for the cloud" in proc.log() and "below 0.50" in proc.log()


def test_detect_queryable(sofia_proc, robot_id: str, session, scenes) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    proc = sofia_proc("detector", "serve")
    proc.wait_for_log("detector ready")
    empty = client.query(session, keys.detect)  # no cloud yet: an error that says so
    assert empty and empty[0].err is not None
    assert "no cloud received yet" in ErrorReply.model_validate_json(empty[0].err.payload.to_bytes()).message
    s = scenes["sphere"]
    cdr = bytes(pointcloud.encode_points(s.points_base, stamp_ns=STAMP_NS, frame_id="panda_link0"))
    ok = client.query(session, keys.detect, cdr)
    det = Detection.model_validate_json(ok[0].ok.payload.to_bytes())
    assert (
        det.stamp_ns == STAMP_NS
        and np.linalg.norm(np.array(det.objects[0].center) - s.objects[0].center) < 0.005
    )
    for garbage, needle in [(b"\x00\x01\x00\x00\x01", "truncated"), (b"{not cdr}", "not a CDR PointCloud2")]:
        bad = client.query(session, keys.detect, garbage)
        assert bad[0].err is not None
        err = ErrorReply.model_validate_json(bad[0].err.payload.to_bytes())
        assert needle in err.message.lower() or needle in err.message, err
    again = client.query(session, keys.detect, cdr)  # still serving after the garbage
    assert Detection.model_validate_json(again[0].ok.payload.to_bytes()).stamp_ns == STAMP_NS
    # no payload: the detection of the latest cloud received on the bus (queried clouds are not)
    assert client.query(session, keys.detect)[0].err is not None
    pub = session.declare_publisher(keys.points, congestion_control=BLOCK)
    dets, _sub = _collect(session, keys.detections)
    _wait_subscribed(session, keys)
    pub.put(bytes(pointcloud.encode_points(s.points_base, stamp_ns=STAMP_NS + 5, frame_id="panda_link0")))
    assert Detection.model_validate_json(dets.get(timeout=15)).stamp_ns == STAMP_NS + 5
    after = Detection.model_validate_json(client.query(session, keys.detect)[0].ok.payload.to_bytes())
    assert after.stamp_ns == STAMP_NS + 5
    status = ServiceStatus.model_validate_json(
        client.query(session, keys.status("detector"))[0].ok.payload.to_bytes()
    )
    assert status.counters["query_errors"] == 4 and status.counters["queries"] == 7
    assert proc.popen.poll() is None


def test_camera_frame_cloud_with_flange_pose_and_transform_file(
    sofia_proc, robot_id: str, session, scenes, flange_cam_file: Path
) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    tf = flange_cam_file
    proc = sofia_proc("detector", "serve", "--transform", str(tf))
    proc.wait_for_log("detector ready")
    dets, _sub = _collect(session, keys.detections)
    _wait_subscribed(session, keys)
    f = scenes["box"].frame
    poses = session.declare_publisher(keys.flange_pose)
    # the arm moves: poses 20 ms before and after the cloud's stamp, the cloud's pose between them
    T_before, T_after = f.T_base_flange.copy(), f.T_base_flange.copy()
    T_before[0, 3] -= 0.01
    T_after[0, 3] += 0.01
    poses.put(encode_flange_pose(FlangePose.from_matrix(T_before, STAMP_NS - 20_000_000)))
    poses.put(FlangePose.from_matrix(T_after, STAMP_NS + 20_000_000).to_json_bytes(), encoding=ENCODING_JSON)
    time.sleep(0.3)
    cam = session.declare_publisher(keys.camera_points, congestion_control=BLOCK)
    cam.put(
        bytes(
            pointcloud.encode_points(
                f.render.points_cam, stamp_ns=STAMP_NS, frame_id="camera_color_optical_frame"
            )
        )
    )
    det = Detection.model_validate_json(dets.get(timeout=15))
    assert det.transform == f"file {tf}" and det.source == keys.camera_points
    assert np.linalg.norm(np.array(det.objects[0].center) - scenes["box"].objects[0].center) < 0.005
    # a camera cloud with no flange pose near its stamp is not detected, and the status says why
    cam.put(bytes(pointcloud.encode_points(f.render.points_cam, stamp_ns=STAMP_NS + 10**9, frame_id="cam")))
    time.sleep(1.0)
    status = ServiceStatus.model_validate_json(
        client.query(session, keys.status("detector"))[0].ok.payload.to_bytes()
    )
    assert status.counters["no_transform"] == 1 and "flange pose" in status.detail
    assert status.info["transform"] == f"file {tf}"
    assert proc.popen.poll() is None


@pytest.mark.parametrize("backlog", [1, 30])
def test_burst_keeps_only_the_latest_cloud(sofia_proc, robot_id: str, session, scenes, backlog: int) -> None:  # type: ignore[no-untyped-def]
    """Backlog 1 (the default): the newest cloud is processed, older ones are dropped and counted.
    A backlog longer than the burst loses nothing."""
    keys = Keys(robot_id)
    proc = sofia_proc("detector", "serve", "--backlog", str(backlog))
    proc.wait_for_log("detector ready")
    dets, _sub = _collect(session, keys.detections)
    _wait_subscribed(session, keys)
    # BLOCK: Zenoh itself must not drop any of the burst, so that the service sees all of them
    pub = session.declare_publisher(keys.points, congestion_control=BLOCK)
    cdr = bytearray(
        pointcloud.encode_points(scenes["box"].points_base, stamp_ns=STAMP_NS, frame_id="panda_link0")
    )
    n = 25
    for i in range(n):  # as fast as possible: faster than the detector
        cdr[4:8] = int((STAMP_NS + i) // 1_000_000_000).to_bytes(4, "little")
        cdr[8:12] = int((STAMP_NS + i) % 1_000_000_000).to_bytes(4, "little")
        pub.put(bytes(cdr), encoding=ENCODING_CDR_POINTCLOUD2)
    stamps = []
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and (not stamps or stamps[-1] != STAMP_NS + n - 1):
        try:
            stamps.append(Detection.model_validate_json(dets.get(timeout=1)).stamp_ns)
        except queue.Empty:
            pass
    assert stamps[-1] == STAMP_NS + n - 1  # the newest cloud is always processed
    assert stamps == sorted(stamps)  # never an older cloud after a newer one
    time.sleep(0.5)
    status = ServiceStatus.model_validate_json(
        client.query(session, keys.status("detector"))[0].ok.payload.to_bytes()
    )
    c = status.counters
    assert c["received"] == n and c["processed"] == len(stamps)
    assert c["processed"] + c["dropped"] == c["received"], c
    if c["dropped"]:  # dropped input: the status says so, with the reason and the count
        assert status.state == "degraded" and f"stale clouds: {c['dropped']} dropped" in status.detail, status
    else:
        assert status.state == "ok", status
    if backlog > n:
        assert c["dropped"] == 0 and stamps == [STAMP_NS + i for i in range(n)]


def test_transform_from_the_calibrator(sofia_proc, robot_id: str, session, scenes) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    proc = sofia_proc("detector", "serve")
    proc.wait_for_log("detector ready")
    dets, _sub = _collect(session, keys.detections)
    _wait_subscribed(session, keys)
    result = _calibration_result(time.time_ns())  # a live result older than the detector is refused
    session.put(keys.calibration_result, result.to_json_bytes(), encoding=ENCODING_JSON)
    proc.wait_for_log("using T_flange_cam from the calibrator")
    f = scenes["sphere"].frame
    session.put(keys.flange_pose, encode_flange_pose(FlangePose.from_matrix(f.T_base_flange, STAMP_NS)))
    time.sleep(0.3)
    session.put(
        keys.camera_points,
        bytes(pointcloud.encode_points(f.render.points_cam, stamp_ns=STAMP_NS, frame_id="cam")),
        congestion_control=zenoh.CongestionControl.BLOCK,  # 4.9 MB: never dropped
    )
    det = Detection.model_validate_json(dets.get(timeout=15))
    assert det.transform == f"calibrator result {result.stamp_ns}"
    assert np.linalg.norm(np.array(det.objects[0].center) - scenes["sphere"].objects[0].center) < 0.005


def test_a_result_published_before_the_detector_started_is_used(sofia_proc, robot_id: str, session) -> None:  # type: ignore[no-untyped-def]
    """The calibrator published its result before the detector started: the detector asks the
    result's queryable at start instead of waiting for the next result."""
    keys = Keys(robot_id)
    result = _calibration_result(77)
    payload = result.to_json_bytes()
    queryable = session.declare_queryable(
        keys.calibration_result, lambda q: q.reply(keys.calibration_result, payload, encoding=ENCODING_JSON)
    )
    try:
        proc = sofia_proc("detector", "serve")
        proc.wait_for_log("using T_flange_cam from the calibrator (result 77)", timeout=60)
    finally:
        queryable.undeclare()


def _calibration_result(stamp_ns: int) -> CalibrationResult:
    """A calibrator result holding the synthetic recordings' true T_flange_cam."""
    return calibration_result(DEFAULT_T_FLANGE_CAM, stamp_ns, target_base=(0.5, 0.0, 0.0))
