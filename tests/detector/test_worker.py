"""The detector's work queue (one wait that wakes on a query, a cloud or a pose; no polling) and the
copies on a cloud's path (buffer identity and tracemalloc peaks)."""

from __future__ import annotations

import threading
import time
import tracemalloc

import numpy as np
import pytest
from sofia_detector.frames import points_to_base
from sofia_detector.service import Detector, ServiceConfig
from sofia_detector.worker import STALE, CloudJob, DropLog, WorkQueue
from sofia_replay.synth import DEFAULT_T_FLANGE_CAM
from sofia_runtime.zenoh_config import ZenohOptions
from sofia_schemas import pointcloud
from sofia_schemas.messages.calibration import CameraCorrection
from sofia_schemas.transforms import apply

STAMP_NS = 1_700_000_000_000_000_000


def _job(camera: bool = False) -> CloudJob:
    return CloudJob(b"", camera, "k")


def test_one_wait_wakes_on_a_query_while_a_cloud_waits_then_on_the_pose() -> None:
    work: WorkQueue[str] = WorkQueue(backlog=2)
    pose_arrived = threading.Event()
    calls = []

    def pose_wait(job: CloudJob) -> float:  # the cloud waits up to 60 s for its pose
        calls.append(time.monotonic())
        return 0.0 if pose_arrived.is_set() else 60.0

    got: list[object] = []
    worker = threading.Thread(target=lambda: [got.append(work.get(pose_wait)) for _ in range(3)])
    cloud = _job(camera=True)
    work.put_cloud(cloud)
    worker.start()
    time.sleep(0.5)
    assert got == [] and len(calls) == 1  # asleep in one wait: no polling while nothing happens
    work.put_query("query")
    deadline = time.monotonic() + 10
    while len(got) < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert got == ["query"]  # served while the cloud waits
    pose_arrived.set()
    work.poke()  # a pose: the waiting cloud is looked at again and taken
    deadline = time.monotonic() + 10
    while len(got) < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert got[1] is cloud and len(work) == 0
    work.close()
    worker.join(10)
    assert got[2] is None and not worker.is_alive()


def test_a_full_queue_drops_the_oldest_cloud_and_says_so() -> None:
    drops = DropLog()
    work: WorkQueue[str] = WorkQueue(backlog=2, drops=drops)
    jobs = [_job() for _ in range(5)]
    dropped = [work.put_cloud(j) for j in jobs]
    assert dropped == [None, None, jobs[0], jobs[1], jobs[2]]
    assert work.received == 5 and drops.counts[STALE] == 3 and len(work) == 2
    assert work.get(lambda j: 0.0) is jobs[3] and work.take_cloud(lambda j: 0.0) is jobs[4]
    state, detail = drops.state()
    assert state == "degraded" and detail.startswith("stale clouds: 3 dropped (last: a newer cloud arrived")
    assert DropLog(window_s=0.0).state() == ("ok", "")
    with pytest.raises(ValueError, match="backlog must be at least 1"):
        WorkQueue(backlog=0)


def test_queries_beyond_the_bound_are_refused_and_counted_not_queued() -> None:
    work: WorkQueue[str] = WorkQueue(max_queries=2)
    assert [work.put_query(q) for q in ("a", "b", "c", "d")] == [0, 0, 2, 2]  # 2 waiting when refused
    assert work.busy == 2
    assert [work.get(lambda j: 0.0), work.get(lambda j: 0.0)] == ["a", "b"]  # the queued ones, in order
    assert work.put_query("e") == 0 and work.get(lambda j: 0.0) == "e"  # room again


