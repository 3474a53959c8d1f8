"""``sofia camera serve``: the D435 (or its simulation) on the bus.

- publishes organized clouds on ``Keys(robot).camera_points`` (CDR PointCloud2, colour optical
  frame, xyz + rgb, NaN where no depth), each with a :class:`~sofia_camera.meta.CloudMeta`
  attachment, and ``Keys(robot).camera_info`` (CDR CameraInfo, same stamp); each cloud is written
  straight into a Zenoh shared-memory buffer (:class:`~sofia_camera.shm.CloudBuffers`; a plain put,
  counted in status ``shm_fallbacks``, when ``$SOFIA_ZENOH_SHM=off`` or the pool is exhausted);
- follows ``Keys(robot).calibration_result`` for the depth correction;
- ``Keys(robot).status("camera")``: :class:`ServiceStatus` every second, and queryable.

One worker thread streams: it opens the camera (retrying while it is absent), builds and
publishes each cloud, and on a silent camera (unplugged) reports the error, closes it and
reopens it when it is back. A cloud is never older than the last one published.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import zenoh
from sofia_replay.preload import shm_enabled
from sofia_runtime.client import fetch_latest
from sofia_runtime.service import StatusEndpoint, StopFlag, run_worker, serve
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas.keys import ENCODING_CDR_CAMERA_INFO, ENCODING_CDR_POINTCLOUD2, Keys
from sofia_schemas.messages import ServiceStatus, now_ns

from .correction import DepthCorrection
from .errors import CameraError, FramesStopped
from .intrinsics import d435_spec
from .pipeline import CloudPipeline
from .processing import FilterChain
from .shm import CloudBuffers
from .streams import FramePair, FrameSource, wait_pair

log = logging.getLogger("sofia.camera")
RETRY_S = 1.0
FIRST_FRAME_S = 5.0  # a camera just opened may take this long to deliver its first frame


@dataclass
class Publishers:
    # the cloud (bytes, or a Zenoh shared-memory buffer) and its attachment
    points: Callable[[Any, bytes | None], None]
    camera_info: Callable[[bytes], None]


@dataclass
class Settings:
    max_skew_ms: float
    drop_unsynced: bool = False
    frame_timeout_s: float = 1.0  # no frame for this long while streaming: the camera is gone
    info: dict[str, Any] = field(default_factory=dict)  # mode, preset, ... for the status


class CameraService:
    """The streaming loop and its counters (no Zenoh declarations: those are in :func:`main`).

    idle_reason: when it returns a text, a camera without frames is waiting (the simulation without
    flange poses), not unplugged.
    """

    def __init__(self, source: FrameSource, pipeline: CloudPipeline, publish: Publishers, settings: Settings,
                 idle_reason: Callable[[], str | None] | None = None) -> None:  # fmt: skip
        self.source = source
        self.pipeline = pipeline
        self.publish = publish
        self.settings = settings
        self.idle_reason = idle_reason or (lambda: None)
        self.opened = False
        self.state: Literal["starting", "ok", "degraded", "error", "stopping"] = "starting"
        self.detail = ""
        self.counters = dict.fromkeys(("published", "dropped", "unsynced", "unsynced_dropped", "stale", "no_color",
                                       "disconnects", "reconnects", "errors"), 0)  # fmt: skip
        self.last_stamp_ns = 0
        self.last_frame_number: int | None = None
        self.build_ms = 0.0
        self._published_at: deque[float] = deque(maxlen=60)
        self._opened_at = 0.0
        self._lock = threading.Lock()

    def _set(self, state: Literal["ok", "degraded", "error"], detail: str) -> None:
        with self._lock:
            if (state, detail) != (self.state, self.detail) and state != "ok":
                log.warning("camera %s: %s", state, detail)
            self.state, self.detail = state, detail

    # --- the loop -------------------------------------------------------
    def run(self, stop: threading.Event | Any) -> None:
        while not stop.is_set():
            if not self.opened and not self._open():
                stop.wait(RETRY_S)
                continue
            first = time.monotonic() - self._opened_at < FIRST_FRAME_S
            timeout = FIRST_FRAME_S if first else self.settings.frame_timeout_s
            pair = wait_pair(self.source, timeout, self.settings.max_skew_ms, stop)
            if pair is None:
                if not stop.is_set():
                    self._no_frame(timeout)
                continue
            try:
                self.handle(pair)
            except Exception as e:  # a bad frame must not stop the camera
                log.exception("camera: frame %s failed", pair.depth.get_frame_number())
                with self._lock:
                    self.counters["errors"] += 1
                self._set("degraded", f"building a cloud failed: {type(e).__name__}: {e}")
        self.source.close()

    def _open(self) -> bool:
        try:
            self.source.open()
        except CameraError as e:  # absent, busy, or without the asked mode: say so and retry
            self._set("error", str(e))
            return False
        if self.counters["disconnects"]:
            self.counters["reconnects"] += 1
            log.info("camera %s is back", self.source.serial)
        self.opened = True
        self._opened_at = time.monotonic()
        self.last_frame_number = None
        self.pipeline.clock.reset()
        self._set("ok", "streaming")
        return True

    def _no_frame(self, waited_s: float) -> None:
        reason = self.idle_reason()
        if reason:
            self._set("degraded", reason)
            return
        self.counters["disconnects"] += 1
        self._set("error", str(FramesStopped(self.source.serial, waited_s)))
        self.source.close()  # frames still queued are dropped: nothing stale is published later
        self.opened = False

    def handle(self, pair: FramePair) -> None:
        """Build and publish the cloud of ``pair`` unless it is stale, colourless or (by choice) unsynced."""
        c = self.counters
        number = pair.depth.get_frame_number()
        if self.last_frame_number is not None and number > self.last_frame_number + 1:
            c["dropped"] += number - self.last_frame_number - 1
        self.last_frame_number = number
        if pair.color is None:
            c["no_color"] += 1
            self._set("degraded", "depth frames arrive without colour frames")
            return
        stamp_ns, color_ns = self.pipeline.stamp(pair, self.source)
        if stamp_ns <= self.last_stamp_ns:
            c["stale"] += 1
            return
        synced = abs(pair.skew_ms) <= self.settings.max_skew_ms
        if not synced:
            c["unsynced"] += 1
            if self.settings.drop_unsynced:
                c["unsynced_dropped"] += 1
                return
        out = self.pipeline.build(pair, self.source, stamp_ns, color_ns)
        self.publish.points(out.cloud, out.attachment)
        self.publish.camera_info(out.camera_info)
        with self._lock:
            self.last_stamp_ns = stamp_ns
            self.build_ms = out.build_ms
            c["published"] += 1
            self._published_at.append(time.monotonic())
        if self.state != "ok":
            self._set("ok", "streaming")

    # --- status ---------------------------------------------------------
    def fps(self) -> float:
        with self._lock:
            times = list(self._published_at)
        if len(times) < 2 or time.monotonic() - times[-1] > 2.0:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])

    def status(self) -> ServiceStatus:
        info: dict[str, str | float | int | bool | None] = {**self.source.info(), **self.settings.info}
        info.update(self.source.telemetry())
        with self._lock:
            state, detail, counters = self.state, self.detail, dict(self.counters)
            info.update(build_ms=round(self.build_ms, 2), last_stamp_ns=self.last_stamp_ns)
        info.update(fps=round(self.fps(), 2), filters=self.pipeline.filters.describe(),
                    depth_correction=self.pipeline.correction.describe(),
                    depth_corrected=self.pipeline.correction.current()[0] is not None)  # fmt: skip
        buffers = self.pipeline.buffers
        info["shm"] = buffers is not None and buffers.enabled
        info["shm_detail"] = None if buffers is None else buffers.detail
        if buffers is not None:  # clouds written into Zenoh shared memory; put as bytes (pool exhausted)
            counters.update(
                shm_direct=buffers.direct,
                shm_copied=buffers.copied,
                shm_fallbacks=buffers.fallbacks,
                shm_unlocated=buffers.pool.unlocated,
            )
        return ServiceStatus(service="camera", stamp_ns=now_ns(), state=state, detail=detail,
                             counters=counters, info=info)  # fmt: skip


def zenoh_publishers(session: zenoh.Session, keys: Keys) -> tuple[Publishers, list[Any]]:
    points = session.declare_publisher(keys.camera_points, encoding=ENCODING_CDR_POINTCLOUD2)
    info = session.declare_publisher(keys.camera_info, encoding=ENCODING_CDR_CAMERA_INFO)
    return Publishers(
        points=lambda cloud, attachment: points.put(cloud, attachment=attachment),
        camera_info=lambda payload: info.put(payload),
    ), [points, info]


@dataclass
class ServiceConfig:
    robot: str
    zenoh: Any  # ZenohOptions
    width: int = 640
    height: int = 480
    fps: int = 30
    serial: str | None = None
    preset: str | None = None
    filters: tuple[str, ...] = ()
    max_skew_ms: float | None = None  # default: half the frame period
    drop_unsynced: bool = False
    depth_correction: bool = True
    sim: Any = None  # SimOptions: frames from the simulated D435 instead of a device
    align: str = "registration"  # depth onto the colour grid: registration | librealsense (rs.align)


def main(config: ServiceConfig) -> int:
    """Run the camera service until SIGINT/SIGTERM."""
    stop = StopFlag()
    keys = Keys(config.robot)
    max_skew_ms = config.max_skew_ms if config.max_skew_ms is not None else 500.0 / config.fps
    correction = DepthCorrection(enabled=config.depth_correction)
    pipeline = CloudPipeline(
        FilterChain(config.filters),
        correction,
        max_skew_ms,
        simulated=config.sim is not None,
        align=config.align,
        buffers=CloudBuffers(shm_enabled()),
    )
    info: dict[str, Any] = {"mode": f"{config.width}x{config.height}@{config.fps}", "preset": config.preset,
                            "simulated": config.sim is not None, "align": config.align}  # fmt: skip
    settings = Settings(max_skew_ms=max_skew_ms, drop_unsynced=config.drop_unsynced,
                        frame_timeout_s=max(1.0, 5.0 / config.fps), info=info)  # fmt: skip
    if config.align == "registration":
        pipeline.warm_up()
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        publish, declared = zenoh_publishers(session, keys)
        declared.append(session.declare_subscriber(keys.calibration_result,
                                                   lambda s: correction.on_result(s.payload.to_bytes())))  # fmt: skip
        # the calibrator's current result, if a calibrator answers (one that starts later: its next result)
        fetching = fetch_latest(session, keys.calibration_result,
                                lambda s: correction.on_result(s.payload.to_bytes()), stop.event, timeout=3.0)  # fmt: skip
        idle = None
        workers = []
        if config.sim is not None:
            from .sim import SimDriver, SimRenderer
            from .sim_scene import SimWorld
            from .software import SoftwareCamera

            spec = d435_spec(config.width, config.height, config.fps)
            camera = SoftwareCamera(spec)
            driver = SimDriver(camera, SimRenderer(SimWorld(config.sim), spec, config.sim.seed), config.fps,
                               keys.flange_pose)  # fmt: skip
            declared.append(session.declare_subscriber(keys.flange_pose, driver.on_pose))
            workers.append(run_worker("camera-sim", lambda: driver.run(stop.event)))
            source: FrameSource = camera
            idle = driver.idle_reason
            info.update(sim_scene=config.sim.scene, sim_seed=config.sim.seed)
        else:
            from .device import DeviceCamera

            source = DeviceCamera(config.serial, config.width, config.height, config.fps, config.preset)
        service = CameraService(source, pipeline, publish, settings, idle)
        status = StatusEndpoint(session, keys.status("camera"), service.status)
        workers.append(run_worker("camera", lambda: service.run(stop.event)))
        log.info("camera ready: clouds on %s, camera info on %s (%s, filters %s)", keys.camera_points,
                 keys.camera_info, "simulated D435" if config.sim is not None else "RealSense", pipeline.filters.describe())  # fmt: skip
        return serve(stop, status, workers, name="camera", log=log, declared=declared, also_join=[fetching])
