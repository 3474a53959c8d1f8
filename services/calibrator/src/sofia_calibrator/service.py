"""``sofia calibrator``: accumulates blob/flange-pose samples online, re-solves after each new one,
publishes the result, and answers queries (result, add, remove, reset, solve, save, samples).

Zenoh callbacks only put events on a queue; one worker thread pairs, stores, solves and replies.
"""

from __future__ import annotations

import argparse
import logging
import queue
from pathlib import Path
from typing import Any

import numpy as np
import zenoh
from sofia_schemas import pointcloud, rosmsg
from sofia_schemas.keys import ENCODING_JSON, Keys, default_robot
from sofia_schemas.messages import ServiceStatus, now_ns
from sofia_schemas.messages.calibration import (
    CalibrationFiles,
    CalibrationRemove,
    CalibrationSample,
    CalibrationSamples,
    CalibrationSolveOptions,
)
from sofia_schemas.service import (
    LatestSlot,
    StatusEndpoint,
    StopFlag,
    query_payload,
    reply_error,
    reply_json,
    run_worker,
)
from sofia_schemas.zenoh_config import ZenohOptions, zenoh_config

from .errors import InputMismatch
from .formats import to_yaml
from .online import Calibrator
from .pairing import PairingOptions
from .store import SampleStore

log = logging.getLogger("sofia.calibrator")
OPS = ("result", "add", "remove", "reset", "solve", "save", "samples")
EVENTS_MAX = 1000  # poses, blobs and queries waiting for the worker
CLOUDS_MAX = 8  # camera clouds waiting for blob extraction (a burst of poses; ~40 MB at 640x480)
STATUS_PERIOD_S = 1.0


