"""``sofia calibrator``: accumulates blob/flange-pose samples online, re-solves after each new one,
publishes the result, and answers queries (result, add, remove, reset, solve, save, samples).

Zenoh callbacks only put events on a queue; one worker thread pairs, stores, solves and replies.
"""

from __future__ import annotations

import argparse
import logging
import queue
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import zenoh
from sofia_schemas import pointcloud, rosmsg
from sofia_schemas.keys import ENCODING_JSON, Keys, default_robot
from sofia_schemas.messages import CalibrationResult, ServiceStatus, now_ns
from sofia_schemas.messages.calibration import (
    CalibrationRemove,
    CalibrationSample,
    CalibrationSamples,
    CalibrationSolveOptions,
)
from sofia_schemas.service import StopFlag, reply_error, reply_json, run_worker
from sofia_schemas.transforms import make_transform, matrix_to_quat_xyzw
from sofia_schemas.zenoh_config import ZenohOptions, zenoh_config

from .calibrate import calibrate
from .errors import CalibrationError, InputMismatch
from .formats import to_message, to_yaml
from .noise import camera_sigma
from .pairing import NotPaired, PairingOptions, PoseBuffer
from .store import SampleStore

log = logging.getLogger("sofia.calibrator")
OPS = ("result", "add", "remove", "reset", "solve", "save", "samples")
PENDING_TIMEOUT_S = 2.0


@dataclass
class Calibrator:
    """The service's state, touched only by the worker thread."""

    store: SampleStore
    pairing: PairingOptions = field(default_factory=PairingOptions)
    min_samples: int = 3
    poses: PoseBuffer = field(default_factory=PoseBuffer)
    pending: list[tuple[int, np.ndarray, float, float]] = field(default_factory=list)  # stamp, p, conf, t
    result: CalibrationResult | None = None
    options: CalibrationSolveOptions = field(default_factory=CalibrationSolveOptions)
    last_error: str = ""

    def on_pose(self, payload: bytes) -> None:
        pose = rosmsg.decode_flange_pose(payload)
        self.poses.add(pose.stamp_ns, pose.matrix())

    def on_blob(self, stamp_ns: int, p_cam: np.ndarray, confidence: float) -> None:
        self.pending.append((stamp_ns, p_cam, confidence, time.monotonic()))

    def pair_pending(self) -> list[CalibrationSample]:
        """Pair the blobs whose flange poses (up to the still window after them) have arrived."""
        added, keep = [], []
        latest = self.poses.latest_ns
        for stamp_ns, p_cam, conf, t_in in self.pending:
            ready = latest is not None and latest >= stamp_ns + self.pairing.still_window_ns
            if not ready and time.monotonic() - t_in < PENDING_TIMEOUT_S:
                keep.append((stamp_ns, p_cam, conf, t_in))
                continue
            try:
                T = self.poses.pair(stamp_ns, self.pairing)
            except NotPaired as e:
                log.info("sample skipped: %s", e)
                continue
            added.append(self.store.add(_sample(stamp_ns, p_cam, T, conf)))
            log.info("sample %d added (%d samples)", added[-1].sample_id, len(self.store.samples))
        self.pending = keep
        return added

    def solve(self, options: CalibrationSolveOptions | None = None) -> CalibrationResult:
        opts = options or self.options
        p, T, ids = self.store.arrays()
        guess = (
            None if opts.guess is None else make_transform(np.array(opts.guess[:3]), np.array(opts.guess[3:]))
        )
        if opts.noise not in ("depth", "uniform"):
            raise InputMismatch(f"noise must be 'depth' or 'uniform', got {opts.noise!r}")
        sigma = camera_sigma(p) if opts.noise == "depth" else np.full_like(p, 1e-3)
        conf = np.array([s.confidence for s in self.store.ordered()])
        sigma = sigma / np.clip(conf, 0.05, 1.0)[:, None]  # a less confident blob weighs less
        cal = calibrate(p, T, guess=guess, sigma=sigma, loss=opts.loss, exclude_outliers=opts.exclude_outliers,
                        leave_one_out=len(p) <= 60)  # fmt: skip
        self.result = to_message(cal, now_ns(), ids)
        self.result = self.result.model_copy(
            update={"inliers": [ids[i] for i in cal.inliers], "outliers": [ids[i] for i in cal.outliers]}
        )
        return self.result


