"""The replayer: streams every message of a recording to its Zenoh key, bytes unchanged.

Timing follows the recorded log times, scaled by ``rate`` (2.0 plays twice as fast), or no
timing at all (``fast``). The recording is read lazily, one chunk at a time, or with ``preload``
into memory once, decompressed, before playing (each loop then costs no reading or decompression,
and restamping writes the 8 stamp bytes in place instead of copying the message).

Back-pressure: publishers are reliable with ``CongestionControl.BLOCK`` by default, so no
message is lost on a healthy link, and a stalled subscriber slows the replay instead of
growing a buffer (Zenoh's transmission queue is bounded; a link stalled longer than Zenoh's
block timeout is closed by Zenoh). ``congestion="drop"`` behaves like a live sensor instead: the
player never waits, and a slow link loses messages. Either way memory stays bounded.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh
from sofia_runtime.client import matched
from sofia_runtime.service import StatusEndpoint, StopFlag
from sofia_schemas.keys import ENCODING_CDR_POINT, ENCODING_CDR_POINTCLOUD2, ENCODING_CDR_TRANSFORM, Keys
from sofia_schemas.messages import ServiceStatus, now_ns
from sofia_schemas.rosmsg import POINT_STAMPED, POINTCLOUD2, TRANSFORM_STAMPED

from .clock import PlayClock
from .errors import BadMappingError, NoSuchTopicError, RecordingError
from .mcap_io import RecordedMessage, iter_messages, summary
from .preload import ShmBuffers, preload, shm_enabled
from .stamps import HEADER_FIRST

log = logging.getLogger(__name__)

ENCODINGS = {
    POINTCLOUD2: ENCODING_CDR_POINTCLOUD2,
    TRANSFORM_STAMPED: ENCODING_CDR_TRANSFORM,
    POINT_STAMPED: ENCODING_CDR_POINT,
}
CONGESTION = {"block": zenoh.CongestionControl.BLOCK, "drop": zenoh.CongestionControl.DROP}
DRAIN_S = 0.3  # after the last put, before the session closes, so queued messages leave


def encoding_of(schema_name: str) -> str:
    """Zenoh encoding of a recorded ROS 2 type: ``application/cdr;<type>``."""
    return ENCODINGS.get(schema_name, f"application/cdr;{schema_name}")


def default_key(keys: Keys, topic: str) -> str:
    """The SofIA key of an MCAP topic; unknown topics go to ``sofia/{robot}/replay/<topic>``."""
    known = keys.topic_map().get(topic)
    if known is not None:
        return known
    chunks = [c for c in topic.split("/") if c]
    if not chunks:
        raise BadMappingError(topic, "topic name has no chunk to build a key from")
    return f"{keys.prefix}/replay/{'/'.join(chunks)}"


def check_key(key: str) -> str:
    """Return ``key`` if it is a concrete Zenoh key (no wildcards), else raise BadMappingError."""
    try:
        zenoh.KeyExpr(key)
    except Exception as e:  # zenoh raises ZError
        raise BadMappingError(key, f"not a Zenoh key expression: {e}") from None
    if "*" in key or "$" in key:
        raise BadMappingError(key, "a publication key must not contain wildcards")
    return key


@dataclass
class PlayOptions:
    """How to play. ``start_s``/``end_s`` are seconds from the first recorded message."""

    rate: float = 1.0
    fast: bool = False
    loop: bool = False
    start_s: float | None = None
    end_s: float | None = None
    topic_map: dict[str, str] = field(default_factory=dict)  # MCAP topic -> Zenoh key
    topics: list[str] | None = None  # play only these topics
    congestion: str = "block"
    wait_subscribers_s: float = 0.0
    progress_period_s: float = 5.0
    status_period_s: float = 1.0
    max_loops: int | None = None
    restamp: bool = False  # header stamps rewritten to the publish time (wall clock)
    preload: bool = False  # read the played messages into memory once (decompressed) before playing
    shm: bool = field(default_factory=shm_enabled)  # large messages put from Zenoh shared memory

    def __post_init__(self) -> None:
        if not self.fast and not (self.rate > 0 and self.rate < float("inf")):
            raise RecordingError(f"--rate must be a positive finite multiplier, got {self.rate}")
        if self.congestion not in CONGESTION:
            raise RecordingError(f"congestion {self.congestion!r} is not one of {sorted(CONGESTION)}")
        if self.start_s is not None and self.end_s is not None and self.end_s <= self.start_s:
            raise RecordingError(f"--end {self.end_s} s must be after --start {self.start_s} s")
        for key in self.topic_map.values():
            check_key(key)


@dataclass
class PlayResult:
    published: int = 0
    bytes: int = 0
    loops: int = 0
    per_topic: Counter[str] = field(default_factory=Counter)
    late_resyncs: int = 0
    stopped: bool = False


class Player:
    """Plays one MCAP file on an open Zenoh session."""

    def __init__(self, session: zenoh.Session, path: str | Path, robot: str, options: PlayOptions) -> None:
        self.session = session
        self.path = Path(path)
        self.keys = Keys(robot)
        self.options = options
        self.summary = summary(self.path)
        missing = sorted(set(options.topics or []) - set(self.summary.topics))
        if missing:  # before anything is declared: nothing to undo
            raise NoSuchTopicError(self.path, missing, sorted(self.summary.topics))
        self.result = PlayResult()
        self._publishers: dict[str, Any] = {}
        self._state = "starting"
        self._position_s = 0.0
        self._status = StatusEndpoint(session, self.keys.status("replay"), self.status)
        start_ns, end_ns = self.window_ns()
        log.info(
            "replaying %s: %d messages on %d topics, %.2f s (window %.2f..%.2f s), %s, congestion %s",
            self.path, self.summary.n_messages, len(self.summary.topics), self.summary.duration_s,
            (start_ns - self.summary.start_ns) / 1e9, (end_ns - self.summary.start_ns) / 1e9,
            "as fast as possible" if options.fast else f"rate x{options.rate}", options.congestion,
        )  # fmt: skip
        for topic in sorted(set(options.topic_map) - set(self.summary.topics)):
            log.warning(
                "--map %s: no such topic in %s (topics: %s)", topic, self.path, sorted(self.summary.topics)
            )
        for topic, ts in sorted(self.summary.topics.items()):
            if options.topics is None or topic in options.topics:
                self._publisher(topic, ts.schema_name)
        self._out = ShmBuffers(options.shm)
        self._preloaded: list[RecordedMessage] | None = None
        if options.preload:
            start_ns, end_ns = self.window_ns()
            self._preloaded = preload(self.path, options.topics, start_ns, end_ns, options.restamp)

    # --- setup ------------------------------------------------------------
    def window_ns(self) -> tuple[int, int]:
        """Log-time window ``[start, end)`` played, nanoseconds."""
        s0 = self.summary.start_ns
        start = s0 if self.options.start_s is None else s0 + int(self.options.start_s * 1e9)
        end = self.summary.end_ns + 1 if self.options.end_s is None else s0 + int(self.options.end_s * 1e9)
        return start, end

    def key_of(self, topic: str) -> str:
        return self.options.topic_map.get(topic) or default_key(self.keys, topic)

    def _publisher(self, topic: str, schema_name: str) -> Any:
        pub = self._publishers.get(topic)
        if pub is None:
            key = check_key(self.key_of(topic))
            pub = self.session.declare_publisher(
                key,
                encoding=encoding_of(schema_name),
                congestion_control=CONGESTION[self.options.congestion],
                reliability=zenoh.Reliability.RELIABLE,
            )
            self._publishers[topic] = pub
            log.info("%s (%s) -> %s", topic, schema_name, key)
        return pub

    def wait_for_subscribers(self, stop: StopFlag) -> bool:
        """Wait up to ``wait_subscribers_s`` until every publisher has a matching subscriber (a
        subscriber of only some keys makes it wait the whole time, then play anyway)."""
        deadline = time.monotonic() + self.options.wait_subscribers_s
        while time.monotonic() < deadline and not stop.is_set():
            if all(matched(p) for p in self._publishers.values()):
                return True
            stop.wait(0.05)
        missing = [str(p.key_expr) for p in self._publishers.values() if not matched(p)]
        if missing:
            log.warning(
                "no subscriber on %s after %.1f s, playing anyway", missing, self.options.wait_subscribers_s
            )
        return not missing

    # --- status -----------------------------------------------------------
    def status(self) -> ServiceStatus:
        """Runs on Zenoh's thread for status queries too: reads only (the topic counts are copied
        in one step, while the play loop may add a topic)."""
        r, position_s = self.result, self._position_s
        counters = {
            "published": r.published,
            "bytes": r.bytes,
            "loops": r.loops,
            "late_resyncs": r.late_resyncs,
            "shm_fallbacks": self._out.fallbacks,
            "shm_unlocated": self._out.unlocated,
        }
        counters.update({f"topic:{t}": n for t, n in sorted(dict(r.per_topic).items())})
        return ServiceStatus(
            service="replay",
            stamp_ns=now_ns(),
            state=self._state,  # type: ignore[arg-type]
            detail=f"{self.path.name} at {position_s:.2f} s of {self.summary.duration_s:.2f} s",
            counters=counters,
            info={
                "file": str(self.path),
                "rate": None if self.options.fast else self.options.rate,
                "position_s": round(position_s, 3),
                "duration_s": round(self.summary.duration_s, 3),
                "loop": self.options.loop,
            },
        )

    # --- playing ----------------------------------------------------------
    def _messages(self) -> Iterator[RecordedMessage]:
        if self._preloaded is not None:
            return iter(self._preloaded)
        start_ns, end_ns = self.window_ns()
        return iter_messages(self.path, self.options.topics, start_ns, end_ns)

    def run(self, stop: StopFlag) -> PlayResult:
        """Play until the end (or forever with ``loop``), or until ``stop`` is set."""
        o, r = self.options, self.result
        self._status.publish()
        if o.wait_subscribers_s > 0:
            self.wait_for_subscribers(stop)
        self._state = "ok"
        t_wall0 = time.monotonic()
        next_progress, next_status = t_wall0 + o.progress_period_s, t_wall0
        try:
            clock = PlayClock(o.rate)
            while not stop.is_set():
                published_before = r.published
                for m in self._messages():
                    now = time.monotonic()
                    if not o.fast:
                        delay = clock.delay_s(m.topic, m.log_time_ns, now)
                        r.late_resyncs = clock.resyncs
                        if delay > 0 and stop.wait(delay):
                            break
                    elif stop.is_set():
                        break
                    restamped = o.restamp and m.schema_name in HEADER_FIRST
                    payload, attachment = self._out.payload(m.data, restamped)
                    self._publisher(m.topic, m.schema_name).put(payload, attachment=attachment)
                    r.published += 1
                    r.bytes += len(m.data)
                    r.per_topic[m.topic] += 1
                    position_s = self._position_s = (m.log_time_ns - self.summary.start_ns) / 1e9
                    if now >= next_status:
                        self._status.publish()
                        next_status = now + o.status_period_s
                    if now >= next_progress:
                        elapsed = now - t_wall0
                        log.info(
                            "published %d messages (%.1f/s, %.1f MB/s), at %.2f s of %.2f s, loop %d",
                            r.published, r.published / elapsed, r.bytes / elapsed / 1e6, position_s,
                            self.summary.duration_s, r.loops + 1,
                        )  # fmt: skip
                        next_progress = now + o.progress_period_s
                else:
                    r.loops += 1
                    if r.published == published_before:
                        log.warning("nothing to play in %s within the window and topics given", self.path)
                        break
                    if o.loop and (o.max_loops is None or r.loops < o.max_loops):
                        clock.next_loop()
                        continue
                break
        finally:
            r.stopped = stop.is_set()
            self._state = "stopping"
            self._status.publish()
            time.sleep(DRAIN_S)
        elapsed = time.monotonic() - t_wall0
        log.info(
            "replay done: %d messages, %.1f MB in %.2f s (%d loops)%s",
            r.published, r.bytes / 1e6, elapsed, r.loops, ", stopped" if r.stopped else "",
        )  # fmt: skip
        return r

    def close(self) -> None:
        for pub in self._publishers.values():
            pub.undeclare()
        self._status.undeclare()
