"""``sofia detector serve``: the detector on the bus.

Subscribes ``Keys(robot).points`` (base frame) and ``camera_points`` (mapped with the flange pose at
the stamp and ``T_flange_cam``); publishes a :class:`Detection` per cloud on ``detections`` and a
:class:`PickTarget` (:class:`~.pick.Picks`) on ``pick_target``; the ``detect`` queryable answers a
cloud payload with its detection, an empty one with the latest; status every second. Callbacks
only hand over to one :class:`~.worker.WorkQueue` (shared-memory clouds read in place).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

import numpy as np
import zenoh
from sofia_replay.preload import shm_enabled
from sofia_runtime import serve
from sofia_runtime.client import fetch_latest
from sofia_runtime.limits import check_payload, error_text
from sofia_runtime.service import StatusEndpoint, StopFlag, query_payload, reply_error, reply_json, run_worker
from sofia_runtime.shm import SharedReader
from sofia_runtime.stamps import StampCheck
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas import pointcloud
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import CalibrationResult, Detection, ServiceStatus, now_ns
from sofia_schemas.messages.calibration import CameraCorrection, correction_applied, read_calibration_file
from sofia_schemas.ros2.encoding import decode_flange, typed_cloud
from sofia_schemas.transforms import as_transforms

from .detect import detect
from .errors import DetectorBusy, DetectorError, TransformUnavailable, UnknownFrame
from .frames import FlangeHistory, points_to_base
from .pick import Picks
from .selection import select, split_selection
from .service_config import ServiceConfig
from .warmup import warm_up
from .worker import BAD, STALE, UNMAPPED, CloudJob, DropLog, WorkQueue

log = logging.getLogger("sofia.detector")


class Detector:
    """State and work of the service (no Zenoh declarations: those are in :func:`main`)."""

    def __init__(self, config: ServiceConfig, publish: dict[str, zenoh.Publisher]) -> None:
        self.config, self.board = config, config.board
        self.publish = publish
        self.drops = DropLog()
        self.work: WorkQueue[zenoh.Query] = WorkQueue(config.backlog, self.drops)
        self.flange = FlangeHistory()
        pinned = config.transform_file  # a file given at start: calibrator results are ignored
        # the camera correction is applied to camera-frame clouds before T_flange_cam
        mount: tuple[np.ndarray | None, CameraCorrection] = (None, CameraCorrection())
        self.T_flange_cam, self.correction = read_calibration_file(pinned) if pinned else mount
        self.transform_name = f"file {pinned}" if pinned else None
        self.result_stamp_ns = -1  # stamp of the calibrator result in use
        self.stamps = StampCheck()  # future poses and results, live results older than this start
        self.latest: Detection | None = None
        self.picks = Picks(config.pick)
        self.shared = SharedReader(shm_enabled())  # clouds read in place from Zenoh shared memory
        self.counters = dict.fromkeys(("processed", "errors", "queries", "query_errors"), 0)
        self.last_error = ""
        self.last_ms = 0.0
        self._lock = threading.Lock()

    # --- callbacks: hand over only -------------------------------------
    def on_cloud(self, sample: zenoh.Sample, camera: bool = False) -> None:
        """A cloud on ``points`` (base frame) or, ``camera``, on ``camera_points``."""
        if typed_cloud(sample, self._error):
            payload, attachment = self.shared.received(sample)
            corrected = camera and correction_applied(attachment)
            self.work.put_cloud(CloudJob(payload, camera, str(sample.key_expr), corrected))

    def on_query(self, query: zenoh.Query) -> None:
        if waiting := self.work.put_query(query):  # refused: answered here at once, never silence
            reply_error(query, DetectorBusy(waiting))

    def on_flange_pose(self, sample: zenoh.Sample) -> None:
        try:
            check_payload(str(sample.key_expr), sample.payload)
            pose = decode_flange(sample.payload.to_bytes(), sample.encoding)
            self.stamps.check("flange pose", pose.stamp_ns)
        except ValueError as e:
            self._error(f"flange pose: {error_text(e)}")
            return
        self.flange.add(pose.stamp_ns, pose)
        self.work.poke()  # a camera cloud may be waiting for this pose

    def on_calibration(self, sample: zenoh.Sample, live: bool = False) -> None:
        """A calibrator result; ``live``: published now (not fetched at start), so one stamped
        before this service started is a replay and is refused."""
        if self.config.transform_file:
            return
        try:
            check_payload(str(sample.key_expr), sample.payload)
            result = CalibrationResult.model_validate_json(sample.payload.to_bytes())
            T = as_transforms(np.array(result.matrix), "calibration result matrix", tol=1e-4)
            self.stamps.check("calibration result", result.stamp_ns, since_start=live)
        except ValueError as e:
            self._error(f"calibration result: {error_text(e)}")
            return
        with self._lock:
            if result.stamp_ns < self.result_stamp_ns:  # an older result fetched after a newer one
                return
            self.T_flange_cam, self.result_stamp_ns = T, result.stamp_ns
            self.correction = result.camera_correction
            self.transform_name = f"calibrator result {result.stamp_ns}"
        log.info("using T_flange_cam from the calibrator (result %d)", result.stamp_ns)

    def _error(self, message: str) -> None:
        with self._lock:
            self.counters["errors"] += 1
            self.last_error = message = error_text(message)
        log.warning("%s", message)

    # --- work -------------------------------------------------------------
    def run(self) -> None:
        """Worker loop, until the work queue is closed: it sleeps until a query, a ready cloud or a
        flange pose arrives; queries first, then the oldest cloud kept."""
        while (item := self.work.get(self.pose_wait)) is not None:
            try:
                if isinstance(item, CloudJob):
                    self.process(item)
                else:
                    self.answer(item)
            except Exception as e:  # an unforeseen failure must not stop the service
                log.exception("detector worker: unexpected error")
                self._error(f"unexpected {type(e).__name__}: {e}")

    def pose_wait(self, job: CloudJob) -> float:
        """Seconds ``job`` may still wait for the flange pose of its stamp (0: process it now).
        Called by the work queue with its lock held: reads the cloud's header only (no copy)."""
        stamp_ns = job.pose_stamp(lambda frame: self.in_camera_frame(frame, job.camera, job.key))
        if stamp_ns is None or self.T_flange_cam is None or self.flange.wait_covered(stamp_ns, 0.0):
            return 0.0
        return job.arrived_s + self.config.pose_wait_s - time.monotonic()

    def detect_payload(
        self, payload: bytes | memoryview | CloudJob, camera: bool, key: str, corrected: bool = False
    ) -> Detection:
        """Decode a CDR PointCloud2 (a job's is decoded once) and detect; ValueError subclasses if bad."""
        cloud = payload.cloud() if isinstance(payload, CloudJob) else pointcloud.decode(payload)
        points, transform = cloud.xyz(), None
        if self.in_camera_frame(cloud.frame_id, camera, key):
            with self._lock:
                T_flange_cam, transform, corr = self.T_flange_cam, self.transform_name, self.correction
            if T_flange_cam is None:
                raise TransformUnavailable(
                    f"cloud in frame {cloud.frame_id!r} and no flange->camera transform: start with "
                    "--transform FILE or run the calibrator"
                )
            # a correction the producer applied already is not applied twice
            points = points_to_base(
                points, self.flange.at(cloud.stamp_ns) @ T_flange_cam, None if corrected else corr
            )
        t0 = time.perf_counter()
        det = detect(
            points, self.board, self.config.params, stamp_ns=cloud.stamp_ns, source=key, rgb=cloud.rgb()
        )
        self.last_ms = (time.perf_counter() - t0) * 1e3
        return det.model_copy(update={"transform": transform}) if transform else det

    def in_camera_frame(self, frame_id: str, camera_key: bool, key: str) -> bool:
        """``header.frame_id`` decides: the board's frame is used as is, a camera frame is mapped with
        the flange pose and ``T_flange_cam``. On the camera key any other frame is the camera's; on
        the base key and in queries an unknown frame is refused (UnknownFrame names it)."""
        frame = frame_id.lstrip("/")
        if frame == self.board.frame_id or (not frame and not camera_key):
            return False
        if camera_key or frame in self.config.camera_frames:
            return True
        raise UnknownFrame(frame, key, (self.board.frame_id, *self.config.camera_frames))

    def process(self, job: CloudJob) -> None:
        try:
            det = self.detect_payload(job, job.camera, job.key, job.corrected)
        except ValueError as e:
            unmapped = isinstance(e, TransformUnavailable)
            message = str(e) if unmapped else f"cloud on {job.key}: {e}"
            self.drops.add(UNMAPPED if unmapped else BAD, error_text(message))
            self._error(message)
            return
        self.latest = det
        self.counters["processed"] += 1
        self.publish["detections"].put(det.to_json_bytes(), encoding=ENCODING_JSON)
        pick = self.picks.of(det, job.key)
        if pick is not None:
            self.publish["pick"].put(pick.to_json_bytes(), encoding=ENCODING_JSON)

    def answer(self, query: zenoh.Query) -> None:
        self.counters["queries"] += 1
        try:
            payload = query_payload(query)  # PayloadTooLarge beyond the key's limit
            selection, payload = split_selection(payload, self.config.params.palette)
            if payload:
                det = self.detect_payload(payload, False, f"query {query.key_expr}")
            else:
                job = self.work.take_cloud(self.pose_wait)
                if job is not None:
                    self.process(job)
                if self.latest is None:
                    raise DetectorError(
                        f"no cloud received yet on {Keys(self.config.robot).points} or "
                        f"{Keys(self.config.robot).camera_points}: send a PointCloud2 with the query"
                    )
                det = self.latest
        except Exception as e:  # refused (ValueError) or failed: still answered, never a timeout
            self.counters["query_errors"] += 1
            if isinstance(e, ValueError):
                log.warning("detect query refused: %s", e)
            else:
                log.exception("detect query failed")
            reply_error(query, e)
            return
        reply_json(query, select(det, selection))

    def status(self) -> ServiceStatus:
        with self._lock:
            w, d = self.work, self.drops
            counters = dict(self.counters, received=w.received, dropped=d.counts[STALE], busy_queries=w.busy,
                            no_transform=d.counts[UNMAPPED], bad_clouds=d.counts[BAD],
                            picks=self.picks.published, picks_withheld=self.picks.withheld,
                            shm_read=self.shared.read, shm_copied=self.shared.copied,
                            **self.stamps.counters)  # fmt: skip
            transform, detail = self.transform_name, self.last_error
        state, dropped = self.drops.state()
        return ServiceStatus(
            service="detector", stamp_ns=now_ns(), state=state, detail=dropped or detail,  # type: ignore[arg-type]
            counters=counters,
            info={
                "board_frame": self.board.frame_id, "board": self.board.digest, "transform": transform,
                "flange_poses": len(self.flange), "last_detect_ms": round(self.last_ms, 3),
            },
        )  # fmt: skip


