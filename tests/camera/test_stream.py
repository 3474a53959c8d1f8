"""The streaming path through the software device: bus-clock stamps, filters, depth and colour of
different instants, the depth correction, and a camera unplugged mid-stream."""

from __future__ import annotations

import itertools
import threading
import time

import numpy as np
from sofia_camera.clock import ClockMap
from sofia_camera.meta import CloudMeta
from sofia_camera.service import CameraService, Publishers, Settings
from sofia_camera.sim_scene import SimOptions, SimWorld
from sofia_schemas import pointcloud
from sofia_schemas.messages.calibration import CameraCorrection, correction_applied

from ..conftest import calibration_result
from .conftest import flange_above
from .test_geometry import one_cloud


def test_hardware_timestamps_map_onto_the_bus_clock(make_rig, board_world) -> None:  # type: ignore[no-untyped-def]
    rig = make_rig(board_world)
    depth, rgb = rig.renderer.render(flange_above(board_world))
    powered_up = time.monotonic() - 12.345  # the camera's own clock: ms since it powered up
    stamps, arrivals, device_ns = [], [], []
    for _ in range(12):
        t_ms = (time.monotonic() - powered_up) * 1e3
        rig.camera.inject(depth, rgb, t_ms)
        pair = rig.camera.wait_pair(2.0)
        stamp, _ = rig.pipeline.stamp(pair, rig.camera)
        stamps.append(stamp)
        arrivals.append(pair.arrival_ns)
        device_ns.append(round(t_ms * 1e6))
        time.sleep(1 / 30)
    assert (np.diff(stamps) > 0).all(), f"stamps not increasing: {np.diff(stamps) / 1e6} ms"
    lag_ms = (np.array(arrivals) - np.array(stamps)) / 1e6
    assert (lag_ms >= 0).all() and lag_ms.max() < 200, f"arrival - stamp {lag_ms} ms"
    # the offset (bus - device) only ever moves to a faster-arriving frame's, i.e. down, and little
    offsets_ms = (np.array(stamps) - np.array(device_ns)) / 1e6
    assert (np.diff(offsets_ms) <= 1e-6).all() and offsets_ms[0] - offsets_ms[-1] < 100, offsets_ms


def test_clock_map_restarts_when_the_device_clock_jumps_back() -> None:
    clock = ClockMap()
    base = 10**12  # bus ns
    assert clock.map(50_000.0, base + 5_000_000) == base + 5_000_000
    assert clock.map(50_033.3, base + 35_300_000) == base + 35_300_000  # 3 ms faster: the new offset
    # a frame delayed 7 ms more than the fastest is stamped when it was taken, not when it arrived
    assert clock.map(50_066.6, base + 75_600_000) == base + 68_600_000
    assert clock.map(10.0, base + 200_000_000) == base + 200_000_000  # the camera was reset
    assert clock.resets == 1


def _plane_noise_mm(cloud_bytes: bytearray) -> tuple[float, float]:
    xyz = pointcloud.decode(cloud_bytes).xyz().reshape(-1, 3).astype(np.float64)
    ok = np.isfinite(xyz[:, 2])
    p = xyz[ok]
    A = np.c_[p[:, 0], p[:, 1], np.ones(len(p))]
    coef, *_ = np.linalg.lstsq(A, p[:, 2], rcond=None)
    return float(np.std(p[:, 2] - A @ coef) * 1e3), float(1 - ok.mean())


def test_filters_smooth_and_fill(make_rig) -> None:  # type: ignore[no-untyped-def]
    """A noisy table seen from 0.6 m: spatial + temporal filtering lowers the noise, hole filling
    removes holes, decimation still gives a colour-sized cloud."""
    world = SimWorld(SimOptions(scene="calibration", noise=True, blob_radius=0.001))
    results = {}
    for filters in ((), ("spatial", "temporal"), ("hole_filling",), ("decimation",)):
        rig = make_rig(world, filters=filters)
        T = flange_above(world, height=0.6)
        for k in range(6):  # the temporal filter needs a history
            out = one_cloud(rig, T, 1000.0 + 33.3 * k)
        cloud = pointcloud.decode(out.cloud)
        assert (cloud.height, cloud.width) == (480, 640)
        assert out.meta.filters == (",".join(filters) or "none")
        results[filters] = _plane_noise_mm(out.cloud)
    raw_noise, raw_holes = results[()]
    assert results[("spatial", "temporal")][0] < 0.8 * raw_noise, results
    assert results[("hole_filling",)][1] < 0.2 * raw_holes, results
    assert raw_holes > 0.001, results


class Collector:
    """In-memory publishers of the service under test."""

    def __init__(self) -> None:
        self.clouds: list[tuple[int, CloudMeta, bytes]] = []
        self.infos = 0

    def publishers(self) -> Publishers:
        def points(cloud: bytes | bytearray, attachment: bytes) -> None:
            self.clouds.append(
                (pointcloud.decode(cloud).stamp_ns, CloudMeta.from_attachment(attachment), attachment)
            )

        def info(_payload: bytes) -> None:
            self.infos += 1

        return Publishers(points, info)