@pytest.mark.parametrize(
    "correction",
    [
        CameraCorrection(),
        CameraCorrection(model="depth_scale", depth_scale=0.95),
        CameraCorrection(model="ray_scale", depth_scale=1.03),
        CameraCorrection(model="depth_scale_offset", depth_scale=0.97, depth_offset_m=0.004),
    ],
)
def test_camera_points_reach_the_base_frame_in_one_array(scenes, correction: CameraCorrection) -> None:  # type: ignore[no-untyped-def]
    """The received bytes are read in place (a view), and mapping them into the base frame with the
    correction allocates only the result: no intermediate copy of the cloud."""
    f = scenes["box"].frame
    payload = bytes(pointcloud.encode_points(f.render.points_cam, stamp_ns=STAMP_NS, frame_id="cam"))
    points_cam = pointcloud.decode(payload).xyz()
    assert np.shares_memory(points_cam, np.frombuffer(payload, np.uint8))  # no copy on decoding
    T_base_cam = f.T_base_flange @ DEFAULT_T_FLANGE_CAM
    tracemalloc.start()
    try:
        points_base = points_to_base(points_cam, T_base_cam, correction)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < points_base.nbytes + 100_000, (peak, points_base.nbytes)  # the result alone
    expected = apply(T_base_cam, correction.apply(points_cam))
    assert points_base.shape == points_cam.shape
    np.testing.assert_allclose(points_base, expected, atol=2e-6, equal_nan=True)


def test_a_camera_cloud_costs_one_cloud_array_more_than_a_base_cloud(scenes, board) -> None:  # type: ignore[no-untyped-def]
    """The whole decode + map + detect of a camera-frame cloud peaks at most one float32 cloud above
    the same cloud sent in the base frame (whose points are a view of the received bytes)."""
    f = scenes["box"].frame
    det = Detector(ServiceConfig(board=board, robot="t", zenoh=ZenohOptions()), {})
    det.T_flange_cam = DEFAULT_T_FLANGE_CAM
    det.flange.add(STAMP_NS, f.T_base_flange)
    cam = bytes(
        pointcloud.encode_points(
            f.render.points_cam, stamp_ns=STAMP_NS, frame_id="camera_color_optical_frame"
        )
    )
    base = bytes(pointcloud.encode_points(f.points_base, stamp_ns=STAMP_NS, frame_id=board.frame_id))
    peaks = {}
    for name, payload, camera in (("base", base, False), ("camera", cam, True)):
        det.detect_payload(payload, camera, "k")  # warm-up
        tracemalloc.start()
        try:
            result = det.detect_payload(payload, camera, "k")
            peaks[name] = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert np.linalg.norm(np.array(result.objects[0].center) - scenes["box"].objects[0].center) < 0.005
    cloud_bytes = f.render.points_cam.shape[0] * f.render.points_cam.shape[1] * 3 * 4
    assert peaks["camera"] - peaks["base"] < 1.3 * cloud_bytes, (peaks, cloud_bytes)


def test_a_queued_cloud_is_decoded_once_for_its_pose_and_its_detection(scenes, board) -> None:  # type: ignore[no-untyped-def]
    """The worker reads a queued cloud's header to find the flange pose it needs, then detects on it:
    one decode, whose point views are views of the received bytes."""
    f = scenes["box"].frame
    det = Detector(ServiceConfig(board=board, robot="t", zenoh=ZenohOptions()), {})
    payload = bytes(pointcloud.encode_points(f.points_base, stamp_ns=STAMP_NS, frame_id=board.frame_id))
    job = CloudJob(payload, False, "k")
    assert det.pose_wait(job) == 0.0  # a base-frame cloud needs no pose
    decoded = job.decoded
    assert decoded is not None and job.cloud() is decoded
    assert np.shares_memory(decoded.xyz(), np.frombuffer(payload, np.uint8))
    result = det.detect_payload(job, False, "k")
    assert job.decoded is decoded and result.stamp_ns == STAMP_NS and result.objects
    bad = CloudJob(b"\x00\x01\x00\x00 not a cloud", False, "k")
    assert det.pose_wait(bad) == 0.0  # processed at once: processing names what is wrong
    with pytest.raises(ValueError, match="truncated"):
        det.detect_payload(bad, False, "k")
