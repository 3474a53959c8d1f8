"""``sofia calibrator``: accumulates blob/flange-pose samples online, re-solves once a burst of new
ones is over, publishes the result, and answers queries (result, add, remove, reset, solve, save,
samples). Zenoh callbacks only hand data to the :class:`Inbox`; one worker thread does the rest.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
import zenoh
from pydantic import ValidationError
from sofia_runtime.limits import PayloadTooLarge, check_payload, error_text
from sofia_runtime.service import (
    StatusEndpoint,
    StopFlag,
    query_payload,
    reply_error,
    reply_json,
    run_worker,
    serve,
)
from sofia_runtime.zenoh_config import ZenohOptions, zenoh_config
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

from .cloud_target import CloudTarget
from .errors import InputMismatch
from .inbox import QUERY_DEADLINE_S, Inbox
from .online import Calibrator
from .pairing import PairingOptions
from .result_files import prior_option, save_result
from .samples.checks import check_sample
from .samples.errors import CalibratorBusy, CalibratorLate, SolveFailed
from .samples.store import SamplesPage, SampleStore

log = logging.getLogger("sofia.calibrator")
OPS = ("result", "add", "remove", "reset", "solve", "save", "samples")
EVENTS_MAX = 1000  # poses and blobs waiting for the worker
QUERIES_MAX = 100  # queries waiting for the worker; beyond, they are answered "busy, retry" at once
CLOUDS_MAX = 8  # camera clouds waiting for blob extraction (a burst of poses; ~40 MB at 640x480)
IDLE_WAKE_S = 0.1  # with nothing to do the worker still wakes, to pair blobs whose poses never came
QUIET_S = 0.05  # samples changed: solve once nothing more has arrived for this long ...
SOLVE_DELAY_MAX_S = 1.0  # ... or once the first unsolved change is this old
SETTLING_OPS = ("result", "save")  # queries answered with the result of the samples there are now


class Service:
    def __init__(self, cal: Calibrator, session: zenoh.Session, keys: Keys, cloud_target: CloudTarget | None,
                 query_deadline_s: float = QUERY_DEADLINE_S) -> None:  # fmt: skip
        self.cal, self.session, self.keys = cal, session, keys
        self.cloud_target = cloud_target  # what each camera cloud gives (None: clouds not read)
        cal.centres = cloud_target.shared_centres if cloud_target else None
        self.query_deadline_s = query_deadline_s  # a query the worker reaches later: "busy, retry"
        self.inbox = Inbox(EVENTS_MAX, CLOUDS_MAX, QUERIES_MAX)
        self.solved_generation = -1  # the store generation of the current result (or failed solve)
        self.solve_failures = 0
        self.solve_failing = ""  # why the last solve failed, until one succeeds
        self.late_queries = 0
        self.pub = session.declare_publisher(keys.calibration_result)

    def declare(self) -> list[Any]:
        puts = [("pose", self.keys.flange_pose), ("blob", self.keys.blob)]
        puts += [("cloud", self.keys.camera_points)] if self.cloud_target else []
        subs: list[Any] = [self.session.declare_subscriber(key, self._on_put(kind)) for kind, key in puts]
        return subs + [
            self.session.declare_queryable(self.keys.calibrator_op(op), self._on_query(op)) for op in OPS
        ]

    def status(self) -> ServiceStatus:
        """Runs on Zenoh's thread for status queries: reads only."""
        r, store, dropped = self.cal.result, self.cal.store, self.inbox.dropped
        problems = [self.solve_failing, *store.problems()] if self.solve_failing else store.problems()
        if problems:
            state, detail = "degraded", "; ".join(problems)
        else:
            state = "ok" if r is None or r.passes else "degraded"
            detail = (
                self.cal.last_error if r is None else ("passes" if r.passes else "fails the lab criterion")
            )
        return ServiceStatus(
            service="calibrator", stamp_ns=now_ns(), state=state, detail=detail,  # type: ignore[arg-type]
            counters={"samples": len(store.samples), "pending": len(self.cal.pending),
                      "dropped": sum(dropped.values()) + self.cal.dropped,
                      "dropped_blobs": dropped["blob"] + self.cal.dropped,
                      "dropped_poses": dropped["pose"], "dropped_clouds": dropped["cloud"],
                      "dropped_queries": self.inbox.busy + self.late_queries, "late_queries": self.late_queries,
                      "refused_samples": self.cal.refused, "solve_failures": self.solve_failures,
                      **store.counters(), **self.cal.stamps.counters},
            info={"samples_consistent": not store.suspect(),
                  "sample_log": str(store.path)},
        )  # fmt: skip

    def _on_put(self, kind: str) -> Any:
        def callback(sample: zenoh.Sample) -> None:  # Zenoh's thread: check the size, hand over
            try:
                check_payload(str(sample.key_expr), sample.payload)
            except PayloadTooLarge as e:
                self.inbox.dropped[kind] += 1
                log.warning("%s dropped: %s", kind, error_text(e))
                return
            if kind == "cloud":
                self.inbox.put_cloud(sample.payload.to_bytes())
            else:
                self.inbox.put_event(kind, sample.payload.to_bytes())

        return callback

    def _on_query(self, op: str) -> Any:
        def callback(query: zenoh.Query) -> None:
            waiting = self.inbox.put_query(op, query)
            if waiting:  # answered here, on Zenoh's thread: never silence
                reply_error(query, CalibratorBusy(waiting))

        return callback

    def run(self, stop: StopFlag) -> None:
        """Take everything pending, apply it, answer the queries; solve once the burst is over."""
        first_unsolved = 0.0
        while not stop.is_set():
            unsolved = self.solved_generation != self.cal.store.generation
            batch = self.inbox.take(QUIET_S if unsolved else IDLE_WAKE_S)
            for kind, payload in batch.events:
                self.step(kind, payload)
            for cloud in batch.clouds:
                self.step("cloud", cloud)
            if self.cal.pending:
                self.step("pair", None)
            for op, query, arrived in batch.queries:
                if (waited := time.monotonic() - arrived) > self.query_deadline_s:
                    self.late_queries += 1
                    reply_error(query, CalibratorLate(waited, self.query_deadline_s))
                    continue
                self.step("query", (op, query))
            if self.solved_generation == self.cal.store.generation:
                first_unsolved = 0.0
                continue
            now = time.monotonic()
            first_unsolved = first_unsolved or now
            if not batch or now - first_unsolved >= SOLVE_DELAY_MAX_S:
                self.resolve_and_publish()
                first_unsolved = 0.0

    def step(self, kind: str, item: Any) -> None:
        try:
            self.handle(kind, item)
        except Exception as e:  # one bad message must not stop the service
            log.warning("%s dropped: %s: %s", kind, type(e).__name__, e)
            if kind == "query":  # every op replies last, so a failed op has not replied yet
                reply_error(item[1], e)

    def handle(self, kind: str, item: Any) -> None:
        if kind == "pose":
            self.cal.on_pose(item)
        elif kind == "blob":
            obs = rosmsg.decode_blob(item)
            self.cal.on_blob(obs.stamp_ns, np.array(obs.position), obs.confidence)
        elif kind == "cloud" and self.cloud_target is not None:
            cloud = pointcloud.decode(item)
            self.cal.on_blob(cloud.stamp_ns, *self.cloud_target.find_in(cloud))
        elif kind == "pair":
            self.cal.pair_pending()
        elif kind == "query":
            self.answer(*item)

    def resolve_and_publish(self) -> None:
        """Solve with the samples there are now; a result of other samples is never kept."""
        self.solved_generation = self.cal.store.generation
        n = len(self.cal.store.samples)
        if n < self.cal.min_samples:
            self.cal.result = None
            self.cal.last_error = f"{n} samples, at least {self.cal.min_samples} needed"
            return
        try:
            result = self.solve()
        except SolveFailed as e:  # report, keep serving
            self.cal.result = None
            self.cal.last_error = f"{e}"
            log.warning("%s", e)
            return
        self.pub.put(result.model_dump_json(), encoding=ENCODING_JSON)
        log.info("solved with %d samples: spread %s mm, %s; %s; noise %s mm", n,
                 np.round(result.spread_mm, 1).tolist(), "pass" if result.passes else "FAIL",
                 result.camera_correction.model, result.noise_mm and round(result.noise_mm, 2))  # fmt: skip

    def solve(self, opts: CalibrationSolveOptions | None = None) -> Any:
        """The calibrator's solve; any failure (a numerical one, or a fit the result's own checks
        refuse) becomes :class:`SolveFailed` naming it. A failure with the service's own options
        makes the status degraded until a solve succeeds (one with a caller's options only answers
        that caller)."""
        try:
            result = self.cal.solve(opts)
        except Exception as e:  # CalibrationError, a numerical failure, or a fit the result refuses
            reason = f"{type(e).__name__}: {e}"
            if isinstance(e, ValidationError):
                first = e.errors()[0]
                where = ".".join(str(p) for p in first["loc"])
                reason = f"the fit gave an impossible {where}: {first['msg']} (got {first.get('input')!r})"
            failed = SolveFailed(len(self.cal.store.samples), reason)
            self.solve_failures += 1
            self.solve_failing = f"{failed}" if opts is None else self.solve_failing
            raise failed from e
        self.solve_failing = ""
        return result

    def samples_reply(self, query: zenoh.Query, payload: bytes = b"") -> None:
        page = SamplesPage.model_validate_json(payload) if payload.strip() else SamplesPage()
        reply_json(query, CalibrationSamples(samples=self.cal.store.page(page.after_id, page.limit)))

    def answer(self, op: str, query: zenoh.Query) -> None:
        payload = query_payload(query)
        store = self.cal.store
        if op in SETTLING_OPS and self.solved_generation != store.generation:
            self.resolve_and_publish()
        if op == "result":
            if self.cal.result is None:
                raise InputMismatch(
                    f"no result yet: {len(store.samples)} samples. {self.cal.last_error}".strip()
                )
            reply_json(query, self.cal.result)
        elif op == "samples":
            self.samples_reply(query, payload)
        elif op == "add":
            sample = CalibrationSample.model_validate_json(payload)
            check_sample(sample.model_copy(update={"sample_id": None}))  # named first: impossible values
            self.cal.stamps.check("sample", sample.stamp_ns)
            s = store.add(sample)
            log.info("sample %d added by query", s.sample_id)
            reply_json(query, CalibrationSamples(samples=[s]))
        elif op == "remove":
            store.remove(CalibrationRemove.model_validate_json(payload).sample_ids)
            self.samples_reply(query)
        elif op == "reset":  # a payload (solve options) becomes the service's: e.g. the set-up
            options = CalibrationSolveOptions.model_validate_json(payload) if payload.strip() else None
            store.reset()
            self.cal.options = options or self.cal.options
            self.cal.result, self.cal.pending = None, []  # blobs waiting for poses: the old session's
            self.samples_reply(query)
        elif op == "solve":
            opts = CalibrationSolveOptions.model_validate_json(payload) if payload.strip() else None
            result = self.solve(opts)
            self.solved_generation = store.generation
            self.cal.options = opts or self.cal.options
            reply_json(query, result)
            self.pub.put(result.model_dump_json(), encoding=ENCODING_JSON)
        elif op == "save":
            if self.cal.result is None:
                raise InputMismatch("nothing to save: no result yet")
            reply_json(query, CalibrationFiles(files=save_result(self.cal.result, Path(store.dir))))


def main(args: argparse.Namespace) -> int:
    keys = Keys(args.robot or default_robot())
    store = SampleStore(args.state_dir, max_samples=args.max_samples)
    cal = Calibrator(
        store, PairingOptions(tolerance_ns=int(args.tolerance_ms * 1e6)), max(args.min_samples, 3),
        parent_frame=args.parent_frame, child_frame=args.child_frame,
        options=CalibrationSolveOptions(setup=args.setup, depth_scale_prior=prior_option(args.scale_prior)),
    )  # fmt: skip
    stop = StopFlag()
    with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
        cloud_target = CloudTarget(args.cloud_target, args.ball_radius) if args.from_clouds else None
        svc = Service(cal, session, keys, cloud_target, args.query_deadline)
        decls = svc.declare()
        worker = run_worker("calibrator", lambda: svc.run(stop))  # first solves the resumed samples
        log.info("calibrator ready on %s (%d samples in %s)", keys.calibrator, len(store.samples), store.path)
        status = StatusEndpoint(session, keys.status("calibrator"), svc.status)
        code = serve(stop, status, [worker], name="calibrator", log=log, declared=decls)
    store.close()
    return code