def main(config: ServiceConfig) -> int:
    """Run the detector service until SIGINT/SIGTERM."""
    stop = StopFlag()
    keys = Keys(config.robot)
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        publish = {
            "detections": session.declare_publisher(keys.detections),
            "pick": session.declare_publisher(keys.pick_target),
        }
        service = Detector(config, publish)
        took = warm_up(config.board, service.detect_payload, config.pick)  # before the first cloud
        declared: list[Any] = [
            session.declare_subscriber(keys.points, service.on_cloud),
            session.declare_subscriber(keys.camera_points, lambda s: service.on_cloud(s, camera=True)),
            session.declare_subscriber(keys.flange_pose, service.on_flange_pose),
            session.declare_subscriber(
                keys.calibration_result, lambda s: service.on_calibration(s, live=True)
            ),
            session.declare_queryable(keys.detect, service.on_query),
        ]
        status = StatusEndpoint(session, keys.status("detector"), service.status)
        worker = run_worker("detector", service.run)
        fetching = fetch_latest(session, keys.calibration_result, service.on_calibration, stop.event)
        log.info(
            "detector ready: clouds on %s and %s, detections on %s, queries on %s (transform: %s; warmed up in %.0f ms)",
            keys.points, keys.camera_points, keys.detections, keys.detect, service.transform_name, took * 1e3,
        )  # fmt: skip
        return serve(stop, status, [worker], name="detector", log=log, declared=declared,
                     on_stop=[service.work.close], also_join=[fetching])  # fmt: skip