def test_depth_and_colour_of_different_instants_are_flagged(make_rig, board_world) -> None:  # type: ignore[no-untyped-def]
    rig = make_rig(board_world)
    depth, rgb = rig.renderer.render(flange_above(board_world))
    sink = Collector()
    for drop in (False, True):
        service = CameraService(
            rig.camera, rig.pipeline, sink.publishers(), Settings(max_skew_ms=16.0, drop_unsynced=drop)
        )
        service.opened = True
        for k, colour_offset_ms in enumerate((0.0, 5.0, 25.0)):
            t = 2000.0 + 1000 * drop + 33.3 * k
            rig.camera.inject(depth, rgb, t, color_time_ms=t + colour_offset_ms)
            service.handle(rig.camera.wait_pair(2.0, max_skew_ms=16.0))
        assert service.counters["unsynced"] == 1
        assert service.counters["unsynced_dropped"] == int(drop)
    synced = [m.synced for _, m, _ in sink.clouds]
    assert synced == [True, True, False, True, True], synced  # the flagged one is published only when allowed
    assert [abs(m.skew_ms) for _, m, _ in sink.clouds][2] > 16.0


def test_depth_correction_is_applied_once_and_said(make_rig, board_world) -> None:  # type: ignore[no-untyped-def]
    rig = make_rig(board_world)
    T = flange_above(board_world)
    plain = one_cloud(rig, T, 1000.0)
    assert not plain.meta.depth_corrected and not correction_applied(plain.meta.attachment())
    rig.correction.use(CameraCorrection(model="depth_scale", depth_scale=0.95), "calibrator result 7")
    fixed = one_cloud(rig, T, 1033.3)
    assert fixed.meta.depth_corrected and fixed.meta.depth_scale == 0.95
    assert correction_applied(fixed.meta.attachment())
    assert "0.95000" in rig.correction.describe()
    z0 = pointcloud.decode(plain.cloud).xyz()[..., 2]
    z1 = pointcloud.decode(fixed.cloud).xyz()[..., 2]
    ok = np.isfinite(z0) & np.isfinite(z1)
    np.testing.assert_allclose(z1[ok], 0.95 * z0[ok], rtol=1e-5)
    rig.correction.use(CameraCorrection(), "calibrator result 8")  # identity: switched off
    assert one_cloud(rig, T, 1066.6).meta.depth_corrected is False


def test_unplugged_camera_reports_error_and_comes_back_without_stale_clouds(make_rig, board_world) -> None:  # type: ignore[no-untyped-def]
    rig = make_rig(board_world)
    rig.camera.close()
    depth, rgb = rig.renderer.render(flange_above(board_world))
    sink = Collector()
    service = CameraService(
        rig.camera, rig.pipeline, sink.publishers(), Settings(max_skew_ms=16.0, frame_timeout_s=0.5)
    )
    stop = threading.Event()

    def feed() -> None:  # the camera's side: frames at ~30 Hz stamped by its own running clock
        powered_up = time.monotonic() - 5.0
        while not stop.is_set():
            rig.camera.inject(depth, rgb, (time.monotonic() - powered_up) * 1e3)  # dropped while unplugged
            time.sleep(1 / 30)

    threads = [threading.Thread(target=feed), threading.Thread(target=service.run, args=(stop,))]
    for t in threads:
        t.start()
    try:
        _wait(lambda: len(sink.clouds) >= 5, "clouds before the unplug")
        assert service.status().state == "ok"
        rig.camera.unplug()
        unplugged_ns = time.time_ns()
        _wait(lambda: service.status().state == "error", "error state after the unplug")
        status = service.status()
        assert "no frame" in status.detail or "unplugged" in status.detail, status.detail
        n_before = len(sink.clouds)
        time.sleep(1.5)  # stays in error, retries, publishes nothing
        assert len(sink.clouds) == n_before and service.status().state == "error"
        assert "unavailable" in service.status().detail
        replugged_ns = time.time_ns()
        rig.camera.replug()
        _wait(lambda: len(sink.clouds) >= n_before + 5, "clouds after the replug", timeout=15.0)
        assert service.status().state == "ok" and service.counters["reconnects"] == 1
    finally:
        stop.set()
        for t in threads:
            t.join(10)
    stamps = [s for s, _, _ in sink.clouds]
    assert all(b > a for a, b in itertools.pairwise(stamps)), "stamps must increase"
    after = stamps[n_before:]
    assert min(after) > unplugged_ns and min(after) >= replugged_ns - 50_000_000, (
        "a stale cloud was published"
    )


def _wait(condition, what: str, timeout: float = 10.0) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


def test_correction_follows_the_calibrators_results() -> None:
    from sofia_camera.correction import DepthCorrection

    def result(stamp: int, correction: CameraCorrection) -> bytes:
        return calibration_result(
            np.eye(4), stamp, target_base=(0.5, 0.0, 0.0), camera_correction=correction
        ).to_json_bytes()

    corr = DepthCorrection()
    corr.on_result(
        result(41, CameraCorrection(model="depth_scale_offset", depth_scale=0.97, depth_offset_m=0.002))
    )
    applied, source = corr.current()
    assert applied.depth_scale == 0.97 and source == "calibrator result 41"
    assert "offset 2.00 mm" in corr.describe()
    corr.on_result(b'{"stamp_ns": "soon"}')  # malformed: counted, the correction in force stays
    assert (
        corr.errors == 1
        and "calibration result is invalid" in corr.last_error
        and corr.current()[0] is applied
    )
    corr.on_result(result(42, CameraCorrection()))  # the newest result has no correction
    assert corr.current() == (None, "") and corr.describe().startswith("none")
    off = DepthCorrection(enabled=False)
    off.on_result(result(43, CameraCorrection(model="depth_scale", depth_scale=0.9)))
    assert off.current() == (None, "") and off.describe().startswith("off")
