"""The detector service's hand-over: one queue for queries and clouds, one worker waiting on one
condition variable (a query, a cloud, a flange pose or the stop wakes it). Queries come first; a camera
cloud waiting for its flange pose stays at the head meanwhile. Drops are counted per reason (:class:`DropLog`)."""

from __future__ import annotations

import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Generic, TypeVar

from sofia_schemas import pointcloud

Q = TypeVar("Q")
QUERIES_MAX = 64  # detect queries waiting for the worker; beyond, they are answered "busy, retry" at once
DEGRADED_WINDOW_S = 10.0  # the status is degraded while the last drop is more recent than this
STALE = "stale clouds"  # reasons for dropping a cloud, as the status names them
UNMAPPED = "camera-frame clouds not mapped to the base frame"
BAD = "bad clouds"


@dataclass(slots=True)
class CloudJob:
    """Received cloud bytes (a view of Zenoh shared memory, or a copy); ``camera``: camera frame;
    ``corrected``: the producer already applied the camera correction (Zenoh attachment).
    ``arrived_s`` (monotonic) starts the wait for the flange pose of its stamp (:meth:`pose_stamp`)."""

    payload: bytes | memoryview
    camera: bool
    key: str
    corrected: bool = False
    arrived_s: float = field(default_factory=time.monotonic)
    decoded: pointcloud.PointCloud2 | None = None

    def cloud(self) -> pointcloud.PointCloud2:
        """The cloud, decoded once (points are views of ``payload``). Raises ValueError subclasses."""
        if self.decoded is None:
            self.decoded = pointcloud.decode(self.payload)
        return self.decoded

    def pose_stamp(self, in_camera_frame: Callable[[str], bool]) -> int | None:
        """The stamp this cloud needs a flange pose for; None for board-frame and unreadable clouds
        (their error is raised again when the worker takes them)."""
        try:
            cloud = self.cloud()
            return cloud.stamp_ns if in_camera_frame(cloud.frame_id) else None
        except ValueError:
            return None


class WorkQueue(Generic[Q]):
    """Up to ``max_queries`` queries (each one queued is answered; :meth:`put_query` refuses more)
    and the newest ``backlog`` clouds (a put on a full queue drops the oldest cloud and counts it in
    ``drops``), behind one condition variable."""

    def __init__(
        self, backlog: int = 1, drops: DropLog | None = None, max_queries: int = QUERIES_MAX
    ) -> None:
        if backlog < 1:
            raise ValueError(f"backlog must be at least 1 cloud, got {backlog}")
        self.backlog, self.max_queries = backlog, max_queries
        self.drops = drops if drops is not None else DropLog()
        self.received = self.busy = 0  # clouds put; queries refused because max_queries were waiting
        self._cond = threading.Condition()
        self._queries: deque[Q] = deque()
        self._clouds: deque[CloudJob] = deque()
        self._closed = False

    def put_query(self, query: Q) -> int:
        """Queue ``query``; 0, or the number already waiting when it is refused (the caller answers it)."""
        with self._cond:
            if len(self._queries) >= self.max_queries:
                self.busy += 1
                return len(self._queries)
            self._queries.append(query)
            self._cond.notify()
            return 0

    def put_cloud(self, job: CloudJob) -> CloudJob | None:
        """Queue ``job``; returns the cloud dropped to make room (None when there was room)."""
        with self._cond:
            old = self._clouds.popleft() if len(self._clouds) == self.backlog else None
            self._clouds.append(job)
            self.received += 1
            self._cond.notify()
        if old is not None:
            self.drops.add(STALE, f"a newer cloud arrived before it was detected (backlog {self.backlog})")
        return old

    def poke(self, closing: bool = False) -> None:
        """Wake the worker: something a waiting cloud depends on (a flange pose) arrived, or the stop."""
        with self._cond:
            self._closed |= closing
            self._cond.notify_all()

    def close(self) -> None:
        self.poke(closing=True)

    def get(self, pose_wait: Callable[[CloudJob], float]) -> Q | CloudJob | None:
        """Block until there is work: the oldest query, else the oldest cloud once
        ``pose_wait(cloud)`` (seconds it still has to wait, called with the queue locked) is 0.
        None once closed."""
        with self._cond:
            while not self._closed:
                if self._queries:
                    return self._queries.popleft()
                job = self._ready_cloud(pose_wait)
                if isinstance(job, CloudJob):
                    return job
                self._cond.wait(job)
            return None

    def take_cloud(self, pose_wait: Callable[[CloudJob], float]) -> CloudJob | None:
        """The oldest cloud if it is ready now, without waiting."""
        with self._cond:
            job = self._ready_cloud(pose_wait)
            return job if isinstance(job, CloudJob) else None

    def _ready_cloud(self, pose_wait: Callable[[CloudJob], float]) -> CloudJob | float | None:
        """The head cloud, taken, when ready; else how long it may still wait (None: no cloud)."""
        if not self._clouds:
            return None
        wait = pose_wait(self._clouds[0])
        return self._clouds.popleft() if wait <= 0 else wait

    def __len__(self) -> int:
        return len(self._clouds)


class DropLog:
    """Input the service dropped, per reason: ``counts`` so far and the last time and message."""

    def __init__(self, window_s: float = DEGRADED_WINDOW_S) -> None:
        self.window_s = window_s
        self.counts: Counter[str] = Counter()
        self._last: dict[str, tuple[float, str]] = {}
        self._lock = threading.Lock()

    def add(self, reason: str, message: str) -> None:
        with self._lock:
            self.counts[reason] += 1
            self._last[reason] = (time.monotonic(), message)

    def state(self) -> tuple[str, str]:
        """``("degraded", what was dropped and why)`` while drops are recent, else ``("ok", "")``."""
        now = time.monotonic()
        with self._lock:
            recent = [f"{reason}: {self.counts[reason]} dropped (last: {msg})"
                      for reason, (t, msg) in sorted(self._last.items()) if now - t <= self.window_s]  # fmt: skip
        return ("degraded", "; ".join(recent)) if recent else ("ok", "")