class Service:
    def __init__(self, cal: Calibrator, session: zenoh.Session, keys: Keys, from_clouds: bool) -> None:
        self.cal, self.session, self.keys, self.from_clouds = cal, session, keys, from_clouds
        self.events: queue.Queue[tuple[str, Any]] = queue.Queue(maxsize=EVENTS_MAX)
        self.clouds: LatestSlot[bytes] = LatestSlot(CLOUDS_MAX)  # ~5 MB each: only the newest wait
        self.dropped = 0
        self.pub = session.declare_publisher(keys.calibration_result)

    def put(self, kind: str, item: Any) -> None:
        try:
            self.events.put_nowait((kind, item))
        except queue.Full:
            self.dropped += 1

    def declare(self) -> list[Any]:
        subs: list[Any] = [
            self.session.declare_subscriber(
                self.keys.flange_pose, lambda s: self.put("pose", s.payload.to_bytes())
            ),
            self.session.declare_subscriber(self.keys.blob, lambda s: self.put("blob", s.payload.to_bytes())),
        ]
        if self.from_clouds:
            subs.append(self.session.declare_subscriber(self.keys.camera_points,
                                                        lambda s: self.clouds.put(s.payload.to_bytes())))  # fmt: skip
        for op in OPS:
            subs.append(self.session.declare_queryable(self.keys.calibrator_op(op), self._on_query(op)))
        return subs

    def status(self) -> ServiceStatus:
        """Runs on Zenoh's thread for status queries: reads only."""
        r, store = self.cal.result, self.cal.store
        return ServiceStatus(
            service="calibrator", stamp_ns=now_ns(), state="ok" if r is None or r.passes else "degraded",
            detail=self.cal.last_error if r is None else ("passes" if r.passes else "fails the lab criterion"),
            counters={"samples": len(store.samples), "pending": len(self.cal.pending),
                      "dropped": self.dropped + self.clouds.dropped},
        )  # fmt: skip

    def _on_query(self, op: str) -> Any:
        def callback(query: zenoh.Query) -> None:
            self.put("query", (op, query))

        return callback

    def run(self, stop: StopFlag) -> None:
        while not stop.is_set():
            try:
                kind, item = self.events.get(timeout=0.05)
            except queue.Empty:
                cloud = self.clouds.take(timeout=0.15) if self.from_clouds else None
                kind, item = ("cloud", cloud) if cloud is not None else ("tick", None)
            if self.from_clouds and kind != "cloud" and (cloud := self.clouds.take(timeout=0)) is not None:
                self.step("cloud", cloud)  # clouds are served between events, never starved by poses
            self.step(kind, item)

    def step(self, kind: str, item: Any) -> None:
        try:
            self.handle(kind, item)
        except Exception as e:  # one bad message must not stop the service
            log.warning("%s dropped: %s: %s", kind, type(e).__name__, e)
            if kind == "query":  # every op replies last, so a failed op has not replied yet
                reply_error(item[1], e)
        if kind in ("pose", "blob", "cloud", "tick") and self.cal.pending and self.cal.pair_pending():
            self.resolve_and_publish()

    def handle(self, kind: str, item: Any) -> None:
        if kind == "pose":
            self.cal.on_pose(item)
        elif kind == "blob":
            obs = rosmsg.decode_blob(item)
            self.cal.on_blob(obs.stamp_ns, np.array(obs.position), obs.confidence)
        elif kind == "cloud":
            from .blob import find_blob

            cloud = pointcloud.decode(item)
            rgb = cloud.rgb()
            if rgb is None:
                raise InputMismatch("camera cloud has no rgb field")
            shape = (cloud.height, cloud.width, 3)
            blob = find_blob(cloud.xyz().reshape(shape), rgb.reshape(shape))
            self.cal.on_blob(cloud.stamp_ns, blob.p_cam, blob.confidence)
        elif kind == "query":
            self.answer(*item)
        elif kind == "resolve":
            self.resolve_and_publish()

    def resolve_and_publish(self) -> None:
        """Solve with the samples there are now; a result of other samples is never kept."""
        n = len(self.cal.store.samples)
        if n < self.cal.min_samples:
            self.cal.result = None
            self.cal.last_error = f"{n} samples, at least {self.cal.min_samples} needed"
            return
        try:
            result = self.cal.solve()
        except Exception as e:  # CalibrationError, or a numerical failure: report, keep serving
            self.cal.result = None
            self.cal.last_error = f"{type(e).__name__}: {e}"
            log.warning("not solved with %d samples: %s", n, self.cal.last_error)
            return
        self.pub.put(result.model_dump_json(), encoding=ENCODING_JSON)
        log.info("solved with %d samples: spread %s mm, %s", n, np.round(result.spread_mm, 1).tolist(),
                 "pass" if result.passes else "FAIL")  # fmt: skip

    def samples_reply(self, query: zenoh.Query) -> None:
        reply_json(query, CalibrationSamples(samples=self.cal.store.ordered()))

    def answer(self, op: str, query: zenoh.Query) -> None:
        payload = query_payload(query)
        store = self.cal.store
        if op == "result":
            if self.cal.result is None:
                raise InputMismatch(
                    f"no result yet: {len(store.samples)} samples. {self.cal.last_error}".strip()
                )
            reply_json(query, self.cal.result)
        elif op == "samples":
            self.samples_reply(query)
        elif op == "add":
            s = store.add(CalibrationSample.model_validate_json(payload))
            log.info("sample %d added by query", s.sample_id)
            reply_json(query, CalibrationSamples(samples=[s]))
            self.put("resolve", None)
        elif op == "remove":
            for i in CalibrationRemove.model_validate_json(payload).sample_ids:
                store.remove(i)
            self.samples_reply(query)
            self.put("resolve", None)
        elif op == "reset":
            store.reset()
            self.cal.result = None
            self.cal.pending = []  # blobs waiting for their poses belong to the old session too
            self.samples_reply(query)
        elif op == "solve":
            opts = CalibrationSolveOptions.model_validate_json(payload) if payload.strip() else None
            result = self.cal.solve(opts)
            if opts is not None:
                self.cal.options = opts
            reply_json(query, result)
            self.pub.put(result.model_dump_json(), encoding=ENCODING_JSON)
        elif op == "save":
            if self.cal.result is None:
                raise InputMismatch("nothing to save: no result yet")
            yaml_path = Path(store.dir) / "T_flange_cam.yaml"
            yaml_path.write_text(to_yaml(self.cal.result))
            launch = Path(store.dir) / "camera_static_transform.launch"
            launch.write_text(f"<launch>\n  {self.cal.result.ros1_static_transform}\n</launch>\n")
            ros2 = Path(store.dir) / "camera_static_transform_ros2.sh"
            ros2.write_text(f"#!/bin/sh\n{self.cal.result.ros2_static_transform}\n")
            reply_json(query, CalibrationFiles(files=[str(yaml_path), str(launch), str(ros2)]))


def main(args: argparse.Namespace) -> int:
    keys = Keys(args.robot or default_robot())
    store = SampleStore(args.state_dir)
    cal = Calibrator(
        store, PairingOptions(tolerance_ns=int(args.tolerance_ms * 1e6)), max(args.min_samples, 3)
    )
    stop = StopFlag()
    with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
        svc = Service(cal, session, keys, args.from_clouds)
        decls = svc.declare()
        worker = run_worker("calibrator", lambda: svc.run(stop))
        svc.put("resolve", None)  # a restarted calibrator publishes the result of its samples
        log.info(
            "calibrator ready on %s (%d samples, state in %s)",
            keys.calibrator,
            len(store.samples),
            store.path,
        )
        status = StatusEndpoint(session, keys.status("calibrator"), svc.status)
        while not stop.wait(STATUS_PERIOD_S) and worker.is_alive():
            status.publish()
        crashed = not stop.is_set()  # the worker died: exit non-zero so a supervisor restarts us
        stop.set()
        worker.join(timeout=5)
        for d in [*decls, status]:
            d.undeclare()
    store.close()
    log.info("calibrator %s", "worker died, exiting" if crashed else "stopped")
    return 1 if crashed else 0