def _sample(stamp_ns: int, p_cam: np.ndarray, T: np.ndarray, confidence: float) -> CalibrationSample:
    q = matrix_to_quat_xyzw(T[:3, :3])
    return CalibrationSample(
        stamp_ns=stamp_ns, p_cam=tuple(map(float, p_cam)), translation=tuple(map(float, T[:3, 3])),  # type: ignore[arg-type]
        rotation_xyzw=tuple(map(float, q)), confidence=confidence,  # type: ignore[arg-type]
    )  # fmt: skip


def _payload(query: zenoh.Query) -> bytes:
    return query.payload.to_bytes() if query.payload is not None else b""


class Service:
    def __init__(self, cal: Calibrator, session: zenoh.Session, keys: Keys, from_clouds: bool) -> None:
        self.cal, self.session, self.keys, self.from_clouds = cal, session, keys, from_clouds
        self.events: queue.Queue[tuple[str, Any]] = queue.Queue(maxsize=10_000)
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
                                                        lambda s: self.put("cloud", s.payload.to_bytes())))  # fmt: skip
        for op in OPS:
            subs.append(self.session.declare_queryable(self.keys.calibrator_op(op), self._on_query(op)))
        subs.append(self.session.declare_queryable(self.keys.status("calibrator"), self._on_query("status")))
        return subs

    def _on_query(self, op: str) -> Any:
        def callback(query: zenoh.Query) -> None:
            self.put("query", (op, query))

        return callback

    def run(self, stop: StopFlag) -> None:
        while not stop.is_set():
            try:
                kind, item = self.events.get(timeout=0.2)
            except queue.Empty:
                kind, item = "tick", None
            try:
                self.handle(kind, item)
            except Exception as e:  # one bad message must not stop the service
                log.warning("%s dropped: %s: %s", kind, type(e).__name__, e)
                if kind == "query":
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
        n = len(self.cal.store.samples)
        if n < self.cal.min_samples:
            return
        try:
            result = self.cal.solve()
        except CalibrationError as e:
            self.cal.last_error = str(e)
            log.warning("not solved with %d samples: %s", n, e)
            return
        self.pub.put(result.model_dump_json(), encoding=ENCODING_JSON)
        log.info("solved with %d samples: spread %s mm, %s", n, np.round(result.spread_mm, 1).tolist(),
                 "pass" if result.passes else "FAIL")  # fmt: skip

    def samples_reply(self, query: zenoh.Query) -> None:
        reply_json(query, CalibrationSamples(samples=self.cal.store.ordered()))

    def answer(self, op: str, query: zenoh.Query) -> None:
        payload = _payload(query)
        store = self.cal.store
        if op == "result":
            if self.cal.result is None:
                raise InputMismatch(
                    f"no result yet: {len(store.samples)} samples. {self.cal.last_error}".strip()
                )
            reply_json(query, self.cal.result)
        elif op == "samples":
            self.samples_reply(query)
        elif op == "status":
            r = self.cal.result
            reply_json(query, ServiceStatus(
                service="calibrator", stamp_ns=now_ns(), state="ok" if r is None or r.passes else "degraded",
                detail=self.cal.last_error if r is None else ("passes" if r.passes else "fails the lab criterion"),
                counters={"samples": len(store.samples), "pending": len(self.cal.pending), "dropped": self.dropped},
            ))  # fmt: skip
        elif op == "add":
            s = store.add(CalibrationSample.model_validate_json(payload))
            log.info("sample %d added by query", s.sample_id)
            reply_json(query, CalibrationSamples(samples=[s]))
            self.resolve_and_publish()
        elif op == "remove":
            for i in CalibrationRemove.model_validate_json(payload).sample_ids:
                store.remove(i)
            self.samples_reply(query)
            self.resolve_and_publish()
        elif op == "reset":
            store.reset()
            self.cal.result = None
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
            query.reply(
                str(query.key_expr),
                f'{{"files": ["{yaml_path}", "{launch}", "{ros2}"]}}',
                encoding=ENCODING_JSON,
            )


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
        while not stop.wait(0.5) and worker.is_alive():
            pass
        stop.set()
        worker.join(timeout=5)
        del decls
    store.close()
    log.info("calibrator stopped")
    return 0
